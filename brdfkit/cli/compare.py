"""``brdfkit compare``: a comparison sheet of predictions against a reference (PNG)."""

from __future__ import annotations

import json

import click

from brdfkit.cli.common import model_option
from brdfkit.cli.render import threads_option


@click.command("compare")
@click.argument("paths", nargs=-1, required=True, type=click.Path(dir_okay=False), metavar="[REF] PRED...")
@click.option("--ref", "ref", type=click.Path(dir_okay=False), default=None, metavar="REF",
              help="The reference, named (then every argument is a prediction), as brdfkit metrics --ref takes it.")
@model_option
@click.option("--sheet", "-o", "sheet", required=True, type=click.Path(dir_okay=False),
              help="Output PNG: renders in a row with their errors, error images below.")
@click.option("--resolution", type=click.IntRange(min=16, max=4096), default=None,
              help="Size of the reference-scene renders of BRDF inputs (default 256).")
@click.option("--scene", default="reference", show_default=True,
              help="The suite scene BRDF inputs are rendered in (docs/render.md: reference, backlight, rim, "
                   "small-lights, overcast, sunset).")
@click.option("--json", "as_json", is_flag=True, help="Print the scores as JSON on stdout.")
@threads_option
@click.option("--quiet", is_flag=True, help="No progress bars.")
def command(paths, ref, model_path, sheet, resolution, scene, as_json, threads, quiet):
    """Compare predictions PRED... with the reference REF on one sheet.

    The reference comes first (compare REF PRED...) or is named (compare --ref REF
    PRED...), as brdfkit metrics --ref REF PRED takes it. Inputs are MERL .binary tables,
    RGL .bsdf files, .emb embeddings (with -m MODEL) or .exr images of the same size; BRDFs are rendered
    in the reference scene (--scene: another of the suite). The sheet shows the renders in a row, each prediction
    labelled with PSNR, Delta E 2000, SSIM and the BRDF log RMSE against REF (the
    numbers of `brdfkit metrics`), and the per-pixel Delta E 2000 under each
    (docs/compare.md).
    """
    from brdfkit.atomic import refuse_overwrite_of_inputs
    from brdfkit.errors import InputError
    from brdfkit.figures.comparison_sheet import comparison_sheet
    from brdfkit.runtime import set_torch_threads

    ref, preds = (ref, list(paths)) if ref is not None else (paths[0], list(paths[1:]))
    if not preds:
        raise InputError(f"compare {ref}: no prediction; give the reference and at least one PRED")
    refuse_overwrite_of_inputs(sheet, [ref, *preds, model_path])
    if not sheet.lower().endswith(".png"):
        raise InputError(f"{sheet}: the sheet is written as PNG; name it .png")
    # Threads are set on the first render: a sheet of images never imports torch.
    rows = comparison_sheet(ref, preds, sheet, model_path=model_path, resolution=resolution,
                            progress=not quiet and not as_json,
                            before_torch=lambda: set_torch_threads(threads), scene=scene)
    if as_json:
        click.echo(json.dumps({"reference": ref, "predictions": rows}))
    else:
        for label, s in rows.items():
            extra = "" if s["brdf_log_rmse"] is None else f", BRDF log RMSE {s['brdf_log_rmse']:.4f}"
            click.echo(f"{label}: PSNR {s['psnr']:.2f} dB, Delta E 2000 {s['delta_e']:.3f}, "
                       f"SSIM {s['ssim']:.4f}{extra}")
    click.echo(f"wrote {sheet}", err=True)
