"""``brdfkit sample``: draw sparse measurements of a dense MERL table."""

from __future__ import annotations

import click

from ..atomic import refuse_overwrite_of_inputs
from ..console import console


@click.command("sample")
@click.argument("brdf", type=click.Path(dir_okay=True))
@click.option("-n", "--count", "n", type=click.IntRange(min=1), required=True, help="Number of samples.")
@click.option("--seed", type=int, default=0, show_default=True, help="Random seed.")
@click.option("--distribution", type=click.Choice(["angles", "cells"]), default="angles", show_default=True,
              help="Uniform over Rusinkiewicz angles, or over measured cells.")
@click.option("-o", "--output", type=click.Path(dir_okay=False), required=True, help="Output CSV.")
def command(brdf, n, seed, distribution, output):
    """Draw N measurements of the MERL table BRDF into a CSV sample set.

    Only measured cells are drawn. The CSV has columns theta_h,theta_d,phi_d,r,g,b
    (radians, BRDF in 1/sr); see docs/formats.md.
    """
    import os

    from ..merl import read_merl
    from ..samples import draw_samples, write_samples

    refuse_overwrite_of_inputs(output, [brdf])
    table = read_merl(brdf)
    samples = draw_samples(table, n, seed, distribution, source=os.path.basename(brdf))
    write_samples(output, samples)
    console().print(f"wrote {len(samples)} samples of {brdf} to {output}")
