"""``brdfkit plot``: in-plane lobes and theta_h / theta_d slices of BRDFs, as a PNG."""

from __future__ import annotations

import click

from brdfkit.cli.common import model_option, parse_float


def _angles(text: str, name: str) -> list[float]:
    return [parse_float(x.strip(), name) for x in text.split(",") if x.strip()]


@click.command("plot")
@click.argument("paths", nargs=-1, required=True, metavar="BRDF...")
@model_option
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False), help="Output PNG.")
@click.option("--view", type=click.Choice(["both", "lobes", "slices"]), default="both", show_default=True,
              help="In-plane lobes, theta_h / theta_d slices, or both.")
@click.option("--theta-i", "theta_i", default="0,30,60,75", show_default=True, metavar="DEG,...",
              help="Incident angles of the lobes, degrees in [0, 90).")
@click.option("--phi-d", "phi_d", default="90", show_default=True, metavar="DEG,...",
              help="phi_d of the slices, degrees in [0, 180); one row each.")
@click.option("--channel", type=click.Choice(["luminance", "red", "green", "blue"]), default="luminance",
              show_default=True, help="Plot one colour channel or the luminance (Rec. 709).")
@click.option("--cosine", is_flag=True, help="Lobes times cos(theta_o).")
@click.option("--linear", is_flag=True, help="Linear lobe radius (default: log10).")
@click.option("--decades", default="6", show_default=True,
              help="Decades below the largest value shown by the log scales.")
def command(paths, model_path, output, view, theta_i, phi_d, channel, cosine, linear, decades):
    """Plot BRDF files side by side: MERL .binary tables, RGL .bsdf files and/or .emb
    embeddings (decoded with -m MODEL).

    In-plane lobes (polar, as in BRDF Explorer) for several incident angles, and
    theta_h / theta_d slices at fixed phi_d on one shared log colour scale, each input
    named by its file stem. See docs/plot.md.
    """
    from brdfkit.atomic import refuse_overwrite_of_inputs
    from brdfkit.errors import InputError
    from brdfkit.figures.brdf_plot import check_options, load_tables, plot_brdfs

    refuse_overwrite_of_inputs(output, [*paths, model_path])
    if not output.lower().endswith(".png"):
        raise InputError(f"{output}: the plot is written as PNG; name it .png")
    angles_i, angles_d = _angles(theta_i, "--theta-i"), _angles(phi_d, "--phi-d")
    n_decades = parse_float(decades, "--decades")
    check_options(angles_i, angles_d, channel, n_decades, view)
    tables = load_tables(paths, model_path)
    plot_brdfs(tables, output, theta_i=angles_i, phi_d=angles_d, channel=channel, cosine=cosine,
               log=not linear, decades=n_decades, view=view)
    click.echo(f"wrote {output} ({view}: {', '.join(tables)})", err=True)
