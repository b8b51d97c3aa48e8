"""``brdfkit validate``: held-out error of sparse reconstructions on real samples."""

from __future__ import annotations

import click


@click.command("validate")
@click.argument("files", nargs=-1, metavar="SAMPLES...")
@click.option("--holdout", "fraction", type=click.FloatRange(0, 1, min_open=True, max_open=True), default=0.3,
              show_default=True, help="The fraction of each file's samples held out (never given to a method).")
@click.option("-n", "--count", "counts", type=click.IntRange(min=1), multiple=True,
              help="N, the samples each reconstruction is given, drawn from the rest; repeat for several "
                   "[default: all the rest].")
@click.option("--seed", "seeds", type=int, multiple=True,
              help="Draws the held-out set and the N samples (and seeds the method); repeat for several "
                   "[default: 0].")
@click.option("--method", "methods", multiple=True, metavar="NAME[=MODEL]",
              help="A method to score: auto (brdfkit sparse's default), or a method name (prior, hypernet, "
                   "ipca, nbrdf) with =MODEL a built-in name or a model file, e.g. ipca=ipca8.safetensors; "
                   "repeat to compare side by side [default: auto].")
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON on stdout.")
@click.option("-o", "--output", type=click.Path(dir_okay=False), default=None,
              help="Also write the report as JSON to this file.")
@click.pass_context
def command(ctx, files, fraction, counts, seeds, methods, as_json, output):
    """Hold out a fraction of each sample file's measurements, reconstruct the material
    from N of the others, and report how well each method predicts the held-out ones.

    SAMPLES are sample files as `brdfkit sparse` reads them: pbrt-v2 / Cornell .brdf,
    brdfkit's sample CSV, or a measurement CSV (radians or degrees, RGB or one column
    per wavelength). The scores, at the held-out samples (docs/formats.md,
    "Held-out error"): log RMSE (the mapping of the BRDF log RMSE, ln(1 + rho cos
    theta_i)) and the relative error in luminance (sum |Y_pred - Y| / sum Y; and its
    median over samples). Means and standard deviations over the seeds per file, N and
    method, then the mean over files.

    With no arguments, prints this help and exits with status 2.
    """
    import sys

    if not files:
        click.echo(ctx.get_help(), err=True)
        sys.exit(2)
    from brdfkit.atomic import refuse_overwrite_of_inputs
    from brdfkit.evaluation.holdout import validate_files

    refuse_overwrite_of_inputs(output, list(files))
    report = validate_files(files, methods or ("auto",), fraction=fraction, counts=counts or (None,),
                            seeds=seeds or (0,), progress=not as_json)
    if output:
        report.write(output)
    if as_json:
        click.echo(report.to_json())
    else:
        report.print_table()
