"""The demo on real materials with the built-in models (``brdfkit demo``).

Four of the 20 MERL test materials, shipped as their published NBRDF networks and decoded
to dense tables (:mod:`brdfkit.materials.nbrdf_networks`), go through everything brdfkit does with
the built-in models (``docs/models.md``), none of which needs training here:

* sparse reconstruction from 40 and 400 samples (:func:`brdfkit.acquisition.sampling.draw_samples`)
  with ``brdfkit sparse``'s default method on ``merl80-l40`` (its learnt prior,
  :func:`brdfkit.methods.choice.choose`), which never saw these materials, and with
  IPCA on the same PCA basis beside it (Nielsen et al. 2015);
* compression of the full table by three hypernetworks (:data:`COMPRESSIONS`), each
  encode refined on screen for :data:`COMPRESSION_BUDGET` seconds
  (:func:`brdfkit.api.encode`, :func:`brdfkit.hypernet.refine_on_screen.compress_table`), then decoded,
  of two kinds, labelled as such wherever they appear:

  - *in-sample*: ``merl-rgl-l40`` (40 numbers) and ``merl-rgl-l7`` (7 numbers), trained
    on all 151 MERL + RGL proxies, these four included: the paper's compression protocol
    (Gokbudak et al. 2024, Sec. 4.2), a compression model being trained on what it
    compresses;
  - *unseen*: ``merl80-l40`` (40 numbers), trained without the 20 test materials: how
    well a 40-D latent holds a material that the model never saw;

* an interpolation of two materials' ``merl80-l40`` embeddings at ``t = 0.5``
  (:data:`INTERPOLATION_MODEL`);
* errors (:func:`brdfkit.evaluation.metrics.brdf_log_rmse`) and times, a comparison sheet
  (:func:`brdfkit.figures.comparison_sheet.comparison_sheet`) and a plot (:func:`brdfkit.figures.brdf_plot.plot_brdfs`)
  of one material against the learnt prior's reconstructions and the three compressions.

:func:`run_real_demo` returns what it measured and wrote; ``brdfkit demo`` prints it.
It writes what one looks at: the sheet, the plot, the samples, the embeddings and the
errors (``errors.json``). The 33 dense tables (35 MB each, 1.2 GB) stay in memory, the
six the sheet renders in a temporary folder removed at the end
(:func:`brdfkit.demos.synthetic_training.scratch_folder`), unless ``keep_tables``.
``brdfkit demo --train`` is the synthetic training demo (:mod:`brdfkit.demos.synthetic_training`).
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import os
import shutil
import time

from brdfkit.errors import InputError

__all__ = ["SPARSE_MODEL", "COMPRESSIONS", "COMPRESSION_MODELS", "COMPRESSION_KINDS", "COMPRESSION_BUDGET",
           "INTERPOLATION_MODEL", "SAMPLE_COUNTS", "SHEET_RESOLUTION", "RealDemoResult", "demo_materials",
           "check_models", "compression_labels", "run_real_demo"]

SPARSE_MODEL = "merl80-l40"
"""The built-in of the sparse reconstructions (trained without the test materials)."""
COMPRESSIONS = (("merl-rgl-l40", "in-sample"), ("merl-rgl-l7", "in-sample"), ("merl80-l40", "unseen"))
"""The built-in hypernetworks that compress the full tables, in the demo's order, each with
its kind: ``in-sample`` (the demo's materials were in its training set) or ``unseen``
(they were not). Labels add the latent size: ``in-sample 40-D (merl-rgl-l40)``
(:func:`compression_labels`)."""
COMPRESSION_MODELS = tuple(m for m, _ in COMPRESSIONS)
COMPRESSION_KINDS = {"in-sample": "trained on all 151 MERL + RGL materials, these included (the paper's "
                                  "compression protocol)",
                     "unseen": "trained without the 20 MERL test materials"}
"""What each kind of :data:`COMPRESSIONS` means, for the output."""
COMPRESSION_BUDGET = 1.0
"""Seconds each compression's latent is refined on screen (``brdfkit encode`` refines for
:data:`brdfkit.hypernet.refine_on_screen.DEFAULT_BUDGET`, 3 s): 12 refinements (four materials, three
models), plus about 0.5 s of set-up each, so the demo stays about a minute."""
INTERPOLATION_MODEL = "merl80-l40"
"""The compression model whose embeddings are blended (one of :data:`COMPRESSION_MODELS`).
The unseen one, not ``merl-rgl-l40``: its latent space is the one the sparse
reconstructions use, and editing materials that the model never saw is what a user does
with their own measurements, which no built-in was trained on."""
SAMPLE_COUNTS = (40, 400)
SHEET_RESOLUTION = 64
"""Render size of the comparison sheet, pixels: its six quadrature renders of 64 px took
6.2 s on the project's idle 2-core machine (``docs/demo.md``)."""


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
    from brdfkit.models.builtin import builtin_models

    have = {m.name for m in builtin_models()}
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
        ``{model: latent size}`` of the loaded models (the labels say what the model
        files hold, not what their names suggest).

    Returns
    -------
    list
        ``[(model, kind, label, short)]`` in the demo's order, ``kind`` that of
        :data:`COMPRESSIONS`, ``label`` such as ``in-sample 40-D (merl-rgl-l40)`` (the
        console table, ``errors.json``, the times), ``short`` such as ``in-sample 40-D``
        (the sheet's tiles, the plot's legend; the full labels where two would coincide).
    """
    short = [f"{kind} {latent_dims[m]}-D" for m, kind in COMPRESSIONS]
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
    compression_budget: float = COMPRESSION_BUDGET
    """Seconds each compression was refined on screen."""


class _Clock:
    """Accumulates the seconds spent in named steps (``with clock("step"):``)."""

    def __init__(self):
        self.spent: dict[str, list[float]] = {}

    def __call__(self, step: str):
        clock = self

        class _Span:
            def __enter__(self):
                self.t = time.monotonic()

            def __exit__(self, *exc):
                clock.spent.setdefault(step, []).append(time.monotonic() - self.t)

        return _Span()

    def total(self, step: str) -> float:
        return float(sum(self.spent.get(step, ())))

    def mean(self, step: str) -> float:
        v = self.spent.get(step, ())
        return float(sum(v) / len(v)) if v else 0.0


def _pick(only) -> list[str]:
    names = demo_materials()
    if not only:
        return names
    unknown = [n for n in only if n not in names]
    if unknown:
        raise InputError(f"unknown demo material(s) {', '.join(unknown)}; known: {', '.join(names)}")
    return list(dict.fromkeys(only))


def run_real_demo(out_dir: str = "brdfkit-demo", *, only=None, seed: int = 0, device="auto", render: bool = True,
                  resolution: int = SHEET_RESOLUTION, keep_tables: bool = False,
                  budget: float | None = None) -> RealDemoResult:
    """Run the demo (see the module doc), reporting progress on stderr.

    Parameters
    ----------
    out_dir
        Folder for the samples, embeddings, errors, sheet and plot (and tables).
    only
        Names of the materials to run (default all four; :func:`demo_materials`).
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
    budget
        Seconds each compression's latent is refined on screen (default
        :data:`COMPRESSION_BUDGET`; 0: the encoder's pass alone).

    Raises
    ------
    InputError
        The built-in models are not installed (:func:`check_models`), an unknown
        material, a bad resolution or budget.
    """
    from brdfkit.hypernet.refine_on_screen import CompressConfig
    from brdfkit.demos.synthetic_training import scratch_folder

    check_models()
    names = _pick(only)
    if not 8 <= resolution <= 1024:
        raise InputError(f"--resolution must be between 8 and 1024 pixels, got {resolution}")
    budget = COMPRESSION_BUDGET if budget is None else budget
    CompressConfig(budget=budget)  # its one-line refusal, before any work
    out_dir = os.path.abspath(out_dir)
    os.makedirs(out_dir, exist_ok=True)
    # The sheet takes its tiles' labels from its inputs' file stems, so it renders files
    # named by label in a temporary folder, written there or linked to the kept tables.
    sheet_dir = scratch_folder(out_dir, keep_tables=False) if render else contextlib.nullcontext(None)
    with sheet_dir as scratch:
        return _run(out_dir, scratch, keep_tables, names, seed, device, resolution, float(budget))


def _run(out_dir, scratch, keep_tables, names, seed, device, resolution, budget) -> RealDemoResult:
    """:func:`run_real_demo` in ``out_dir``; ``scratch``: the temporary folder of the
    sheet's inputs (``None``: no sheet)."""
    import torch

    from brdfkit import api
    from brdfkit.atomic import atomic_open
    from brdfkit.console import console
    from brdfkit.io.embedding import write_embedding
    from brdfkit.io.merl import write_merl
    from brdfkit.methods import get_method
    from brdfkit.methods.choice import AUTO, choose
    from brdfkit.evaluation.metrics import brdf_log_rmse
    from brdfkit.materials.nbrdf_networks import load_nbrdf_weights, nbrdf_table
    from brdfkit.figures.brdf_plot import plot_brdfs
    from brdfkit.io.samples import write_samples
    from brdfkit.acquisition.sampling import draw_samples

    err = console()
    clock = _Clock()
    t_all = time.monotonic()
    render = scratch is not None
    kept = ("materials", "reconstructed", "decoded") if keep_tables else ()
    dirs = {d: os.path.join(out_dir, d) for d in ("samples", "embeddings", *kept)}
    for d in dirs.values():
        os.makedirs(d, exist_ok=True)
    err.print(f"[bold]brdfkit demo[/]: {len(names)} MERL test material(s) with the built-in models; "
              f"writing into {out_dir}"
              + ("" if keep_tables else " (the dense tables stay in memory; --keep-tables writes them)"))
    err.print(f"using {torch.get_num_threads()} torch thread(s) (set OMP_NUM_THREADS to choose)")
    written, n_tables = [], [0]

    def write_table(folder, stem, table, tile=None):
        """Write ``OUT/folder/stem.binary`` when tables are kept, and the sheet's input
        ``scratch/TILE.binary`` (``tile``: its label on the sheet) when it renders one;
        returns the latter, else ``None``."""
        kept_path = None
        if keep_tables:
            kept_path = os.path.join(dirs[folder], stem + ".binary")
            with clock("write tables"):
                write_merl(kept_path, table)
            written.append(kept_path)
            n_tables[0] += 1
        if tile is None or scratch is None:
            return None
        path = os.path.join(scratch, tile + ".binary")
        with clock("write tables"):
            if kept_path is None:
                write_merl(path, table)
                n_tables[0] += 1
            else:  # the kept file, without a second 35 MB write where hard links work
                try:
                    os.link(kept_path, path)
                except OSError:
                    shutil.copyfile(kept_path, path)
        return path

    with clock("load models"):
        choice = choose(AUTO, SPARSE_MODEL)
        sparse_method = get_method(choice.method)
        sparse_model = sparse_method.load(choice.path, device)
        ipca = get_method("ipca")
        ipca_model = ipca.load(SPARSE_MODEL)
        hyper = {m: api.load_model(m, device) for m in COMPRESSION_MODELS}
        weights = load_nbrdf_weights()
    comps = compression_labels({m: hyper[m].cfg.latent_dim for m in COMPRESSION_MODELS})
    methods = [(choice.method, sparse_method, sparse_model), ("ipca", ipca, ipca_model)]
    columns = [f"{label} {n}" for label, _, _ in methods for n in SAMPLE_COUNTS]
    columns += [label for _, _, label, _ in comps]
    refined = f"refined on screen, {budget:g} s" if budget > 0 else "encoder pass only"
    encode_step = f"encode + refine {budget:g} s" if budget > 0 else "encode (encoder pass only)"  # in the times
    # What the plot and the sheet show of the first material ({result key: label}): the
    # default method from both sample counts and all three compressions, so that in-sample
    # and unseen compression sit side by side. IPCA is left to the table so that the sheet
    # keeps six tiles (its width and render time of two compressions).
    tiles = {"reference": names[0],
             **{f"{choice.method} {n}": f"{choice.method}, {n} samples" for n in SAMPLE_COUNTS},
             **{m: short for m, _, _, short in comps}}

    rows, embs, shown, sheet_inputs = [], {}, {}, {}
    for name in names:
        err.print(f"{name}: decoding its NBRDF network, reconstructing, compressing ({refined})")
        with clock("decode NBRDF tables"):
            ref = nbrdf_table(weights[name], device=device)
        first = name == names[0]

        def tile(key):
            return tiles.get(key) if first and render else None

        files = {"reference": write_table("materials", name, ref, tile("reference"))}
        found = {}
        for n in SAMPLE_COUNTS:
            samples = draw_samples(ref, n, seed=seed, source=f"{name}-{n}")
            written.append(os.path.join(dirs["samples"], f"{name}-{n}.csv"))
            write_samples(written[-1], samples)
            for label, method, model in methods:
                with clock(f"sparse {label}"):
                    pred, emb = method.sparse(samples, model, seed=seed, device=device)
                key = f"{label} {n}"
                with clock("score"):
                    found[key] = brdf_log_rmse(pred, ref)
                files[key] = write_table("reconstructed", f"{name}-{label}-{n}", pred, tile(key))
                if emb is not None:  # a hypernetwork default makes one
                    written.append(os.path.join(dirs["embeddings"], f"{name}-{label}-{n}.emb"))
                    write_embedding(written[-1], emb)
                if first and key in tiles:
                    shown[tiles[key]] = pred
        row = [found[f"{label} {n}"] for label, _, _ in methods for n in SAMPLE_COUNTS]
        for m, _, _, short in comps:
            with clock(f"encode {m}"):
                emb = api.encode(hyper[m], ref, source=name, refine=budget > 0, budget=budget)
            with clock(f"decode {m}"):
                dec = api.decode(hyper[m], emb)
            with clock("score"):
                row.append(brdf_log_rmse(dec, ref))
            written.append(os.path.join(dirs["embeddings"], f"{name}-{m}.emb"))
            write_embedding(written[-1], emb)
            files[m] = write_table("decoded", f"{name}-{m}", dec, tile(m))
            if m == INTERPOLATION_MODEL:
                embs[name] = emb
            if first:
                shown[short] = dec
        if first:
            shown = {name: ref, **shown}
            sheet_inputs = files
        rows.append((name, row))

    m = INTERPOLATION_MODEL
    if len(names) > 1:
        a, b = names[0], names[1]
        err.print(f"interpolating {a} and {b} at t = 0.5 ({m})")
        with clock("interpolate"):
            mix = api.interpolate(embs[a], embs[b], 0.5)
            mixed = api.decode(hyper[m], mix)
        stem = f"{a}+{b}-t0.5-{m}"
        written.append(os.path.join(dirs["embeddings"], stem + ".emb"))
        write_embedding(written[-1], mix)
        write_table("decoded", stem, mixed)

    name = names[0]
    plot_path = os.path.join(out_dir, f"plot-{name}.png")
    err.print(f"plotting {name} against its reconstructions: {plot_path}")
    with clock("plot"):
        plot_brdfs(shown, plot_path)
    written.append(plot_path)
    sheet_path = None
    if render:
        from brdfkit.figures.comparison_sheet import comparison_sheet

        sheet_path = os.path.join(out_dir, f"sheet-{name}.png")
        preds = [sheet_inputs[k] for k in tiles if k != "reference"]
        err.print(f"rendering {name} and {len(preds)} reconstructions ({resolution} px): {sheet_path}")
        with clock("sheet"):
            comparison_sheet(sheet_inputs["reference"], preds, sheet_path, resolution=resolution)
        written.append(sheet_path)

    n_mat = len(names)
    times = [("load the built-in models", clock.total("load models")),
             (f"decode {n_mat} NBRDF network(s) to MERL tables", clock.total("decode NBRDF tables"))]
    for label, _, _ in methods:
        times.append((f"sparse reconstruction, {label} (mean of {n_mat * len(SAMPLE_COUNTS)})",
                      clock.mean(f"sparse {label}")))
    for m, _, label, _ in comps:
        times.append((f"{encode_step}, {label} (mean)", clock.mean(f"encode {m}")))
        times.append((f"decode, {label} (mean)", clock.mean(f"decode {m}")))
    if len(names) > 1:
        times.append(("interpolate two embeddings + decode", clock.total("interpolate")))
    times.append((f"score the results (brdf_log_rmse, {len(clock.spent.get('score', ()))})",
                  clock.total("score")))
    where = "" if keep_tables else " the sheet renders, to a temporary folder"
    times.append((f"write the MERL tables{where} ({n_tables[0]})", clock.total("write tables")))
    times.append(("plot", clock.total("plot")))
    if render:
        times.append((f"comparison sheet ({len(preds) + 1} renders, {resolution} px)", clock.total("sheet")))
    errors_path = os.path.join(out_dir, "errors.json")
    doc = {"format": "brdfkit-demo-errors", "metric": "brdf_log_rmse", "sparse_model": SPARSE_MODEL,
           "sparse_method": choice.method, "compression_models": list(COMPRESSION_MODELS),
           "compressions": [{"column": label, "model": m, "kind": kind, "latent_dim": hyper[m].cfg.latent_dim}
                            for m, kind, label, _ in comps],
           "compression_budget_s": budget, "interpolation_model": INTERPOLATION_MODEL, "seed": seed,
           "columns": columns, "errors": {n: dict(zip(columns, map(float, row))) for n, row in rows}}
    with atomic_open(errors_path, "w", encoding="utf-8") as f:
        json.dump(doc, f, indent=1)
    written.append(errors_path)
    times.append(("whole demo", time.monotonic() - t_all))
    return RealDemoResult(out_dir, names, choice.method, columns, rows, times, sorted(written), sheet_path,
                          plot_path, name, resolution, keep_tables, comps, budget)
