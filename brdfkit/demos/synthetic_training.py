"""The training demo: the whole job on built-in synthetic data, no download
(``brdfkit demo --train``; ``brdfkit demo`` alone is :mod:`brdfkit.demos.real_materials`).

Writes a synthetic material library (:mod:`brdfkit.materials.synthetic`, stiff cases included),
holds a few materials out, trains a small budget of the hypernetwork
(:func:`brdfkit.hypernet.training.loop.fit`), then on the held-out materials: sparse reconstruction from
40 and 400 samples (:func:`brdfkit.api.sparse`), compression (encode the full table, decode
it), and an interpolation of two embeddings. :func:`run_demo` returns the errors
(:func:`brdfkit.evaluation.metrics.brdf_log_rmse`, and the rendered PSNR of one reconstruction), the
times and the files written; ``brdfkit demo`` prints them.

Dense tables are 35 MB each (the library alone 700 MB), so unless ``keep_tables`` they
live in a temporary folder inside the output folder (:func:`scratch_folder`), removed at
the end, on error and on Ctrl-C too.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import math
import os
import tempfile
import time

from brdfkit.errors import InputError

__all__ = ["SAMPLE_COUNTS", "RENDER_RESOLUTION", "DemoResult", "choose_holdout", "write_demo_library",
           "render_psnr", "scratch_folder", "run_demo"]

SAMPLE_COUNTS = (40, 400)
RENDER_RESOLUTION = 128
LIBRARY_MANIFEST = "library.json"


def scratch_folder(out_dir: str, keep_tables: bool):
    """Context manager: ``None`` with ``keep_tables``, else a temporary folder inside
    ``out_dir`` (``.brdfkit-tmp-demo-*``: the same file system as the outputs, not a
    possibly small ``/tmp``) for the dense tables a demo needs on disk but does not keep,
    removed on leaving, by an exception or Ctrl-C too (not by SIGKILL)."""
    if keep_tables:
        return contextlib.nullcontext(None)
    return tempfile.TemporaryDirectory(prefix=".brdfkit-tmp-demo-", dir=out_dir)


def choose_holdout(names: list[str], k: int) -> list[str]:
    """``k`` held-out names spread evenly over the random (non-stiff) materials, so the
    stiff cases (mirror, black, white, grazing) stay in training; from all names if there
    are too few random ones."""
    pool = [n for n in names if not n.startswith("stiff-")]
    if len(pool) < k:
        pool = list(names)
    return [pool[int((i + 0.5) * len(pool) / k)] for i in range(k)]


def write_demo_library(folder: str, n: int, seed: int, out=None) -> list[str]:
    """The synthetic library in ``folder``, reusing the tables of an earlier demo run made
    with the same ``n`` and ``seed`` (recorded in ``library.json``); ``out``: the Rich
    console of the progress bar (default stderr)."""
    from brdfkit.atomic import atomic_open
    from brdfkit.console import ProgressBar
    from brdfkit.io.merl import is_merl_file, write_merl
    from brdfkit.materials.synthetic import library, table

    os.makedirs(folder, exist_ok=True)
    manifest = os.path.join(folder, LIBRARY_MANIFEST)
    want = {"count": n, "seed": seed}
    try:
        with open(manifest, encoding="utf-8") as f:
            same = json.load(f) == want
    except (OSError, ValueError):
        same = False
    mats = library(n, seed)
    paths = [os.path.join(folder, m.name + ".binary") for m in mats]
    todo = [(m, p) for m, p in zip(mats, paths) if not (same and is_merl_file(p))]
    if todo:
        if os.path.exists(manifest):
            os.unlink(manifest)  # stale until every table of this library is written
        with ProgressBar("synthetic materials", total=len(todo), count=True, out=out) as bar:
            for m, p in todo:
                write_merl(p, table(m))
                bar.update(advance=1)
        with atomic_open(manifest, "w") as f:
            json.dump(want, f)
    return paths


def render_psnr(resolution: int = RENDER_RESOLUTION):
    """A function ``(pred_table, ref_table, save=None) -> PSNR dB`` over the sphere's pixels
    of the reference scene rendered at ``resolution`` pixels by the quadrature renderer.

    ``save``, a pair of path prefixes ``(prediction, reference)``, also writes each render
    as ``PREFIX.exr`` (linear) and ``PREFIX.png`` (displayed as in ``docs/render.md``)."""
    from brdfkit.evaluation.metrics import psnr
    from brdfkit.render.renderable import TableBRDF
    from brdfkit.render.image import write_exr, write_png
    from brdfkit.render.quadrature import render
    from brdfkit.render.scene import REFERENCE

    scene = dataclasses.replace(REFERENCE, resolution=resolution)

    def score(pred, ref, save=None):
        img, mask = render(TableBRDF(pred, "reconstruction"), scene)
        ref_img, _ = render(TableBRDF(ref, "material"), scene)
        for image, prefix in zip((img, ref_img), save or ()):
            write_exr(prefix + ".exr", image)
            write_png(prefix + ".png", image)
        return psnr(img, ref_img, mask=mask)

    return score


@dataclasses.dataclass
class DemoResult:
    """What :func:`run_demo` measured and wrote.

    Attributes
    ----------
    out_dir, model_path
        The demo's folder and its model file.
    materials
        Paths of the synthetic library (in ``OUT/materials`` with ``keep_tables``, else
        in the temporary folder, removed by the time this is returned).
    held
        Names of the held-out materials.
    latent_dim
        The model's embedding size.
    errors
        ``[(material, [median reference, 40 samples, 400 samples, full table])]``: BRDF
        log RMSE of each prediction against the material.
    columns
        Names of those four columns.
    psnr
        ``[(material, PSNR dB)]`` of the rendered reconstruction (empty without rendering).
    times
        ``[(step, seconds)]``, the last the whole demo.
    files
        Every file written and kept besides the library (model, checkpoint, embeddings,
        renders; the decoded tables with ``keep_tables``).
    keep_tables
        Whether the dense tables were kept.
    """

    out_dir: str
    model_path: str
    materials: list
    held: list
    latent_dim: int
    errors: list
    columns: list
    psnr: list
    times: list
    files: list
    keep_tables: bool = True


def run_demo(out_dir: str = "brdfkit-demo", *, minutes: float = 3.0, steps: int | None = None,
             n_materials: int = 20, holdout: int = 4, seed: int = 0, device="auto", render: bool = True,
             options: dict | None = None, keep_tables: bool = False) -> DemoResult:
    """Run the demo (see the module doc), reporting progress on stderr.

    Parameters
    ----------
    out_dir
        Folder for the materials, model, embeddings and tables.
    minutes, steps
        Training budget (wall clock, reading the data included) and optional step limit.
    n_materials, holdout
        Size of the synthetic library and materials held out of training.
    seed
        Library, training and sampling seed.
    device
        ``auto``, ``cpu`` or ``cuda``.
    render
        Also the rendered PSNR of one reconstruction.
    options
        Advanced training options (:func:`brdfkit.hypernet.training.loop.fit`).
    keep_tables
        Keep the dense tables (the library in ``OUT/materials``, reused by a later run
        with the same size and seed, and the decoded tables in ``OUT/decoded``: 35 MB
        each); ``False``: the library lives in a temporary folder removed at the end and
        decoded tables stay in memory.
    """
    if not (minutes > 0 and math.isfinite(minutes)):
        raise InputError(f"--minutes must be a positive number, got {minutes}")
    if holdout >= n_materials:
        raise InputError(f"--holdout {holdout} leaves nothing to train on among {n_materials} materials")
    out_dir = os.path.abspath(out_dir)
    os.makedirs(out_dir, exist_ok=True)
    with scratch_folder(out_dir, keep_tables) as scratch:
        return _run(out_dir, scratch, minutes, steps, n_materials, holdout, seed, device, render, options)


def _run(out_dir, scratch, minutes, steps, n_materials, holdout, seed, device, render, options) -> DemoResult:
    """:func:`run_demo` in ``out_dir``, its dense tables in ``scratch`` (``None``: kept)."""
    import numpy as np
    import torch

    from brdfkit import api
    from brdfkit.console import console
    from brdfkit.hypernet.training.loop import fit

    err = console()
    t_all = time.monotonic()
    mat_dir = os.path.join(scratch or out_dir, "materials")
    emb_dir, dec_dir, ren_dir = (os.path.join(out_dir, d) for d in ("embeddings", "decoded", "renders"))
    dec_dir = dec_dir if scratch is None else None
    ren_dir = ren_dir if render else None
    for d in (emb_dir,) + ((dec_dir,) if dec_dir else ()) + ((ren_dir,) if ren_dir else ()):
        os.makedirs(d, exist_ok=True)
    err.print(f"[bold]brdfkit demo[/]: writing into {out_dir}"
              + ("" if scratch is None else " (the dense tables: in memory and a temporary folder there, removed "
                                            "at the end; --keep-tables keeps them)"))
    # brdfkit.cli.main already sized the pool to the idle cores (brdfkit.runtime).
    err.print(f"using {torch.get_num_threads()} torch thread(s) (set OMP_NUM_THREADS to choose)")
    times, written = [], []

    t = time.monotonic()
    paths = write_demo_library(mat_dir, n_materials, seed, err)
    names = [os.path.basename(p)[:-len(".binary")] for p in paths]
    held = choose_holdout(names, holdout)
    times.append((f"synthetic library ({n_materials} materials)", time.monotonic() - t))
    err.print(f"{n_materials} synthetic materials in {mat_dir}; held out of training: {', '.join(held)}")

    model_path = os.path.join(out_dir, "model.safetensors")
    t = time.monotonic()
    fit(paths, model_path, steps=steps, minutes=minutes, seed=seed, device=device,
        exclude=held, progress=True, **(options or {}))
    model = api.load_model(model_path, None if device == "auto" else device)
    times.append((f"training ({model.meta['steps']} steps)", time.monotonic() - t))

    rows, psnr_rows, full_emb, spent = _reconstruct_held_out(model, held, mat_dir, emb_dir, dec_dir, ren_dir, seed, err,
                                                     times, written)
    t_interp = _interpolate(model, held, names, full_emb, mat_dir, emb_dir, dec_dir, written)

    for n in SAMPLE_COUNTS:
        times.append((f"sparse reconstruction, {n} samples (mean per material)", float(np.mean(spent[n]))))
    times.append(("encode a full table (mean)", float(np.mean(spent["encode"]))))
    times.append(("decode to a full table (mean)", float(np.mean(spent["decode"]))))
    times.append(("interpolate two embeddings + decode", t_interp))
    times.append(("whole demo", time.monotonic() - t_all))
    columns = ["median reference", *(f"{n} samples" for n in SAMPLE_COUNTS), "full table (compressed)"]
    return DemoResult(out_dir, model_path, paths, held, model.cfg.latent_dim, rows, columns, psnr_rows, times,
                      [model_path, model_path + ".ckpt"] + sorted(written), scratch is None)


def _reconstruct_held_out(model, held, mat_dir, emb_dir, dec_dir, ren_dir, seed, err, times, written):
    """Reconstruct, compress and score each held-out material of ``mat_dir`` with ``model``.

    Writes the embeddings into ``emb_dir``, the decoded tables into ``dec_dir`` (``None``:
    not kept) and, for the first material, the renders of its reconstruction from the most
    samples into ``ren_dir`` (``None``: no render); appends the files to ``written`` and
    the render's time to ``times``.

    Returns
    -------
    tuple
        ``(rows, psnr_rows, full_emb, spent)``: the :class:`DemoResult` errors and PSNR,
        ``{material: embedding of its full table}``, and the seconds of each call,
        ``{N: [sparse], "encode": [...], "decode": [...]}``.
    """
    import numpy as np

    from brdfkit import api
    from brdfkit.io.embedding import write_embedding
    from brdfkit.io.merl import read_merl, write_merl
    from brdfkit.evaluation.metrics import brdf_log_rmse
    from brdfkit.acquisition.sampling import draw_samples

    scorer = render_psnr() if ren_dir is not None else None
    rows, psnr_rows, full_emb = [], [], {}
    spent = {**{n: [] for n in SAMPLE_COUNTS}, "encode": [], "decode": []}
    ref_table = model.rho_ref.astype(np.float64)
    for i, name in enumerate(held):
        err.print(f"reconstructing {name}")
        table = read_merl(os.path.join(mat_dir, name + ".binary"))
        row = [brdf_log_rmse(ref_table, table)]
        for n in SAMPLE_COUNTS:
            samples = draw_samples(table, n, seed=seed + 1000 * i + n, source=f"{name}-{n}")
            t = time.monotonic()
            pred, emb = api.sparse(samples, model, refine=False)  # the paper's one encoder pass
            emb.source = f"{name} ({n} samples)"
            spent[n].append(time.monotonic() - t)
            written.append(os.path.join(emb_dir, f"{name}-{n}samples.emb"))
            write_embedding(written[-1], emb)
            row.append(brdf_log_rmse(pred, table))
            if scorer is not None and n == SAMPLE_COUNTS[-1] and i == 0:
                # One material: a render takes tens of seconds on a CPU core.
                err.print(f"rendering {name} and its {n}-sample reconstruction ({RENDER_RESOLUTION} px)")
                t = time.monotonic()
                save = (os.path.join(ren_dir, f"{name}-{n}samples"), os.path.join(ren_dir, name))
                psnr_rows.append((name, scorer(pred, table, save=save)))
                written += [prefix + ext for prefix in save for ext in (".png", ".exr")]
                times.append((f"render material + reconstruction ({RENDER_RESOLUTION} px)", time.monotonic() - t))
        t = time.monotonic()
        emb = api.encode(table, model, source=name)
        spent["encode"].append(time.monotonic() - t)
        t = time.monotonic()
        decoded = api.decode(emb, model)
        spent["decode"].append(time.monotonic() - t)
        row.append(brdf_log_rmse(decoded, table))
        written.append(os.path.join(emb_dir, f"{name}.emb"))
        write_embedding(written[-1], emb)
        if dec_dir is not None:
            written.append(os.path.join(dec_dir, f"{name}.binary"))
            write_merl(written[-1], decoded)
        full_emb[name] = emb
        rows.append((name, row))
    return rows, psnr_rows, full_emb, spent


def _interpolate(model, held, names, full_emb, mat_dir, emb_dir, dec_dir, written) -> float:
    """Blend the embeddings of the first two held-out materials (or the first and a
    trained one) at ``t = 0.5`` and decode the blend, writing its embedding into
    ``emb_dir`` and its table into ``dec_dir`` (``None``: not kept); returns the seconds
    the blend and its decode took. ``full_emb``: ``{material: embedding}``, completed here."""
    from brdfkit import api
    from brdfkit.io.embedding import write_embedding
    from brdfkit.io.merl import read_merl, write_merl

    a = held[0]
    b = held[1] if len(held) > 1 else next(n for n in names if n not in held)
    if b not in full_emb:
        full_emb[b] = api.encode(read_merl(os.path.join(mat_dir, b + ".binary")), model, source=b)
    t = time.monotonic()
    mix = api.interpolate(full_emb[a], full_emb[b], 0.5)
    mixed = api.decode(mix, model)
    t_interp = time.monotonic() - t
    mix_name = f"{a}+{b}-t0.5"
    written.append(os.path.join(emb_dir, mix_name + ".emb"))
    write_embedding(written[-1], mix)
    if dec_dir is not None:
        written.append(os.path.join(dec_dir, mix_name + ".binary"))
        write_merl(written[-1], mixed)
    return t_interp
