"""What the real-materials demo (:mod:`brdfkit.demos.real_materials`) writes, and the clock
of its steps: its output folders and the files it keeps, its dense tables (kept in the
output folder, or the comparison sheet's inputs in a temporary folder), the plot, the
comparison sheets, the page of the materials (``view.html``), the table of its steps'
seconds, ``errors.json`` (with the digests of the built-in parts that made it:
:func:`parts_used`), and their copies into the docs' gallery (``brdfkit demo --gallery
docs/images``).
"""

from __future__ import annotations

import os
import shutil
import time

__all__ = ["StepClock", "DemoFiles", "write_view", "write_figures", "step_times", "parts_used", "write_errors", "GALLERY",
           "check_gallery", "copy_to_gallery"]


class StepClock:
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


class DemoFiles:
    """The demo's output folder: its subfolders, the files kept there, and the dense tables.

    Parameters
    ----------
    out_dir
        The demo's folder: ``samples/`` and ``embeddings/`` are made there, and with
        ``keep_tables`` ``materials/``, ``reconstructed/`` and ``decoded/`` too.
    scratch
        The temporary folder of the sheet's inputs (``None``: no sheet).
    keep_tables
        Write the dense tables into ``out_dir``.
    clock
        Times the table writes (step ``write tables``).

    Attributes
    ----------
    dirs
        ``{subfolder: path}``.
    written
        Every file written and kept, in order.
    n_tables
        Dense tables written, kept or for the sheet (not the sheet's links to kept ones).
    sheets
        ``{scene: {tile label: scores}}`` of the comparison sheets (:func:`write_figures`).
    """

    def __init__(self, out_dir: str, scratch: str | None, keep_tables: bool, clock: StepClock):
        self.out_dir, self.scratch, self.keep_tables, self.clock = out_dir, scratch, keep_tables, clock
        kept = ("materials", "reconstructed", "decoded") if keep_tables else ()
        self.dirs = {d: os.path.join(out_dir, d) for d in ("samples", "embeddings", *kept)}
        for d in self.dirs.values():
            os.makedirs(d, exist_ok=True)
        self.written: list[str] = []
        self.n_tables = 0
        self.sheets: dict = {}
        self.materials: dict = {}  # {name: table} of the materials themselves (view.html)

    def table(self, folder: str, stem: str, table, tile: str | None = None) -> str | None:
        """Write ``OUT/folder/stem.binary`` when tables are kept, and the sheet's input
        ``scratch/TILE.binary`` (``tile``: its label on the sheet) when it renders one;
        returns the latter, else ``None``. ``table``: ``(90, 90, 180, 3)``, 1/sr."""
        from brdfkit.io.merl import write_merl

        if folder == "materials":
            self.materials[stem] = table
        kept_path = None
        if self.keep_tables:
            kept_path = os.path.join(self.dirs[folder], stem + ".binary")
            with self.clock("write tables"):
                write_merl(kept_path, table)
            self.written.append(kept_path)
            self.n_tables += 1
        if tile is None or self.scratch is None:
            return None
        path = os.path.join(self.scratch, tile + ".binary")
        with self.clock("write tables"):
            if kept_path is None:
                write_merl(path, table)
                self.n_tables += 1
            else:  # the kept file, without a second 35 MB write where hard links work
                try:
                    os.link(kept_path, path)
                except OSError:
                    shutil.copyfile(kept_path, path)
        return path

    def keep(self, folder: str, name: str) -> str:
        """``OUT/folder/name``, recorded in :attr:`written` (before it is written: a failed
        write ends the demo)."""
        self.written.append(os.path.join(self.dirs[folder], name))
        return self.written[-1]


SHEET_SCENES = ("reference", "backlight")
"""The scenes the comparison sheets render in: the reference, and the backlit rim where
compressions fail first (the hypernetwork's latent loses 5 dB there; ``docs/notes/compression.md``)."""


def write_view(files: DemoFiles, err, clock: StepClock, model: str) -> str:
    """``OUT/view.html`` (:mod:`brdfkit.view`): the materials live in a browser, the first
    one, its embedding by ``model`` decoded by the page's shader from its numbers, then the
    others; returns its path."""
    from brdfkit.view.inputs import PageInput, read_inputs
    from brdfkit.view.page import write_inputs

    names = list(files.materials)
    path = os.path.join(files.out_dir, "view.html")
    with clock("view"):
        inputs = [PageInput(names[0], names[0], "table", table=files.materials[names[0]]),
                  *read_inputs([os.path.join(files.dirs["embeddings"], f"{names[0]}-{model}.emb")], live=True),
                  *(PageInput(n, n, "table", table=files.materials[n]) for n in names[1:])]
        size = write_inputs(inputs, path)["bytes"]
    err.print(f"the page of the materials, to open in a browser: {path} ({size / 1e6:.1f} MB)")
    files.written.append(path)
    return path


def write_figures(files: DemoFiles, err, clock: StepClock, name: str, shown: dict, inputs: dict,
                  tiles: dict, resolution: int, compressions=(), live: str | None = None,
                  renders: dict | None = None) -> tuple[str, str | None]:
    """The plot of ``shown`` (``{label: (90, 90, 180, 3) table}``, the material first;
    :func:`brdfkit.figures.brdf_plot.plot_brdfs`) and, when ``files`` has a scratch folder,
    the comparison sheets (:func:`brdfkit.figures.comparison_sheet.comparison_sheet`, one in
    each of :data:`SHEET_SCENES`: ``sheet-NAME.png``, ``sheet-NAME-backlight.png``) of the
    sheet's ``inputs`` (``{result key: path}``) in the order of ``tiles`` (``{result key:
    label}``, the reference first), rendered at ``resolution`` pixels, of the material
    ``name``; the backlit sheet shows the keys of ``compressions`` only; progress on the
    console ``err``. Each sheet's scores go to ``files.sheets`` (:func:`sheet_scores`).
    With the sheets and ``live`` (a model), also ``view.html`` (:func:`write_view`).
    ``renders``: ``{result key: reference-scene render at resolution}`` already made
    (:func:`render_scores`'s), which the reference sheet then shows instead of rendering
    them again.

    Returns
    -------
    tuple
        ``(plot path, reference-scene sheet path)``, the latter ``None`` without a sheet.
    """
    from brdfkit.figures.brdf_plot import plot_brdfs

    plot_path = os.path.join(files.out_dir, f"plot-{name}.png")
    err.print(f"plotting {name} against its reconstructions: {plot_path}")
    with clock("plot"):
        plot_brdfs(shown, plot_path)
    files.written.append(plot_path)
    if files.scratch is None:
        return plot_path, None
    from brdfkit.figures.comparison_sheet import comparison_sheet

    from brdfkit.evaluation.comparison import FileLoader

    sheet_path = os.path.join(files.out_dir, f"sheet-{name}.png")
    preds = [inputs[k] for k in tiles if k != "reference"]
    loader = FileLoader(None, resolution, True, keep=len(tiles))  # one reading of the tables for both sheets
    for key, image in (renders or {}).items():
        loader.remember(inputs[key], image)
    for scene in SHEET_SCENES:
        path = sheet_path if scene == "reference" else os.path.join(files.out_dir, f"sheet-{name}-{scene}.png")
        # the second scene shows the compressions (the sparse reconstructions are on the first)
        shown = preds if scene == "reference" else [inputs[k] for k in tiles if k in compressions]
        err.print(f"rendering {name} and {len(shown)} reconstructions in the {scene} scene ({resolution} px): {path}")
        with clock("sheet"):
            rows = comparison_sheet(inputs["reference"], shown, path, resolution=resolution, scene=scene,
                                    loader=loader)
            files.sheets[scene] = sheet_scores(loader, inputs["reference"], shown, rows, scene)
        files.written.append(path)
    if live is not None:
        write_view(files, err, clock, live)
    return plot_path, sheet_path


def sheet_scores(loader, ref: str, preds: list, rows: dict, scene: str) -> dict:
    """The scores a comparison sheet prints under its tiles: ``rows`` (its ``{label:
    scores}``, :func:`brdfkit.figures.comparison_sheet.comparison_sheet`), each with
    ``delta_e_max``, the largest per-pixel Delta E 2000 of its error image (the sheet's
    ``max``), from the renders ``loader`` keeps."""
    from brdfkit.evaluation.metrics import delta_e_2000_map

    ref_img, *images = loader.renders([ref, *preds], None, scene)  # cached: no render
    return {label: {**{k: (None if v is None else float(v)) for k, v in scores.items()},
                    "delta_e_max": float(delta_e_2000_map(img, ref_img).max())}
            for (label, scores), img in zip(rows.items(), images)}


def render_scores(ref, tables: list, resolution: int) -> tuple[list, list]:
    """``([(PSNR dB, Delta E 2000)], renders)``: the scores of each of ``tables`` against
    the table ``ref`` (``(90, 90, 180, 3)``, 1/sr), all rendered in the reference scene at
    ``resolution`` pixels in one quadrature pass (the demo's tables rank reconstructions
    by renders), and those renders, ``ref``'s first."""
    import dataclasses

    from brdfkit.evaluation.metrics import delta_e_2000, psnr
    from brdfkit.render.quadrature import render_many
    from brdfkit.render.renderable import TableBRDF
    from brdfkit.render.scene import REFERENCE

    scene = dataclasses.replace(REFERENCE, resolution=int(resolution))
    images = [img for img, _ in render_many([TableBRDF(t) for t in [ref, *tables]], scene)]
    return [(min(psnr(img, images[0]), 100.0), delta_e_2000(img, images[0])) for img in images[1:]], images


def step_times(clock: StepClock, methods, comps, n_mat: int, n_samples: int, files: DemoFiles, refine_steps: int,
               renders: int, resolution: int) -> list:
    """``[(step, seconds)]`` of the real-materials demo's steps from ``clock``, the whole
    demo not yet: ``methods`` its sparse ``[(label, method, model)]``, ``comps`` its
    compressions ``[(model, kind, label, short)]``, ``n_mat`` materials of ``n_samples``
    sample counts each; ``renders``: the sheet's tiles (counted only with a sheet)."""
    encode_step = f"encode + refine ({refine_steps} steps)" if refine_steps > 0 else "encode (encoder pass only)"
    times = [("load the built-in models", clock.total("load models")),
             (f"decode {n_mat} NBRDF network(s) to MERL tables", clock.total("decode NBRDF tables"))]
    for label, _, _ in methods:
        times.append((f"sparse reconstruction, {label} (mean of {n_mat * n_samples})", clock.mean(f"sparse {label}")))
    for m, _, label, _ in comps:
        times.append((f"{encode_step}, {label} (mean)", clock.mean(f"encode {m}")))
        times.append((f"decode, {label} (mean)", clock.mean(f"decode {m}")))
    if n_mat > 1:
        times.append(("interpolate two embeddings + decode", clock.total("interpolate")))
    times.append((f"score the results (brdf_log_rmse, {len(clock.spent.get('score', ()))})",
                  clock.total("score")))
    if "render scores" in clock.spent:
        times.append((f"render and score the results ({resolution} px)", clock.total("render scores")))
    where = "" if files.keep_tables else " the sheet renders, to a temporary folder"
    times.append((f"write the MERL tables{where} ({files.n_tables})", clock.total("write tables")))
    times.append(("plot", clock.total("plot")))
    if files.scratch is not None:
        times.append((f"comparison sheets, reference and backlight ({2 * renders - 2} renders, {resolution} px)",
                      clock.total("sheet")))
        times.append(("the page of the materials (view.html)", clock.total("view")))
    return times


def parts_used(sparse_model: str, sparse_parts, decoders: dict) -> dict:
    """``{built-in: {part: digest}}``: the parts of the built-ins that made the demo's
    figures, each by the digest its manifest records (what ``tests/test_gallery.py``
    compares with the shipped manifest, so that a part replaced after the gallery was
    drawn is seen): ``sparse_parts`` of ``sparse_model`` (its sparse methods' parts), and
    of each built-in in ``decoders`` (``{built-in: Decoder}``, the compressions'), the
    parts whose digests its decoder names (its own, and the basis a residual names)."""
    from brdfkit.models.builtin import installed_bundles

    bundles = {b.name: b for b in installed_bundles()}
    named = {sparse_model: {bundles[sparse_model].part(part).digest for part in sparse_parts}}
    for m, dec in decoders.items():
        named.setdefault(m, set()).update({dec.digest, getattr(dec.obj, "basis_digest", None)})
    return {m: {part: p.digest for part, p in bundles[m].parts.items() if p.digest in digests}
            for m, digests in named.items()}


def write_errors(out_dir, made: dict, columns, rows, scored, sheets=None) -> str:
    """Write ``OUT/errors.json`` (atomically): the BRDF log RMSE of each material and
    column (``rows``: ``[(material, values)]``), the renders' PSNR and Delta E 2000
    (``scored``, when rendered), the comparison sheets' scores (``sheets``: ``{scene:
    {tile label: {"psnr", "delta_e", "ssim", "brdf_log_rmse", "delta_e_max"}}}``, when
    drawn), and ``made``, what made them; returns its path. The gallery quotes its figures
    from this file (``docs/images/demo-errors.json``, ``tests/test_gallery.py``)."""
    import json
    import os

    from brdfkit.atomic import atomic_open

    path = os.path.join(out_dir, "errors.json")
    doc = {"format": "brdfkit-demo-errors", "metric": "brdf_log_rmse", **made, "columns": columns,
           "errors": {n: dict(zip(columns, map(float, row))) for n, row in rows}}
    if scored:
        doc["psnr"] = {n: {c: float(v[0]) for c, v in zip(columns, row)} for n, row in scored}
        doc["delta_e"] = {n: {c: float(v[1]) for c, v in zip(columns, row)} for n, row in scored}
    if sheets:
        doc["sheets"] = sheets
    with atomic_open(path, "w", encoding="utf-8") as f:
        json.dump(doc, f, indent=1)
    return path



GALLERY = {"sheet-{name}.png": "demo-sheet.png", "sheet-{name}-backlight.png": "demo-sheet-backlight.png",
           "plot-{name}.png": "demo-plot.png", "errors.json": "demo-errors.json"}
"""What ``brdfkit demo --gallery DIR`` copies (``{file in OUT: name in DIR}``, ``{name}``
the sheets' material): the pictures and figures ``docs/gallery.md`` shows from
``docs/images``."""


def check_gallery(folder, render: bool) -> None:
    """Refuse ``--gallery`` before the demo runs: a folder that does not exist, or a run
    that draws no sheets (``--no-render``)."""
    from brdfkit.errors import InputError

    if folder is None:
        return
    if not os.path.isdir(folder):
        raise InputError(f"--gallery {folder}: no such folder")
    if not render:
        raise InputError(f"--gallery {folder}: the gallery shows the sheets, which --no-render does not draw")


def copy_to_gallery(out_dir: str, name: str, folder: str) -> list[str]:
    """Copy the demo's sheets and plot of the material ``name`` and its ``errors.json``
    from ``out_dir`` into ``folder`` under the names of :data:`GALLERY`, each atomically;
    returns the paths written."""
    from brdfkit.atomic import atomic_path

    done = []
    for src, dst in GALLERY.items():
        target = os.path.join(folder, dst)
        with atomic_path(target) as tmp:
            shutil.copyfile(os.path.join(out_dir, src.format(name=name)), tmp)
        done.append(target)
    return done
