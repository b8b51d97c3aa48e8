"""``brdfkit metrics``: image and BRDF-space errors of predictions against references."""

from __future__ import annotations

import json
import os
import sys

import click

from brdfkit.console import console
from brdfkit.cli.common import model_option
from brdfkit.cli.render import threads_option


def _fmt(v, digits):
    return "-" if v is None else f"{v:.{digits}f}"


def _table(first: str, rows: dict, log_rmse: bool = True):
    from rich.table import Table

    t = Table(title=None)
    cols = ("PSNR dB", "Delta E 2000", "SSIM") + (("BRDF log RMSE", "peak/grazing") if log_rmse else ())
    for col in (first, *cols):
        t.add_column(col, justify="left" if col == first else "right")
    for label, r in rows.items():
        cells = [_fmt(r["psnr"], 2), _fmt(r["delta_e"], 3), _fmt(r["ssim"], 4)]
        if log_rmse:
            h = r.get("highlights") or {}
            cells += [_fmt(r["brdf_log_rmse"], 4), "/".join(_signed(h.get(k)) for k in ("peak", "grazing"))]
        t.add_row(label, *cells)
    return t


def _signed(v):
    return "-" if v is None else f"{v:+.2f}"


def _print_table(rows: dict, mean: dict | None, scenes=None):
    """The scores per material (and their mean); scored in scenes, the image scores are
    means over the scenes, and a second table gives each scene's (over the materials)."""
    from rich.console import Console

    out = Console(soft_wrap=True)
    shown = dict(rows)
    if mean is not None:
        shown["[bold]mean[/bold]"] = mean
    first = "material" if scenes is None else f"material (mean of {len(scenes)} scene{'s' * (len(scenes) > 1)})"
    out.print(_table(first, shown))
    if scenes is not None:
        per = (mean or next(iter(rows.values())))["scenes"]
        out.print(_table("scene" if mean is None else "scene (mean of the materials)", per, log_rmse=False))


SAMPLE_SUFFIXES = (".csv", ".brdf")
"""Suffixes of sample files (CSV, pbrt-v2 / Cornell ``.brdf``): a reference only."""


def _is_samples(path: str) -> bool:
    return os.path.splitext(path)[1].lower() in SAMPLE_SUFFIXES and not os.path.isdir(path)


def roles(paths, ref) -> tuple[str, str]:
    """``(pred, ref)`` of the command line: ``--ref REF PRED``; or two paths whose kinds
    tell their roles, in either order: a sample file is the reference, an ``.emb`` the
    prediction. Two paths of one kind are refused in one line: before, ``metrics`` took
    ``PRED REF`` and ``compare`` ``REF PRED``, and a silent swap would change the scores'
    meaning (peak/grazing, the row's name)."""
    from brdfkit.errors import InputError

    if ref is not None:
        if len(paths) != 1:
            raise InputError(f"metrics --ref {ref}: give one PRED (a BRDF file, an image or a folder), "
                             f"got {len(paths)} path(s)")
        return paths[0], ref
    if len(paths) != 2:
        raise InputError(f"metrics: expected --ref REF PRED, got {len(paths)} path(s)")
    samples = [_is_samples(p) for p in paths]
    if all(samples):
        raise InputError(f"{paths[0]}, {paths[1]}: two sample files; PRED must be a BRDF file")
    if any(samples):  # measurements are only ever the reference
        return (paths[1], paths[0]) if samples[0] else tuple(paths)
    embs = [p.lower().endswith(".emb") and not os.path.isdir(p) for p in paths]
    if sum(embs) == 1:  # an embedding is a reconstruction: the prediction
        return tuple(paths) if embs[0] else (paths[1], paths[0])
    raise InputError(f"metrics {paths[0]} {paths[1]}: which one is the reference? name it: brdfkit metrics "
                     f"--ref REF PRED (as brdfkit compare takes REF first; metrics used to take PRED REF)")


@click.command("metrics")
@click.argument("paths", nargs=-1, metavar="PRED")
@click.option("--ref", "ref", type=click.Path(), default=None, metavar="REF",
              help="The reference: a BRDF file, an EXR image, a sample file (.csv, .brdf), or a folder "
                   "(with PRED a folder).")
@model_option
@click.option("--json", "as_json", is_flag=True, help="Print JSON on stdout (see below).")
@click.option("--resolution", type=click.IntRange(min=16, max=4096), default=None,
              help="Size of the renders of BRDF inputs (default 256).")
@click.option("--scenes", default=None, metavar="all|A,B",
              help="Score two BRDF inputs in these scenes of the suite (all: reference, backlight, rim, "
                   "small-lights, overcast, sunset; docs/render.md), each and their mean.")
@threads_option
@click.option("--quiet", is_flag=True, help="No progress bars.")
@click.pass_context
def command(ctx, paths, ref, model_path, as_json, resolution, scenes, threads, quiet):
    """Score PRED against the reference REF (--ref): PSNR, Delta E 2000, SSIM, BRDF log RMSE.

    brdfkit metrics --ref REF PRED names the reference, as brdfkit compare takes it first
    (compare REF PRED..., or compare --ref REF PRED...). Two files whose kinds tell their
    roles may come without --ref, in either order: a sample file is the reference, an
    .emb the prediction (metrics ref.binary pred.emb); two of one kind (two tables, two
    images, two folders) need --ref (docs/render.md says why).

    PRED and REF are BRDF files (MERL .binary, RGL .bsdf, or .emb with -m MODEL), which are first
    rendered in the reference scene by the quadrature renderer (an RGL .bsdf straight
    from the file, as Mitsuba 3 renders it), EXR images of the same
    size, or two folders whose files (.binary, .bsdf, .emb, .exr) are matched by file stem.
    Image metrics use the display encoding of docs/render.md (exposure 1, clipped,
    sRGB) over the whole image; PSNR of identical images is reported as 100 dB.
    brdf_log_rmse (docs/render.md) needs two BRDF files, else it is null.

    peak/grazing (log10, two BRDF files) is the peak region's brightness against the
    reference's, below and above theta_d = 60 degrees: +0.3 a highlight twice as bright
    (invented), -1 ten times darker (lost); docs/render.md.

    REF may also be a sample file (.csv, or a pbrt-v2 / Cornell .brdf): PRED is then
    scored at its measurements' directions (log RMSE and relative luminance error, as
    `brdfkit validate` scores held-out samples; docs/formats.md).

    --json prints {"psnr", "delta_e", "ssim", "brdf_log_rmse", "highlights"} for a pair and
    {"materials": {name: {...}}, "mean": {...}} for folders. With --scenes the image
    scores are means over the scenes and "scenes": {name: {"psnr", "delta_e",
    "ssim"}} holds each scene's.

    With no arguments, prints this help and exits with status 2.
    """
    from brdfkit.errors import InputError

    if not paths and ref is None:
        click.echo(ctx.get_help(), err=True)
        sys.exit(2)
    pred, ref = roles(paths, ref)
    if _is_samples(ref):
        from brdfkit.evaluation.holdout import score_at_samples

        result = score_at_samples(pred, ref, model_path)
        click.echo(json.dumps(result) if as_json else
                   f"{pred} at the {result['covered']} of {result['samples']} samples of {ref} it has a value at: "
                   f"log RMSE {result['log_rmse']:.4f}, luminance error {_fmt(result['luminance_error'], 4)} "
                   f"(median {_fmt(result['luminance_error_median'], 4)})")
        return
    from brdfkit.evaluation.comparison import FileLoader, compare_files, compare_folders, mean_scores
    from brdfkit.render.scene_suite import scene_names
    from brdfkit.runtime import set_cpu_threads, set_torch_threads

    set_cpu_threads(threads)
    # torch's threads are set before a hypernetwork is loaded: nothing else imports torch.
    loader = FileLoader(model_path, resolution, progress=not quiet and not as_json,
                        before_torch=lambda: set_torch_threads(threads))
    names = None if scenes is None else scene_names(scenes)
    dirs = [os.path.isdir(p) for p in (pred, ref)]
    if any(dirs) and not all(dirs):
        raise InputError(f"{pred if not dirs[0] else ref}: is a file but the other input is a folder; "
                         "give two files or two folders")
    if not all(dirs):
        result = compare_files(loader, pred, ref, names, highlights=True)
        if as_json:
            click.echo(json.dumps(result))
        else:
            _print_table({os.path.splitext(os.path.basename(pred))[0]: result}, None, names)
        return

    def on_file(i, n, stem):
        if not (quiet or as_json):
            console().print(f"[{i}/{n}] {stem}", soft_wrap=True)

    def on_skip(stem, where):
        console().print(f"note: {stem} only in {where}; skipped", soft_wrap=True)

    rows = compare_folders(loader, pred, ref, on_file, on_skip, names, highlights=True)
    mean = mean_scores(list(rows.values()))
    if as_json:
        click.echo(json.dumps({"materials": rows, "mean": mean}))
    else:
        _print_table(rows, mean, names)
