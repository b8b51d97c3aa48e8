"""``brdfkit demo``: the whole job on built-in synthetic data, no download.

Writes a synthetic material library (:mod:`brdfkit.synthetic`, stiff cases included),
holds a few materials out, trains a small budget of the hypernetwork
(:func:`brdfkit.training.fit`), then on the held-out materials: sparse reconstruction from
40 and 400 samples (:func:`brdfkit.api.sparse`), compression (encode the full table, decode
it), and an interpolation of two embeddings; prints the errors
(:func:`brdfkit.metrics.brdf_log_rmse`, and rendered PSNR when :mod:`brdfkit.render`
offers its documented ``render``) and the times, and lists the files written.
"""

from __future__ import annotations

import json
import os
import time

import click

from ..console import console

SAMPLE_COUNTS = (40, 400)
LIBRARY_MANIFEST = "library.json"


def choose_holdout(names: list[str], k: int) -> list[str]:
    """``k`` held-out names spread evenly over the random (non-stiff) materials, so the
    stiff cases (mirror, black, white, grazing) stay in training; from all names if there
    are too few random ones."""
    pool = [n for n in names if not n.startswith("stiff-")]
    if len(pool) < k:
        pool = list(names)
    return [pool[int((i + 0.5) * len(pool) / k)] for i in range(k)]


def write_demo_library(folder: str, n: int, seed: int, out) -> list[str]:
    """The synthetic library in ``folder``, reusing the tables of an earlier demo run made
    with the same ``n`` and ``seed`` (recorded in ``library.json``)."""
    from ..atomic import atomic_open
    from ..merl import is_merl_file, write_merl
    from ..synthetic import library, table

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
        from ..console import ProgressBar

        with ProgressBar("synthetic materials", total=len(todo), count=True, out=out) as bar:
            for m, p in todo:
                write_merl(p, table(m))
                bar.update(advance=1)
        with atomic_open(manifest, "w") as f:
            json.dump(want, f)
    return paths


RENDER_RESOLUTION = 128


def render_psnr(resolution: int = RENDER_RESOLUTION):
    """A function ``(pred_table, ref_table) -> PSNR dB`` over the sphere's pixels, through
    the documented ``brdfkit.render.quadrature.render`` (reference scene at ``resolution``
    pixels), or ``None`` when that renderer is not there."""
    import dataclasses
    import importlib
    import importlib.util

    try:
        if importlib.util.find_spec("brdfkit.render.quadrature") is None:
            return None
        quadrature = importlib.import_module("brdfkit.render.quadrature")
        brdf = importlib.import_module("brdfkit.render.brdf")
        scene_mod = importlib.import_module("brdfkit.render.scene")
    except ImportError:
        return None
    render = getattr(quadrature, "render", None)
    table_brdf = getattr(brdf, "TableBRDF", None)
    reference = getattr(scene_mod, "REFERENCE", None)
    if render is None or table_brdf is None or reference is None or not render.__doc__:
        return None
    from ..metrics import psnr

    scene = dataclasses.replace(reference, resolution=resolution)

    def score(pred, ref):
        img, mask = render(table_brdf(pred, "reconstruction"), scene)
        ref_img, _ = render(table_brdf(ref, "material"), scene)
        return psnr(img, ref_img, mask=mask)

    return score


def _fmt_bytes(n: int) -> str:
    return f"{n / 1e6:.1f} MB" if n >= 1e5 else f"{n / 1e3:.1f} kB"


@click.command("demo")
@click.option("--out", "out_dir", type=click.Path(file_okay=False), default="brdfkit-demo",
              show_default=True, help="Folder for the materials, model, embeddings and tables.")
@click.option("--minutes", type=float, default=3.0, show_default=True,
              help="Training budget (wall clock, reading the data included).")
@click.option("--steps", type=click.IntRange(min=1), default=None,
              help="Also stop training after this many steps.")
@click.option("--materials", "n_materials", type=click.IntRange(min=3), default=20, show_default=True,
              help="Size of the synthetic library (the first 4 are the stiff cases).")
@click.option("--holdout", type=click.IntRange(min=1), default=4, show_default=True,
              help="Materials held out of training and reconstructed.")
@click.option("--seed", type=int, default=0, show_default=True, help="Library, training and sampling seed.")
@click.option("--device", default="auto", show_default=True, help="auto, cpu or cuda.")
@click.option("--render/--no-render", "do_render", default=True, show_default=True,
              help="Rendered PSNR too, when brdfkit.render is available.")
@click.option("-O", "--option", "options", multiple=True, metavar="KEY=VALUE",
              help="Advanced training option (see docs/training.md).")
def command(out_dir, minutes, steps, n_materials, holdout, seed, device, do_render, options):
    """Train and try a hypernetwork BRDF model on built-in synthetic materials.

    Needs no download and no data: writes a synthetic library into OUT, holds some
    materials out, trains a small model (about 3 minutes), reconstructs the held-out
    materials from 40 and 400 samples, compresses them, blends two of them, and prints
    the errors and times. Takes about 5 minutes on 2 CPU cores.
    """
    import math

    import numpy as np
    from rich.console import Console
    from rich.table import Table

    from .. import api
    from ..embedding import write_embedding
    from ..errors import InputError
    from ..merl import read_merl, write_merl
    from ..metrics import brdf_log_rmse
    from ..samples import draw_samples
    from ..training import fit
    from .fit import _parse_option

    if not (minutes > 0 and math.isfinite(minutes)):
        raise InputError(f"--minutes must be a positive number, got {minutes}")
    if holdout >= n_materials:
        raise InputError(f"--holdout {holdout} leaves nothing to train on among {n_materials} materials")
    err = console()
    report = Console()
    t_all = time.monotonic()
    out_dir = os.path.abspath(out_dir)
    mat_dir, emb_dir, dec_dir = (os.path.join(out_dir, d) for d in ("materials", "embeddings", "decoded"))
    for d in (out_dir, emb_dir, dec_dir):
        os.makedirs(d, exist_ok=True)
    err.print(f"[bold]brdfkit demo[/]: writing everything into {out_dir}")
    import torch

    # brdfkit.cli.main already sized the pool to the idle cores (brdfkit.threads).
    err.print(f"using {torch.get_num_threads()} torch thread(s) (set OMP_NUM_THREADS to choose)")
    times, written = [], []

    t = time.monotonic()
    paths = write_demo_library(mat_dir, n_materials, seed, err)
    names = [os.path.basename(p)[:-len(".binary")] for p in paths]
    held = choose_holdout(names, holdout)
    times.append((f"synthetic library ({n_materials} materials)", time.monotonic() - t))
    err.print(f"{n_materials} synthetic materials in {mat_dir}; held out of training: {', '.join(held)}")

    model_path = os.path.join(out_dir, "model.safetensors")
    advanced = dict(_parse_option(o) for o in options)
    t = time.monotonic()
    fit(paths, model_path, steps=steps, minutes=minutes, seed=seed, device=device,
        exclude=held, progress=True, **advanced)
    model = api.load_model(model_path, None if device == "auto" else device)
    times.append((f"training ({model.meta['steps']} steps)", time.monotonic() - t))

    scorer = render_psnr() if do_render else None
    rows, psnr_rows, full_emb = [], [], {}
    t_sparse = {n: [] for n in SAMPLE_COUNTS}
    t_encode, t_decode = [], []
    ref_table = model.rho_ref.astype(np.float64)
    for i, name in enumerate(held):
        err.print(f"reconstructing {name}")
        table = read_merl(os.path.join(mat_dir, name + ".binary"))
        row = [brdf_log_rmse(ref_table, table)]
        for n in SAMPLE_COUNTS:
            samples = draw_samples(table, n, seed=seed + 1000 * i + n, source=f"{name}-{n}")
            t = time.monotonic()
            pred, emb = api.sparse(model, samples, source=f"{name} ({n} samples)")
            t_sparse[n].append(time.monotonic() - t)
            written.append(os.path.join(emb_dir, f"{name}-{n}samples.emb"))
            write_embedding(written[-1], emb)
            row.append(brdf_log_rmse(pred, table))
            if scorer is not None and n == SAMPLE_COUNTS[-1] and i == 0:
                # One material: a render takes tens of seconds on a CPU core.
                err.print(f"rendering {name} and its {n}-sample reconstruction ({RENDER_RESOLUTION} px)")
                t = time.monotonic()
                psnr_rows.append((name, scorer(pred, table)))
                times.append((f"render material + reconstruction ({RENDER_RESOLUTION} px)", time.monotonic() - t))
        t = time.monotonic()
        emb = api.encode(model, table, source=name)
        t_encode.append(time.monotonic() - t)
        t = time.monotonic()
        decoded = api.decode(model, emb)
        t_decode.append(time.monotonic() - t)
        row.append(brdf_log_rmse(decoded, table))
        written += [os.path.join(emb_dir, f"{name}.emb"), os.path.join(dec_dir, f"{name}.binary")]
        write_embedding(written[-2], emb)
        write_merl(written[-1], decoded)
        full_emb[name] = emb
        rows.append((name, row))

    a = held[0]
    b = held[1] if len(held) > 1 else next(n for n in names if n not in held)
    if b not in full_emb:
        full_emb[b] = api.encode(model, read_merl(os.path.join(mat_dir, b + ".binary")), source=b)
    t = time.monotonic()
    mix = api.interpolate(full_emb[a], full_emb[b], 0.5)
    mixed = api.decode(model, mix)
    t_interp = time.monotonic() - t
    mix_name = f"{a}+{b}-t0.5"
    written += [os.path.join(emb_dir, mix_name + ".emb"), os.path.join(dec_dir, mix_name + ".binary")]
    write_embedding(written[-2], mix)
    write_merl(written[-1], mixed)

    for n in SAMPLE_COUNTS:
        times.append((f"sparse reconstruction, {n} samples (mean per material)", float(np.mean(t_sparse[n]))))
    times.append(("encode a full table (mean)", float(np.mean(t_encode))))
    times.append(("decode to a full table (mean)", float(np.mean(t_decode))))
    times.append(("interpolate two embeddings + decode", t_interp))

    cols = ["median reference", *(f"{n} samples" for n in SAMPLE_COUNTS), "full table (compressed)"]
    tab = Table(title=f"Held-out materials: BRDF log RMSE (lower is better), latent {model.cfg.latent_dim}")
    tab.add_column("material")
    for c in cols:
        tab.add_column(c, justify="right")
    for name, row in rows:
        tab.add_row(name, *(f"{v:.3f}" for v in row))
    tab.add_row("[bold]mean[/]", *(f"[bold]{np.mean([r[k] for _, r in rows]):.3f}[/]" for k in range(len(cols))))
    report.print(tab)
    report.print("median reference: the training materials' per-cell median, used as the prediction "
                 "(what the model must beat); brdf_log_rmse as in brdfkit.metrics.")
    if psnr_rows:
        pt = Table(title="Rendered PSNR",
                   caption=f"reference scene at {RENDER_RESOLUTION} px, sphere pixels; the "
                           f"{SAMPLE_COUNTS[-1]}-sample reconstruction against the material")
        pt.add_column("material")
        pt.add_column("PSNR (dB)", justify="right")
        for name, v in psnr_rows:
            pt.add_row(name, f"{v:.2f}")
        report.print(pt)
    elif do_render:
        report.print("rendered PSNR: skipped (brdfkit.render.quadrature.render is not available)")
    tt = Table(title="Times")
    tt.add_column("step")
    tt.add_column("seconds", justify="right")
    for what, s in times:
        tt.add_row(what, f"{s:.2f}")
    tt.add_row("[bold]whole demo[/]", f"[bold]{time.monotonic() - t_all:.1f}[/]")
    report.print(tt)

    report.print(f"Files in {out_dir}:")
    for p in [model_path, model_path + ".ckpt"] + sorted(written):
        report.print(f"  {os.path.relpath(p, out_dir)}  ({_fmt_bytes(os.path.getsize(p))})")
    report.print(f"  materials/  ({len(paths)} synthetic MERL tables)")
    report.print(f"Next: brdfkit sample {os.path.relpath(os.path.join(mat_dir, held[0] + '.binary'))} "
                 f"-n 100 -o s.csv && brdfkit sparse s.csv -m {os.path.relpath(model_path)} -o r.binary")
