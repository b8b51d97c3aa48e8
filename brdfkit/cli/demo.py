"""``brdfkit demo``: the whole job on built-in synthetic data, no download
(:func:`brdfkit.demo.run_demo`); prints its errors, times and files."""

from __future__ import annotations

import os

import click

from .common import parse_option


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
              help="Rendered PSNR of one reconstruction too.")
@click.option("-O", "--option", "options", multiple=True, metavar="KEY=VALUE",
              help="Advanced training option (see docs/training.md).")
def command(out_dir, minutes, steps, n_materials, holdout, seed, device, do_render, options):
    """Train and try a hypernetwork BRDF model on built-in synthetic materials.

    Needs no download and no data: writes a synthetic library into OUT, holds some
    materials out, trains a small model (about 3 minutes), reconstructs the held-out
    materials from 40 and 400 samples, compresses them, blends two of them, and prints
    the errors and times. Takes about 5 minutes on 2 CPU cores.
    """
    from rich.console import Console
    from rich.table import Table

    from ..demo import RENDER_RESOLUTION, SAMPLE_COUNTS, run_demo

    res = run_demo(out_dir, minutes=minutes, steps=steps, n_materials=n_materials, holdout=holdout, seed=seed,
                   device=device, render=do_render, options=dict(parse_option(o) for o in options))
    report = Console()
    tab = Table(title=f"Held-out materials: BRDF log RMSE (lower is better), latent {res.latent_dim}")
    tab.add_column("material")
    for c in res.columns:
        tab.add_column(c, justify="right")
    for name, row in res.errors:
        tab.add_row(name, *(f"{v:.3f}" for v in row))
    means = [sum(r[k] for _, r in res.errors) / len(res.errors) for k in range(len(res.columns))]
    tab.add_row("[bold]mean[/]", *(f"[bold]{v:.3f}[/]" for v in means))
    report.print(tab)
    report.print("median reference: the training materials' per-cell median, used as the prediction "
                 "(what the model must beat); brdf_log_rmse as in brdfkit.metrics.")
    if res.psnr:
        pt = Table(title="Rendered PSNR",
                   caption=f"reference scene at {RENDER_RESOLUTION} px, sphere pixels; the "
                           f"{SAMPLE_COUNTS[-1]}-sample reconstruction against the material")
        pt.add_column("material")
        pt.add_column("PSNR (dB)", justify="right")
        for name, v in res.psnr:
            pt.add_row(name, f"{v:.2f}")
        report.print(pt)
        report.print(f"Renders of both (PNG to look at, EXR linear): {os.path.join(res.out_dir, 'renders')}",
                     soft_wrap=True)
    tt = Table(title="Times")
    tt.add_column("step")
    tt.add_column("seconds", justify="right")
    for what, sec in res.times[:-1]:
        tt.add_row(what, f"{sec:.2f}")
    tt.add_row(f"[bold]{res.times[-1][0]}[/]", f"[bold]{res.times[-1][1]:.1f}[/]")
    report.print(tt)

    report.print(f"Files in {res.out_dir}:")
    for p in res.files:
        report.print(f"  {os.path.relpath(p, res.out_dir)}  ({_fmt_bytes(os.path.getsize(p))})")
    report.print(f"  materials/  ({len(res.materials)} synthetic MERL tables)")
    mat = os.path.join(res.out_dir, "materials", res.held[0] + ".binary")
    report.print(f"Next: brdfkit sample {os.path.relpath(mat)} -n 100 -o s.csv && "
                 f"brdfkit sparse s.csv -m {os.path.relpath(res.model_path)} -o r.binary")
