"""The demo on real materials with the built-in models (``brdfkit demo``).

Four of the 20 MERL test materials, shipped as their published NBRDF networks and decoded
to dense tables (:mod:`brdfkit.nbrdf_tables`), go through everything brdfkit does with
the built-in models (``docs/models.md``), none of which needs training here:

* sparse reconstruction from 40 and 400 samples (:func:`brdfkit.samples.draw_samples`)
  with ``brdfkit sparse``'s default method on ``merl80-l40`` (its learnt prior,
  :func:`brdfkit.methods.model_spec.choose`), which never saw these materials, and with
  IPCA on the same PCA basis beside it (Nielsen et al. 2015);
* compression: the full table encoded and decoded by the hypernetworks ``merl80-l40``
  (40 numbers) and ``merl-rgl-l7`` (7 numbers; trained on all 151 materials, these
  included, as a compression model is);
* an interpolation of two materials' ``merl80-l40`` embeddings at ``t = 0.5``;
* errors (:func:`brdfkit.metrics.brdf_log_rmse`) and times, a comparison sheet
  (:func:`brdfkit.sheet.comparison_sheet`) and a plot (:func:`brdfkit.plot.plot_brdfs`)
  of one material against its reconstructions.

:func:`run_real_demo` returns what it measured and wrote; ``brdfkit demo`` prints it.
It writes what one looks at: the sheet, the plot, the samples, the embeddings and the
errors (``errors.json``). The 29 dense tables (35 MB each, 1 GB) stay in memory, the
six the sheet renders in a temporary folder removed at the end
(:func:`brdfkit.demo.scratch_folder`), unless ``keep_tables``.
``brdfkit demo --train`` is the synthetic training demo (:mod:`brdfkit.demo`).
"""

from __future__ import annotations

import dataclasses
import json
import os
import time

from .errors import InputError

__all__ = ["SPARSE_MODEL", "COMPRESSION_MODELS", "SAMPLE_COUNTS", "SHEET_RESOLUTION", "RealDemoResult",
           "demo_materials", "check_models", "run_real_demo"]

SPARSE_MODEL = "merl80-l40"
"""The built-in of the sparse reconstructions (trained without the test materials)."""
COMPRESSION_MODELS = ("merl80-l40", "merl-rgl-l7")
"""The built-in hypernetworks that compress the full tables; the first interpolates."""
SAMPLE_COUNTS = (40, 400)
SHEET_RESOLUTION = 64
"""Render size of the comparison sheet, pixels: its six quadrature renders of 64 px took
6.2 s on the project's idle 2-core machine (``docs/demo.md``)."""


def demo_materials() -> list[str]:
    """Names of the shipped materials, in the demo's order."""
    from .nbrdf_tables import load_nbrdf_weights

    return list(load_nbrdf_weights())


def check_models() -> None:
    """Refuse, in one line, to run without the built-in models the demo uses.

    Raises
    ------
    InputError
        One of :data:`SPARSE_MODEL`, :data:`COMPRESSION_MODELS` is not installed.
    """
    from .model.builtin import builtin_models

    have = {m.name for m in builtin_models()}
    missing = [n for n in dict.fromkeys((SPARSE_MODEL, *COMPRESSION_MODELS)) if n not in have]
    if missing:
        what = "no built-in model is installed" if not have else f"built-in model(s) not installed: {', '.join(missing)}"
        raise InputError(f"brdfkit demo runs the built-in models and {what} (see `brdfkit models`); "
                         f"`brdfkit demo --train` trains a small model on synthetic materials instead")


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
        Labels of the error columns.
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
                  resolution: int = SHEET_RESOLUTION, keep_tables: bool = False) -> RealDemoResult:
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

    Raises
    ------
    InputError
        The built-in models are not installed (:func:`check_models`), an unknown
        material, a bad resolution.
    """
    from .demo import scratch_folder

    check_models()
    names = _pick(only)
    if not 8 <= resolution <= 1024:
        raise InputError(f"--resolution must be between 8 and 1024 pixels, got {resolution}")
    out_dir = os.path.abspath(out_dir)
    os.makedirs(out_dir, exist_ok=True)
    with scratch_folder(out_dir, keep_tables) as scratch:
        return _run(out_dir, scratch, names, seed, device, render, resolution)


def _run(out_dir, scratch, names, seed, device, render, resolution) -> RealDemoResult:
    """:func:`run_real_demo` in ``out_dir``; ``scratch``: the temporary folder of the
    sheet's tables (``None``: every table is kept in the output folder)."""
    import torch

    from . import api
    from .atomic import atomic_open
    from .console import console
    from .embedding import write_embedding
    from .merl import write_merl
    from .methods import get_method
    from .methods.model_spec import AUTO, choose
    from .metrics import brdf_log_rmse
    from .nbrdf_tables import load_nbrdf_weights, nbrdf_table
    from .plot import plot_brdfs
    from .samples import draw_samples, write_samples

    err = console()
    clock = _Clock()
    t_all = time.monotonic()
    kept = ("materials", "reconstructed", "decoded") if scratch is None else ()
    dirs = {d: os.path.join(out_dir, d) for d in ("samples", "embeddings", *kept)}
    for d in dirs.values():
        os.makedirs(d, exist_ok=True)
    err.print(f"[bold]brdfkit demo[/]: {len(names)} MERL test material(s) with the built-in models; "
              f"writing into {out_dir}"
              + ("" if scratch is None else " (the dense tables stay in memory; --keep-tables writes them)"))
    err.print(f"using {torch.get_num_threads()} torch thread(s) (set OMP_NUM_THREADS to choose)")
    written, n_tables = [], [0]

    def write_table(folder, stem, table, sheet=False):
        """The table's file: in ``OUT/folder`` when tables are kept, else in the scratch
        folder when the sheet renders it (its file stem is the sheet's label), else none."""
        if scratch is None:
            path = os.path.join(dirs[folder], stem + ".binary")
            written.append(path)
        elif sheet:
            path = os.path.join(scratch, stem + ".binary")
        else:
            return None
        with clock("write tables"):
            write_merl(path, table)
        n_tables[0] += 1
        return path

    with clock("load models"):
        choice = choose(AUTO, SPARSE_MODEL)
        sparse_method = get_method(choice.method)
        sparse_model = sparse_method.load(choice.path, device)
        ipca = get_method("ipca")
        ipca_model = ipca.load(SPARSE_MODEL)
        hyper = {m: api.load_model(m, device) for m in COMPRESSION_MODELS}
        weights = load_nbrdf_weights()
    methods = [(choice.method, sparse_method, sparse_model), ("ipca", ipca, ipca_model)]
    columns = [f"{label} {n}" for label, _, _ in methods for n in SAMPLE_COUNTS]
    columns += [f"full {hyper[m].cfg.latent_dim}-D" for m in COMPRESSION_MODELS]
    # What the plot and the sheet show of the first material: the default method from
    # both sample counts, IPCA from the larger, and both compressions.
    shown_keys = (f"{choice.method} {SAMPLE_COUNTS[0]}", f"{choice.method} {SAMPLE_COUNTS[-1]}",
                  f"ipca {SAMPLE_COUNTS[-1]}")
    sheet_keys = ("reference", *shown_keys, *COMPRESSION_MODELS) if render else ()

    rows, embs, shown, sheet_inputs = [], {}, {}, {}
    for name in names:
        err.print(f"{name}: decoding its NBRDF network, reconstructing, compressing")
        with clock("decode NBRDF tables"):
            ref = nbrdf_table(weights[name], device=device)
        first = name == names[0]
        files = {"reference": write_table("materials", name, ref, first and "reference" in sheet_keys)}
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
                files[key] = write_table("reconstructed", f"{name}-{label}-{n}", pred, first and key in sheet_keys)
                if emb is not None:  # a hypernetwork default makes one
                    written.append(os.path.join(dirs["embeddings"], f"{name}-{label}-{n}.emb"))
                    write_embedding(written[-1], emb)
                if first and key in shown_keys:
                    shown[key] = pred
        row = [found[f"{label} {n}"] for label, _, _ in methods for n in SAMPLE_COUNTS]
        for m in COMPRESSION_MODELS:
            with clock(f"encode {m}"):
                emb = api.encode(hyper[m], ref, source=name)
            with clock(f"decode {m}"):
                dec = api.decode(hyper[m], emb)
            with clock("score"):
                row.append(brdf_log_rmse(dec, ref))
            written.append(os.path.join(dirs["embeddings"], f"{name}-{m}.emb"))
            write_embedding(written[-1], emb)
            files[m] = write_table("decoded", f"{name}-{m}", dec, first and m in sheet_keys)
            embs[(name, m)] = emb
            if first:
                shown[f"hypernet {m}"] = dec
        if first:
            shown = {name: ref, **shown}
            sheet_inputs = files
        rows.append((name, row))

    if len(names) > 1:
        a, b, m = names[0], names[1], COMPRESSION_MODELS[0]
        err.print(f"interpolating {a} and {b} at t = 0.5 ({m})")
        with clock("interpolate"):
            mix = api.interpolate(embs[(a, m)], embs[(b, m)], 0.5)
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
        from .sheet import comparison_sheet

        sheet_path = os.path.join(out_dir, f"sheet-{name}.png")
        preds = [sheet_inputs[k] for k in (*shown_keys, *COMPRESSION_MODELS)]
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
    for m in COMPRESSION_MODELS:
        times.append((f"encode a full table, {m} (mean)", clock.mean(f"encode {m}")))
        times.append((f"decode a full table, {m} (mean)", clock.mean(f"decode {m}")))
    if len(names) > 1:
        times.append(("interpolate two embeddings + decode", clock.total("interpolate")))
    times.append((f"score the results (brdf_log_rmse, {len(clock.spent.get('score', ()))})",
                  clock.total("score")))
    where = "" if scratch is None else " the sheet renders, to a temporary folder"
    times.append((f"write the MERL tables{where} ({n_tables[0]})", clock.total("write tables")))
    times.append(("plot", clock.total("plot")))
    if render:
        times.append((f"comparison sheet ({len(preds) + 1} renders, {resolution} px)", clock.total("sheet")))
    errors_path = os.path.join(out_dir, "errors.json")
    doc = {"format": "brdfkit-demo-errors", "metric": "brdf_log_rmse", "sparse_model": SPARSE_MODEL,
           "sparse_method": choice.method, "compression_models": list(COMPRESSION_MODELS), "seed": seed,
           "columns": columns, "errors": {n: dict(zip(columns, map(float, row))) for n, row in rows}}
    with atomic_open(errors_path, "w", encoding="utf-8") as f:
        json.dump(doc, f, indent=1)
    written.append(errors_path)
    times.append(("whole demo", time.monotonic() - t_all))
    return RealDemoResult(out_dir, names, choice.method, columns, rows, times, sorted(written), sheet_path,
                          plot_path, name, resolution, scratch is None)
