"""``brdfkit metrics``: image and BRDF-space errors of predictions against references."""

from __future__ import annotations

import json
import os
import sys

import click

from ..console import console
from .common import model_option
from .render import threads_option

_SUFFIXES = (".binary", ".emb", ".exr")


def _kind(path: str) -> str:
    from ..errors import InputError

    ext = os.path.splitext(path)[1].lower()
    if ext == ".exr":
        return "image"
    if ext in (".binary", ".emb"):
        return "brdf"
    raise InputError(f"{path}: not a BRDF (.binary, .emb) or an image (.exr)")


class _Loader:
    """Loads each input once: images, reference-scene renders and dense tables."""

    def __init__(self, model_path, resolution, progress):
        self.model_path = model_path
        self.resolution = resolution
        self.progress = progress
        self._model = None

    def model(self):
        if self._model is None:
            from ..api import load_model
            from .common import require_model

            self._model = load_model(require_model(self.model_path))
        return self._model

    def _needs_model(self, path):
        return path.lower().endswith(".emb")

    def image(self, path, resolution=None):
        from ..render.image import read_exr
        from .render import render_brdf_file

        if _kind(path) == "image":
            return read_exr(path)
        model = self.model() if self._needs_model(path) else None
        img, _ = render_brdf_file(path, resolution=resolution or self.resolution,
                                  progress=self.progress, model=model)
        return img

    def check(self, path):
        """Read ``path`` (and the model an ``.emb`` needs) without rendering: a bad
        reference must not cost a render of the prediction first (a 256 px render is
        minutes on a busy 2-core machine; docs/stability.md)."""
        if _kind(path) == "image":
            from ..render.image import read_exr

            read_exr(path)
        elif self._needs_model(path):
            from ..embedding import check_compatible, read_embedding

            check_compatible(read_embedding(path), self.model(), path)
        else:
            from ..merl import read_merl

            read_merl(path)

    def table(self, path):
        if path.lower().endswith(".binary"):
            from ..merl import read_merl

            return read_merl(path)
        from ..api import decode
        from ..embedding import read_embedding

        return decode(self.model(), read_embedding(path))


def _pair(loader: _Loader, pred: str, ref: str) -> dict:
    """Metrics of one prediction against one reference (see ``command``)."""
    from ..atomic import check_input_file
    from ..errors import InputError
    from ..metrics import PSNR_CAP, brdf_log_rmse, image_metrics

    check_input_file(pred)
    check_input_file(ref)
    kp, kr = _kind(pred), _kind(ref)
    loader.check(pred)
    loader.check(ref)
    # A BRDF compared with an image is rendered at the image's size.
    size = None
    img_r = loader.image(ref) if kr == "image" else None
    img_p = loader.image(pred) if kp == "image" else None
    for img, path in ((img_r, ref), (img_p, pred)):
        if img is not None and size is None:
            if img.shape[0] != img.shape[1]:
                if kp != kr:
                    raise InputError(f"{path}: a {img.shape[1]}x{img.shape[0]} image cannot be compared "
                                     "with a reference-scene render (square)")
            size = img.shape[0]
    if img_p is None:
        img_p = loader.image(pred, size)
    if img_r is None:
        img_r = loader.image(ref, size)
    if img_p.shape != img_r.shape:
        raise InputError(f"{pred}, {ref}: image sizes differ ({img_p.shape[1]}x{img_p.shape[0]} "
                         f"and {img_r.shape[1]}x{img_r.shape[0]})")
    out = image_metrics(img_p, img_r)
    out["psnr"] = min(out["psnr"], PSNR_CAP)
    out["brdf_log_rmse"] = brdf_log_rmse(loader.table(pred), loader.table(ref)) \
        if kp == kr == "brdf" else None
    return out


def _stems(folder: str) -> dict:
    found = {}
    for name in sorted(os.listdir(folder)):
        stem, ext = os.path.splitext(name)
        if ext.lower() in _SUFFIXES and os.path.isfile(os.path.join(folder, name)):
            found.setdefault(stem, os.path.join(folder, name))
    return found


def _mean(rows: list) -> dict:
    out = {}
    for key in ("psnr", "delta_e", "ssim", "brdf_log_rmse"):
        vals = [r[key] for r in rows if r.get(key) is not None]
        out[key] = float(sum(vals) / len(vals)) if vals else None
    return out


def _fmt(v, digits):
    return "-" if v is None else f"{v:.{digits}f}"


def _print_table(rows: dict, mean: dict | None):
    from rich.console import Console
    from rich.table import Table

    t = Table(title=None)
    for col in ("material", "PSNR dB", "Delta E 2000", "SSIM", "BRDF log RMSE"):
        t.add_column(col, justify="left" if col == "material" else "right")
    for name, r in rows.items():
        t.add_row(name, _fmt(r["psnr"], 2), _fmt(r["delta_e"], 3), _fmt(r["ssim"], 4),
                  _fmt(r["brdf_log_rmse"], 4))
    if mean is not None:
        t.add_row("[bold]mean[/bold]", _fmt(mean["psnr"], 2), _fmt(mean["delta_e"], 3),
                  _fmt(mean["ssim"], 4), _fmt(mean["brdf_log_rmse"], 4))
    Console(soft_wrap=True).print(t)


@click.command("metrics")
@click.argument("paths", nargs=-1, metavar="PRED REF")
@model_option
@click.option("--json", "as_json", is_flag=True, help="Print JSON on stdout (see below).")
@click.option("--resolution", type=click.IntRange(min=16, max=4096), default=None,
              help="Size of the reference-scene renders of BRDF inputs (default 256).")
@threads_option
@click.option("--quiet", is_flag=True, help="No progress bars.")
@click.pass_context
def command(ctx, paths, model_path, as_json, resolution, threads, quiet):
    """Compare PRED with REF: PSNR, Delta E 2000, SSIM and the BRDF log RMSE.

    PRED and REF are BRDF files (MERL .binary, or .emb with -m MODEL), which are first
    rendered in the reference scene by the quadrature renderer, EXR images of the same
    size, or two folders whose files (.binary, .emb, .exr) are matched by file stem.
    Image metrics use the display encoding of docs/render.md (exposure 1, clipped,
    sRGB) over the whole image; PSNR of identical images is reported as 100 dB.
    brdf_log_rmse (docs/render.md) needs two BRDF files, else it is null.

    --json prints {"psnr", "delta_e", "ssim", "brdf_log_rmse"} for a pair and
    {"materials": {name: {...}}, "mean": {...}} for folders.

    With no arguments, prints this help and exits with status 2.
    """
    from ..errors import InputError

    if not paths:
        click.echo(ctx.get_help(), err=True)
        sys.exit(2)
    if len(paths) != 2:
        raise InputError(f"metrics: expected PRED REF, got {len(paths)} path(s)")
    pred, ref = paths
    from .render import set_threads

    set_threads(threads)
    loader = _Loader(model_path, resolution, progress=not quiet and not as_json)
    dirs = [os.path.isdir(p) for p in paths]
    if any(dirs) and not all(dirs):
        raise InputError(f"{pred if not dirs[0] else ref}: is a file but the other input is a folder; "
                         "give two files or two folders")
    if not all(dirs):
        result = _pair(loader, pred, ref)
        if as_json:
            click.echo(json.dumps(result))
        else:
            _print_table({os.path.splitext(os.path.basename(pred))[0]: result}, None)
        return
    a, b = _stems(pred), _stems(ref)
    common = [s for s in a if s in b]
    if not common:
        raise InputError(f"{pred}, {ref}: no file stems in common (files must be .binary, .emb or .exr)")
    for stem in sorted(set(a) ^ set(b)):
        where = pred if stem in a else ref
        console().print(f"note: {stem} only in {where}; skipped", soft_wrap=True)
    rows = {}
    for i, stem in enumerate(common, 1):
        if not (quiet or as_json):
            console().print(f"[{i}/{len(common)}] {stem}", soft_wrap=True)
        rows[stem] = _pair(loader, a[stem], b[stem])
    mean = _mean(list(rows.values()))
    if as_json:
        click.echo(json.dumps({"materials": rows, "mean": mean}))
    else:
        _print_table(rows, mean)
