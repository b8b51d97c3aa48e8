"""The demo on real materials with the built-in models (``brdfkit demo``).

Two of the 20 MERL test materials (:data:`DEMO_MATERIALS`, of the four shipped as their
published NBRDF networks), decoded to dense tables (:mod:`brdfkit.materials.nbrdf_networks`),
go through everything brdfkit does with the built-in models (``docs/models.md``), each job
once a material, none of which needs training here:

* sparse reconstruction from 40 and 400 samples (:func:`brdfkit.acquisition.sampling.draw_samples`)
  with ``brdfkit sparse``'s default method on ``merl80-l40`` (its learnt prior,
  :func:`brdfkit.methods.choice.choose`), which never saw these materials, and with
  IPCA on the same PCA basis beside it (Nielsen et al. 2015);
* compression of the full table by three built-ins (:data:`COMPRESSIONS`) as ``brdfkit
  encode`` makes it (:func:`brdfkit.api.encode`): the 40-D ones' default embeddings (39
  coefficients of the PCA basis they ship, and their residual's correction where they ship
  one), the 7-D one's latent, each refined on screen
  for at most :data:`COMPRESSION_STEPS` steps, then decoded; of two kinds, labelled so:

  - *in-sample*: ``merl-rgl-l40`` (39 numbers) and ``merl-rgl-l7`` (7 numbers), fitted
    on all 151 MERL + RGL proxies, these four included: the paper's compression protocol
    (Gokbudak et al. 2024, Sec. 4.2), a compression model being trained on what it
    compresses;
  - *unseen*: ``merl80-l40`` (39 numbers), its basis fitted without the 20 test
    materials: how well the basis holds a material that the model never saw;

* an interpolation of two materials' ``merl80-l40`` embeddings at ``t = 0.5``
  (:data:`INTERPOLATION_MODEL`);
* errors (:func:`brdfkit.evaluation.metrics.brdf_log_rmse`) and times, a comparison sheet
  (:func:`brdfkit.figures.comparison_sheet.comparison_sheet`) and a plot (:func:`brdfkit.figures.brdf_plot.plot_brdfs`)
  of one material against the learnt prior's reconstructions and the three compressions.

:func:`run_real_demo` returns what it measured and wrote; ``brdfkit demo`` prints it.
It writes what one looks at: the sheet, the plot, the samples, the embeddings and the
errors (``errors.json``, with the digests of the parts that made them:
:func:`brdfkit.demos.real_outputs.parts_used`).
The 17 dense tables (35 MB each, 0.59 GB) stay in memory, the
six the sheet renders in a temporary folder removed at the end
(:func:`brdfkit.demos.synthetic_training.scratch_folder`), unless ``keep_tables``.
``brdfkit demo --train`` is the synthetic training demo (:mod:`brdfkit.demos.synthetic_training`).
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import time

from brdfkit.errors import InputError

__all__ = ["SPARSE_MODEL", "COMPRESSIONS", "COMPRESSION_MODELS", "COMPRESSION_SETS", "COMPRESSION_STEPS",
           "INTERPOLATION_MODEL", "DEMO_MATERIALS", "SAMPLE_COUNTS", "SHEET_RESOLUTION", "RealDemoResult",
           "demo_materials", "check_models", "compression_labels", "run_real_demo"]

SPARSE_MODEL = "merl80-l40"
"""The built-in of the sparse reconstructions (trained without the test materials)."""
COMPRESSIONS = (("merl-rgl-l40", "in-sample"), ("merl-rgl-l7", "in-sample"), ("merl80-l40", "unseen"))
"""The built-ins that compress the full tables, in the demo's order, each with its kind:
``in-sample`` (the demo's materials were in its training set) or ``unseen`` (they were
not). Labels say what the embedding holds (:func:`compression_labels`): ``in-sample
basis-39 (merl-rgl-l40)`` (39 coefficients of its basis), ``in-sample 7-D (merl-rgl-l7)``."""
COMPRESSION_MODELS = tuple(m for m, _ in COMPRESSIONS)
COMPRESSION_SETS = {"in-sample": "trained on all 151 MERL + RGL materials, these included (the paper's "
                                  "compression protocol)",
                     "unseen": "trained without the 20 MERL test materials"}
"""What each kind of :data:`COMPRESSIONS` means, for the output."""
COMPRESSION_STEPS = 20
"""Most refinement steps of each compression (``brdfkit encode``: 80 for a basis embedding,
40 for a latent): 6 refinements (two materials, three models) in the demo's minute."""
INTERPOLATION_MODEL = "merl80-l40"
"""The compression model whose embeddings are blended (one of :data:`COMPRESSION_MODELS`).
The unseen one, not ``merl-rgl-l40``: its basis is the one the sparse reconstructions'
learnt prior uses, and editing materials that the model never saw is what a user does
with their own measurements, which no built-in was trained on."""
DEMO_MATERIALS = ("blue-metallic-paint", "teflon")
"""The materials ``brdfkit demo`` runs unless told otherwise (``only``): two of the four
shipped (:func:`demo_materials`), so that every job is shown once (the first material's
sheets and plot, the blend needs a second) in well under a minute; ``--only`` names
others, or all four."""
SAMPLE_COUNTS = (40, 400)
SHEET_RESOLUTION = 128
"""Render size of the comparison sheets and of the renders the error tables rank by, pixels:
at 128 a sphere is round, at 64 a blocky disc; the demo prints the renders' seconds."""


def demo_materials() -> list[str]:
    """Names of the shipped materials, in the demo's order."""
    from brdfkit.materials.nbrdf_networks import load_nbrdf_weights

    return list(load_nbrdf_weights())


def check_models() -> None:
    """Refuse, in one line, to run without the built-in models the demo uses.

    Raises
    ------
    InputError
        One of :data:`SPARSE_MODEL`, :data:`COMPRESSION_MODELS` is not installed.
    """
    from brdfkit.models.builtin import installed_bundles

    have = {m.name for m in installed_bundles()}
    missing = [n for n in dict.fromkeys((SPARSE_MODEL, *COMPRESSION_MODELS)) if n not in have]
    if missing:
        what = "no built-in model is installed" if not have else f"built-in model(s) not installed: {', '.join(missing)}"
        raise InputError(f"brdfkit demo runs the built-in models and {what} (see `brdfkit models`); "
                         f"`brdfkit demo --train` trains a small model on synthetic materials instead")


def compression_labels(latent_dims: dict) -> list[tuple[str, str, str, str]]:
    """Labels of the compressions of :data:`COMPRESSIONS`.

    Parameters
    ----------
    latent_dims
        ``{model: text}`` such as ``"residual-39"``: the kind and size of each model's
        default embedding (the labels say what the files hold, not what their names
        suggest), or ``{model: latent size}``.

    Returns
    -------
    list
        ``[(model, kind, label, short)]`` in the demo's order, ``kind`` that of
        :data:`COMPRESSIONS`, ``label`` such as ``in-sample 40-D (merl-rgl-l40)`` (the
        console table, ``errors.json``, the times), ``short`` such as ``in-sample 40-D``
        (the sheet's tiles, the plot's legend; the full labels where two would coincide).
    """
    size = {m: f"{d}-D" if isinstance(d, int) else str(d) for m, d in latent_dims.items()}
    short = [f"{kind} {size[m]}" for m, kind in COMPRESSIONS]
    full = [f"{s} ({m})" for s, (m, _) in zip(short, COMPRESSIONS)]
    if len(set(short)) < len(short):
        short = full
    return [(m, kind, f, s) for (m, kind), f, s in zip(COMPRESSIONS, full, short)]


@dataclasses.dataclass
class RealDemoResult:
    """What :func:`run_real_demo` measured and wrote.

    Attributes
    ----------
    out_dir
        The demo's folder.
    materials
        The materials run, in order.
    sparse_method
        The method of the sparse reconstructions (``prior`` with the shipped models).
    columns
        Labels of the error columns: the sparse method and N (``prior 40``), then the
        compressions' labels (``in-sample 40-D (merl-rgl-l40)``).
    errors
        ``[(material, [BRDF log RMSE per column])]`` against the material's table.
    renders
        ``[(material, [(PSNR dB, Delta E 2000) per column])]`` of reference-scene renders
        at ``resolution`` against the material's (empty without renders): what the
        console's tables rank by.
    times
        ``[(step, seconds)]``, the last the whole demo.
    files
        Every file written and kept (samples, embeddings, ``errors.json``, sheet, plot;
        the tables with ``keep_tables``), sorted.
    sheet, plot
        The comparison sheet and the plot (``None``: not made).
    sheet_material
        The material they show.
    resolution
        Render size of the sheet, pixels.
    """

    out_dir: str
    materials: list
    sparse_method: str
    columns: list
    errors: list
    times: list
    files: list
    sheet: str | None
    plot: str | None
    sheet_material: str
    resolution: int
    keep_tables: bool = True
    """Whether the dense tables were written into the output folder."""
    compressions: list = dataclasses.field(default_factory=list)
    """``[(model, kind, label, short)]`` of the compressions (:func:`compression_labels`)."""
    compression_steps: int = COMPRESSION_STEPS
    """Most steps each compression was refined on screen."""
    renders: list = dataclasses.field(default_factory=list)
    """``[(material, [(PSNR dB, Delta E 2000) per column])]`` (see the class doc)."""


def _pick(only) -> list[str]:
    names = demo_materials()
    if not only:
        return [n for n in DEMO_MATERIALS if n in names]
    unknown = [n for n in only if n not in names]
    if unknown:
        raise InputError(f"unknown demo material(s) {', '.join(unknown)}; known: {', '.join(names)}")
    return list(dict.fromkeys(only))


def run_real_demo(out_dir: str = "brdfkit-demo", *, only=None, seed: int = 0, device="auto", render: bool = True,
                  resolution: int = SHEET_RESOLUTION, keep_tables: bool = False,
                  steps: int | None = None) -> RealDemoResult:
    """Run the demo (see the module doc), reporting progress on stderr.

    Parameters
    ----------
    out_dir
        Folder for the samples, embeddings, errors, sheet and plot (and tables).
    only
        Names of the materials to run (default :data:`DEMO_MATERIALS`; any of
        :func:`demo_materials`).
    seed
        Seed of the sample draws.
    device
        ``auto``, ``cpu`` or ``cuda``.
    render
        Also the comparison sheet (quadrature renders; the plot is made either way).
    resolution
        Render size of the sheet, pixels.
    keep_tables
        Also write the dense tables: the materials (``materials/``), the sparse
        reconstructions (``reconstructed/``), the compressions and the blend
        (``decoded/``), 35 MB each.
    steps
        Most steps each compression's latent is refined on screen (default
        :data:`COMPRESSION_STEPS`; 0: the encoder's pass alone).

    Raises
    ------
    InputError
        The built-in models are not installed (:func:`check_models`), an unknown
        material, a bad resolution or step count.
    """
    from brdfkit.render.objective import ObjectiveConfig
    from brdfkit.demos.synthetic_training import scratch_folder

    check_models()
    names = _pick(only)
    if not 8 <= resolution <= 1024:
        raise InputError(f"--resolution must be between 8 and 1024 pixels, got {resolution}")
    refine_steps = COMPRESSION_STEPS if steps is None else steps
    ObjectiveConfig(steps=refine_steps)  # its one-line refusal, before any work
    out_dir = os.path.abspath(out_dir)
    os.makedirs(out_dir, exist_ok=True)
    # The sheet takes its tiles' labels from its inputs' file stems: it renders files named
    # by label in a temporary folder, written there or linked to the kept tables.
    sheet_dir = scratch_folder(out_dir, keep_tables=False) if render else contextlib.nullcontext(None)
    with sheet_dir as scratch:
        return _run(out_dir, scratch, keep_tables, names, seed, device, resolution, int(refine_steps))


def _run(out_dir, scratch, keep_tables, names, seed, device, resolution, refine_steps) -> RealDemoResult:
    """:func:`run_real_demo` in ``out_dir``; ``scratch``: the temporary folder of the
    sheet's inputs (``None``: no sheet)."""
    import torch

    from brdfkit.console import console
    from brdfkit.demos.real_outputs import DemoFiles, StepClock, step_times, write_figures
    from brdfkit.materials.nbrdf_networks import load_nbrdf_weights, nbrdf_table

    err = console()
    clock = StepClock()
    t_all = time.monotonic()
    files = DemoFiles(out_dir, scratch, keep_tables, clock)
    err.print(f"[bold]brdfkit demo[/]: {len(names)} MERL test material(s) with the built-in models; "
              f"writing into {out_dir}"
              + ("" if keep_tables else " (the dense tables stay in memory; --keep-tables writes them)"))
    err.print(f"using {torch.get_num_threads()} torch thread(s) (set OMP_NUM_THREADS to choose)")
    with clock("load models"):
        models = _load_models(device)
        weights = load_nbrdf_weights()
    method = models.choice.method
    columns = [f"{label} {n}" for label, _, _ in models.methods for n in SAMPLE_COUNTS]
    columns += [label for _, _, label, _ in models.comps]
    refined = f"refined on screen, at most {refine_steps} steps" if refine_steps > 0 else "encoder pass only"
    # What the plot and the sheet show of the first material ({result key: label}): the
    # default method from both sample counts and all three compressions, so that in-sample
    # and unseen compression sit side by side. IPCA is left to the table so that the sheet
    # keeps six tiles (its width and render time of two compressions).
    tiles = {"reference": names[0],
             **{f"{method} {n}": f"{method}, {n} samples" for n in SAMPLE_COUNTS},
             **{m: short for m, _, _, short in models.comps}}

    # Each tile's column of the error tables (a compression's tile is keyed by its model).
    column_of = {"reference": "reference", **{k: k for k in tiles if k in columns},
                 **{m: label for m, _, label, _ in models.comps}}
    rows, embs, shown, sheet_inputs, scored, sheet_renders = [], {}, {}, {}, [], {}
    for name in names:
        err.print(f"{name}: decoding its NBRDF network, reconstructing, compressing ({refined})")
        with clock("decode NBRDF tables"):
            ref = nbrdf_table(weights[name], device=device)
        first = name == names[0]
        # Only the first material's results are the sheet's tiles and the plot's lines.
        row, inputs, results, emb, tables = _material(name, ref, models, files, clock, tiles if first else {},
                                                       seed, device, refine_steps)
        if scratch is not None:
            from brdfkit.demos.real_outputs import render_scores

            with clock("render scores"):
                scores, images = render_scores(ref, [tables[c] for c in columns], resolution)
            scored.append((name, scores))
            if first:  # the reference-scene sheet shows these renders: made once
                by_column = dict(zip(["reference", *columns], images))
                sheet_renders = {k: by_column[column_of[k]] for k in tiles}
        if emb is not None:
            embs[name] = emb
        if first:
            shown = {name: ref, **results}
            sheet_inputs = inputs
        rows.append((name, row))
    if len(names) > 1:
        _interpolate(names[0], names[1], embs, models, files, clock, err)

    name = names[0]
    plot_path, sheet_path = write_figures(files, err, clock, name, shown, sheet_inputs, tiles, resolution,
                                          compressions=COMPRESSION_MODELS, live=INTERPOLATION_MODEL,
                                          renders=sheet_renders)
    times = step_times(clock, models.methods, models.comps, len(names), len(SAMPLE_COUNTS), files, refine_steps,
                       len(tiles), resolution)
    files.written.append(_write_errors(out_dir, models, columns, rows, refine_steps, seed, scored, files.sheets))
    times.append(("whole demo", time.monotonic() - t_all))
    return RealDemoResult(out_dir, names, method, columns, rows, times, sorted(files.written), sheet_path,
                          plot_path, name, resolution, keep_tables, models.comps, refine_steps, scored)


@dataclasses.dataclass
class _Models:
    """The demo's loaded models (:func:`_load_models`)."""

    choice: object
    """:func:`brdfkit.methods.choice.choose`'s choice of the sparse reconstructions."""
    methods: list
    """``[(label, method, loaded model)]`` of the sparse reconstructions: the choice, IPCA."""
    hyper: dict
    """``{name: decoder}`` of :data:`COMPRESSION_MODELS` (:class:`brdfkit.embeddings.Decoder`:
    the basis of a built-in that ships one, else its hypernetwork)."""
    comps: list
    """``[(model, kind, label, short)]`` of the compressions (:func:`compression_labels`)."""


def _load_models(device) -> _Models:
    """Load the sparse reconstructions' methods (:data:`SPARSE_MODEL`'s default, and IPCA
    on its basis) and the compression hypernetworks on ``device``."""
    from brdfkit.embeddings import choose_decoder
    from brdfkit.methods import get_method
    from brdfkit.methods.choice import AUTO, choose

    choice = choose(AUTO, SPARSE_MODEL)
    sparse_method = get_method(choice.method)
    sparse_model = sparse_method.load(choice.path, device)
    ipca = get_method("ipca")
    ipca_model = ipca.load(SPARSE_MODEL)
    hyper = {m: choose_decoder(None, m, device) for m in COMPRESSION_MODELS}
    comps = compression_labels({m: d.default_size if d.kind == "hypernet" else f"{d.kind}-{d.default_size}"
                                for m, d in hyper.items()})
    methods = [(choice.method, sparse_method, sparse_model), ("ipca", ipca, ipca_model)]
    return _Models(choice, methods, hyper, comps)


def _material(name, ref, models: _Models, files, clock, tiles: dict, seed, device, refine_steps):
    """Reconstruct the material ``name`` (its table ``ref``, ``(90, 90, 180, 3)``, 1/sr)
    from :data:`SAMPLE_COUNTS` samples by each sparse method, and compress it with each
    hypernetwork, refined for at most ``refine_steps`` steps; write the samples, embeddings and tables
    (``files``: :class:`brdfkit.demos.real_outputs.DemoFiles`), and the sheet's inputs of
    the results that ``tiles`` (``{result key: label}``; empty: none) names.

    Returns
    -------
    tuple
        ``(row, inputs, shown, emb, tables)``: the BRDF log RMSE of each column,
        ``{result key: sheet input or None}``, ``{label: table}`` of the results ``tiles``
        names, the embedding of :data:`INTERPOLATION_MODEL`, and ``{column: table}``.
    """
    from brdfkit import api
    from brdfkit.acquisition.sampling import draw_samples
    from brdfkit.evaluation.metrics import brdf_log_rmse
    from brdfkit.io.embedding import write_embedding
    from brdfkit.io.samples import write_samples

    inputs = {"reference": files.table("materials", name, ref, tiles.get("reference"))}
    found, shown, emb_mix, tables = {}, {}, None, {}
    for n in SAMPLE_COUNTS:
        samples = draw_samples(ref, n, seed=seed, source=f"{name}-{n}")
        write_samples(files.keep("samples", f"{name}-{n}.csv"), samples)
        for label, method, model in models.methods:
            with clock(f"sparse {label}"):
                pred, emb = method.sparse(samples, model, seed=seed, device=device)
            key = f"{label} {n}"
            with clock("score"):
                found[key] = brdf_log_rmse(pred, ref)
            tables[key] = pred
            inputs[key] = files.table("reconstructed", f"{name}-{label}-{n}", pred, tiles.get(key))
            if emb is not None:  # a hypernetwork default makes one
                write_embedding(files.keep("embeddings", f"{name}-{label}-{n}.emb"), emb)
            if key in tiles:
                shown[tiles[key]] = pred
    row = [found[f"{label} {n}"] for label, _, _ in models.methods for n in SAMPLE_COUNTS]
    for m, _, label, short in models.comps:
        with clock(f"encode {m}"):
            emb = api.encode(ref, models.hyper[m], source=name, refine=refine_steps > 0, steps=refine_steps)
        with clock(f"decode {m}"):
            dec = api.decode(emb, models.hyper[m])
        with clock("score"):
            row.append(brdf_log_rmse(dec, ref))
        tables[label] = dec
        write_embedding(files.keep("embeddings", f"{name}-{m}.emb"), emb)
        inputs[m] = files.table("decoded", f"{name}-{m}", dec, tiles.get(m))
        if m == INTERPOLATION_MODEL:
            emb_mix = emb
        if m in tiles:
            shown[short] = dec
    return row, inputs, shown, emb_mix, tables


def _interpolate(a, b, embs, models: _Models, files, clock, err) -> None:
    """Blend the :data:`INTERPOLATION_MODEL` embeddings ``embs`` of the materials ``a`` and
    ``b`` at ``t = 0.5``, decode the blend, and write both."""
    from brdfkit import api
    from brdfkit.io.embedding import write_embedding

    m = INTERPOLATION_MODEL
    err.print(f"interpolating {a} and {b} at t = 0.5 ({m})")
    with clock("interpolate"):
        mix = api.interpolate(embs[a], embs[b], 0.5)
        mixed = api.decode(mix, models.hyper[m])
    stem = f"{a}+{b}-t0.5-{m}"
    write_embedding(files.keep("embeddings", stem + ".emb"), mix)
    files.table("decoded", stem, mixed)


def _write_errors(out_dir, models: _Models, columns, rows, refine_steps, seed, scored, sheets) -> str:
    """``OUT/errors.json`` (:func:`brdfkit.demos.real_outputs.write_errors`) with what
    made its figures; returns its path."""
    from brdfkit.demos.real_outputs import parts_used, write_errors

    made = {"sparse_model": SPARSE_MODEL, "sparse_method": models.choice.method, "compression_models":
            list(COMPRESSION_MODELS), "compressions": [{"column": label, "model": m, "kind": kind, "embedding":
            models.hyper[m].kind, "size": models.hyper[m].default_size} for m, kind, label, _ in models.comps],
            "compression_steps": refine_steps, "interpolation_model": INTERPOLATION_MODEL, "seed": seed,
            "parts": parts_used(SPARSE_MODEL, [method.part for _, method, _ in models.methods], models.hyper)}
    return write_errors(out_dir, made, columns, rows, scored, sheets)
