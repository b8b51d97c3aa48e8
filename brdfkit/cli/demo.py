"""``brdfkit demo``: real MERL test materials through the built-in models
(:func:`brdfkit.demos.real_materials.run_real_demo`); ``--train``: train and try a small model on
built-in synthetic data (:func:`brdfkit.demos.synthetic_training.run_demo`). Prints the errors, times and
files."""

from __future__ import annotations

import os

import click

from brdfkit.demos.real_materials import SHEET_RESOLUTION
from brdfkit.cli.common import parse_option

# Options of one mode only (parameter name: flag): a training one selects --train.
_TRAIN_ONLY = {"minutes": "--minutes", "steps": "--steps", "n_materials": "--materials",
               "holdout": "--holdout", "options": "-O"}
_REAL_ONLY = {"resolution": "--resolution", "only": "--only", "gallery": "--gallery"}


def _fmt_bytes(n: int) -> str:
    return f"{n / 1e6:.1f} MB" if n >= 1e5 else f"{n / 1e3:.1f} kB"


def _mode(train: bool) -> bool:
    """Whether to run the training demo: ``--train``, or an option only it takes (so
    that command lines from before the real-material demo keep working); an option of
    the real-material demo with it is refused."""
    from click.core import ParameterSource

    from brdfkit.errors import InputError

    ctx = click.get_current_context()

    def given(names):
        return [flag for name, flag in names.items()
                if ctx.get_parameter_source(name) not in (ParameterSource.DEFAULT, None)]

    train = train or bool(given(_TRAIN_ONLY))
    if train and given(_REAL_ONLY):
        raise InputError(f"{', '.join(given(_REAL_ONLY))}: option(s) of the real-material demo, but "
                         f"{', '.join(given(_TRAIN_ONLY)) or '--train'} selects the training demo (--train)")
    return train


def _times_table(times):
    from rich.table import Table

    tt = Table(title="Times")
    tt.add_column("step")
    tt.add_column("seconds", justify="right")
    for what, sec in times[:-1]:
        tt.add_row(what, f"{sec:.2f}")
    tt.add_row(f"[bold]{times[-1][0]}[/]", f"[bold]{times[-1][1]:.1f}[/]")
    return tt


def _error_table(title, columns, errors, fmt=lambda v: f"{v:.3f}"):
    """Materials by columns, and the columns' means; ``fmt`` writes a value (a number, or
    a ``(PSNR, Delta E)`` pair)."""
    from rich.table import Table

    tab = Table(title=title)
    # Names whole (the number columns' headers wrap instead).
    tab.add_column("material", no_wrap=True, min_width=max(len(n) for n, _ in errors))
    for c in columns:
        tab.add_column(c, justify="right")
    for name, row in errors:
        tab.add_row(name, *(fmt(v) for v in row))
    means = [_mean([r[k] for _, r in errors]) for k in range(len(columns))]
    tab.add_row("[bold]mean[/]", *(f"[bold]{fmt(v)}[/]" for v in means))
    return tab


def _mean(values):
    if isinstance(values[0], tuple):
        return tuple(sum(v) / len(values) for v in zip(*values))
    return sum(values) / len(values)


@click.command("demo")
@click.option("--train", is_flag=True,
              help="The synthetic training demo instead: write a synthetic library, train a small model "
                   "for --minutes (3), try it; about 5 minutes in all.")
@click.option("--out", "out_dir", type=click.Path(file_okay=False), default="brdfkit-demo",
              show_default=True, help="Folder for everything the demo writes.")
@click.option("--seed", type=int, default=0, show_default=True, help="Sampling seed (--train: library and training too).")
@click.option("--device", default="auto", show_default=True, help="auto, cpu or cuda.")
@click.option("--render/--no-render", "do_render", default=True, show_default=True,
              help="Render one material: the comparison sheet (--train: the rendered PSNR).")
@click.option("--resolution", type=click.IntRange(min=8, max=1024), default=SHEET_RESOLUTION,
              show_default=True, help="Render size of the comparison sheet, pixels.")
@click.option("--keep-tables/--no-keep-tables", default=False, show_default=True,
              help="Also write the dense MERL tables (17 tables of 35 MB, 0.59 GB; --train: the 700 MB "
                   "library and the decoded tables); without it they stay in memory or in a temporary "
                   "folder in OUT that is removed at the end. One material's table alone: brdfkit material.")
@click.option("--only", default=None, metavar="NAME,...",
              help="The shipped materials to run, the first the sheets' and the plot's (brdfkit material "
                   "--list names all four) [default: blue-metallic-paint,teflon].")
@click.option("--gallery", "gallery", type=click.Path(file_okay=False), default=None, hidden=True, metavar="DIR",
              help="Also copy the sheets, the plot and errors.json into DIR under the gallery's names "
                   "(docs/images: docs/gallery.md).")
@click.option("--minutes", type=float, default=3.0, show_default=True,
              help="Implies --train: training budget (wall clock, reading the data included).")
@click.option("--steps", type=click.IntRange(min=1), default=None,
              help="Implies --train: also stop training after this many steps.")
@click.option("--materials", "n_materials", type=click.IntRange(min=3), default=20, show_default=True,
              help="Implies --train: size of the synthetic library (the first 4 are the stiff cases).")
@click.option("--holdout", type=click.IntRange(min=1), default=4, show_default=True,
              help="Implies --train: materials held out of training and reconstructed.")
@click.option("-O", "--option", "options", multiple=True, metavar="KEY=VALUE",
              help="Implies --train: advanced training option (see docs/training.md).")
def command(train, out_dir, seed, device, do_render, resolution, keep_tables, only, gallery, minutes, steps,
            n_materials, holdout, options):
    """Try brdfkit on real materials with the built-in models (no download).

    Two MERL materials the benchmark model never saw (shipped as their published NBRDF
    fits; --only: others) are reconstructed from 40 and 400 samples (learnt prior, and
    IPCA beside it), compressed by three built-ins (in-sample: trained on them, the
    paper's protocol; unseen: not) as `brdfkit encode` does (the 40-D ones' residual
    embeddings: 39 coefficients of the PCA basis they ship and their residual's
    correction; the 7-D one's latent), each refined on screen for at most 20 steps, and
    blended; prints the errors and times, and writes the samples, embeddings, errors,
    comparison sheets (reference scene, and the compressions under backlight; 128 px
    renders), a plot and a page of the materials (view.html) into OUT (--keep-tables: the
    dense tables too, 17 of 35 MB, 0.59 GB; one material's table alone: brdfkit material
    NAME). Under a minute on 2 CPU cores (46 s at load 2: the runs in docs/notes/demo.md). With
    --train: trains a small model on synthetic materials instead, for --minutes (3): about
    5 minutes in all (286 s: the training demo's run recorded there). See docs/demo.md.
    """
    if _mode(train):
        _train(out_dir, minutes, steps, n_materials, holdout, seed, device, do_render, options, keep_tables)
        return
    from rich.console import Console

    from brdfkit.demos.real_materials import COMPRESSION_SETS, INTERPOLATION_MODEL, SPARSE_MODEL, run_real_demo
    from brdfkit.demos.real_outputs import check_gallery, copy_to_gallery

    check_gallery(gallery, do_render)  # before the run
    res = run_real_demo(out_dir, only=[s.strip() for s in only.split(",") if s.strip()] if only else None,
                        seed=seed, device=device, render=do_render, resolution=resolution, keep_tables=keep_tables)
    report = Console()
    # Two tables: the compressions' full labels (kind, size, model) do not fit beside the
    # sparse columns in 80 characters, and would be cut.
    n = len(res.columns) - len(res.compressions)
    for what, cols in (("sparse", slice(0, n)), ("compressed", slice(n, None))):
        if res.renders:  # ranked by renders, what the field judges by
            report.print(_error_table(
                f"MERL test materials, {what}: PSNR dB / Delta E 2000 of {res.resolution} px reference-scene "
                f"renders (higher / lower is better)", res.columns[cols],
                [(m, row[cols]) for m, row in res.renders], fmt=lambda v: f"{v[0]:.1f} / {v[1]:.2f}"))
        else:
            report.print(_error_table(f"MERL test materials, {what}: BRDF log RMSE (lower is better; "
                                      f"--no-render: nothing rendered to rank by)",
                                      res.columns[cols], [(m, row[cols]) for m, row in res.errors]))
    kinds = {}
    for m, kind, _, _ in res.compressions:
        kinds.setdefault(kind, []).append(m)
    report.print(f"{res.sparse_method} N, ipca N: reconstructed from N samples by brdfkit sparse's default "
                 f"method on {SPARSE_MODEL} ({res.sparse_method}) and by IPCA on its PCA basis; {SPARSE_MODEL} "
                 f"never saw these materials. " + _compression_caption(res) + "; "
                 + "; ".join(f"{kind} ({', '.join(ms)}): {COMPRESSION_SETS.get(kind, kind)}"
                             for kind, ms in kinds.items())
                 + ". PSNR and Delta E as brdfkit metrics takes them (docs/render.md); errors.json also "
                   "holds brdf_log_rmse.")
    report.print(_times_table(res.times))
    if gallery is not None:
        copied = copy_to_gallery(res.out_dir, res.sheet_material, gallery)
        report.print(f"Copied into {gallery}: {', '.join(os.path.basename(p) for p in copied)}", soft_wrap=True)
    report.print(f"Files in {res.out_dir}:")
    folders = {}
    for p in res.files:
        rel = os.path.relpath(p, res.out_dir)
        if os.sep in rel:
            folders.setdefault(rel.split(os.sep)[0], []).append(p)
        else:
            report.print(f"  {rel}  ({_fmt_bytes(os.path.getsize(p))})")
    for folder, paths in folders.items():
        size = sum(os.path.getsize(p) for p in paths)
        report.print(f"  {folder}/  ({len(paths)} file{'s' * (len(paths) > 1)}, {_fmt_bytes(size)})")
    view = os.path.join(res.out_dir, "view.html")
    if view in res.files:
        report.print(f"Look: open {os.path.relpath(view)} in a browser (no network needed): the materials on the "
                     "reference scene's sphere; choose 'directional light' and drag on a sphere to turn the light "
                     "(docs/view.md).", soft_wrap=True)
    name = res.sheet_material
    samples = os.path.relpath(os.path.join(res.out_dir, "samples", f"{name}-40.csv"))
    if res.keep_tables:
        report.print(f"Next: brdfkit sparse {samples} -m {SPARSE_MODEL} -o r.binary && "
                     f"brdfkit compare {os.path.relpath(os.path.join(res.out_dir, 'materials', name + '.binary'))} "
                     f"r.binary --sheet r.png", soft_wrap=True)
        return
    from brdfkit.io.merl import MERL_FILE_SIZE

    n_tables = len(res.materials) * (len(res.columns) + 1) + (len(res.materials) > 1)  # + the blend
    report.print("The dense MERL tables (materials, reconstructions, compressions: 35 MB each) were not "
                 "kept; --keep-tables writes them into materials/, reconstructed/ and decoded/ "
                 f"({n_tables} tables, {n_tables * MERL_FILE_SIZE / 1e9:.2f} GB); brdfkit material {name} -o "
                 f"{name}.binary writes the material's alone.", soft_wrap=True)
    emb = os.path.relpath(os.path.join(res.out_dir, "embeddings", f"{name}-{INTERPOLATION_MODEL}.emb"))
    report.print(f"Next: brdfkit sparse {samples} -m {SPARSE_MODEL} -o r.binary && "
                 f"brdfkit plot r.binary {emb} -m {INTERPOLATION_MODEL} -o r.png", soft_wrap=True)


def _compression_caption(res) -> str:
    """What the compression columns hold, by the kinds of embedding the demo made (a basis
    embedding's label reads ``basis-K``, a residual embedding's ``residual-K``, a latent's ``K-D``), and how far
    each was refined."""
    from brdfkit.hypernet.refine_on_screen import DEFAULT_STEPS as LATENT_STEPS
    from brdfkit.basis.coefficients import DEFAULT_STEPS as BASIS_STEPS

    steps = res.compression_steps
    labels = [label for _, _, label, _ in res.compressions]
    basis = any(" basis-" in label for label in labels)
    residual = any(" residual-" in label for label in labels)
    latent = any(" basis-" not in label and " residual-" not in label for label in labels)
    parts = []
    if residual:
        parts.append("residual-K: the full table compressed into K coefficients of the PCA basis the model ships "
                     "and the correction of its hypernetwork residual (kept only where the objective scenes' held-out "
                     "pixels render better with it), the default of a model that ships one, "
                     + (f"refined on screen, at most {steps} steps" if steps > 0 else "not refined"))
    if basis:
        parts.append("basis-K: the full table compressed, as brdfkit encode does by default, into K numbers, the "
                     "coefficients of the PCA basis the model ships (K / 3 components a colour channel), "
                     + (f"refined on screen, at most {steps} steps (brdfkit encode takes at most {BASIS_STEPS} by "
                        f"default)" if steps > 0 else "the projection only"))
    if latent:
        parts.append("K-D: the full table compressed into the hypernetwork's K-D latent (a model that ships no "
                     "basis), " + (f"refined on screen, at most {steps} steps (brdfkit encode takes at most "
                                   f"{LATENT_STEPS} by default)" if steps > 0 else "the encoder's pass only"))
    return "; ".join(parts) + "; each then decoded"


def _train(out_dir, minutes, steps, n_materials, holdout, seed, device, do_render, options, keep_tables):
    from rich.console import Console
    from rich.table import Table

    from brdfkit.demos.synthetic_training import RENDER_RESOLUTION, SAMPLE_COUNTS, run_demo

    res = run_demo(out_dir, minutes=minutes, steps=steps, n_materials=n_materials, holdout=holdout, seed=seed,
                   device=device, render=do_render, options=dict(parse_option(o) for o in options),
                   keep_tables=keep_tables)
    report = Console()
    report.print(_error_table(f"Held-out materials: BRDF log RMSE (lower is better), latent {res.latent_dim}",
                              res.columns, res.errors))
    report.print("median reference: the training materials' per-cell median, used as the prediction "
                 "(what the model must beat); brdf_log_rmse as in brdfkit.evaluation.metrics.")
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
    report.print(_times_table(res.times))

    report.print(f"Files in {res.out_dir}:")
    for p in res.files:
        report.print(f"  {os.path.relpath(p, res.out_dir)}  ({_fmt_bytes(os.path.getsize(p))})")
    model = os.path.relpath(res.model_path)
    if res.keep_tables:
        report.print(f"  materials/  ({len(res.materials)} synthetic MERL tables)")
        mat = os.path.join(res.out_dir, "materials", res.held[0] + ".binary")
        report.print(f"Next: brdfkit sample {os.path.relpath(mat)} -n 100 -o s.csv && "
                     f"brdfkit sparse s.csv -m {model} -o r.binary")
        return
    report.print(f"The dense MERL tables (the {len(res.materials)} synthetic materials, the decoded ones: 35 MB "
                 f"each) were not kept; --keep-tables writes them into materials/ and decoded/.", soft_wrap=True)
    embs = [os.path.relpath(os.path.join(res.out_dir, "embeddings", f"{res.held[0]}{s}.emb"))
            for s in ("", f"-{SAMPLE_COUNTS[-1]}samples")]
    report.print(f"Next: brdfkit plot {' '.join(embs)} -m {model} -o p.png && "
                 f"brdfkit decode {embs[1]} -m {model} -o r.binary", soft_wrap=True)
