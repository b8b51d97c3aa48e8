"""``brdfkit synth``: write a synthetic material library as MERL tables."""

from __future__ import annotations

import click

from brdfkit.console import console


@click.command("synth")
@click.argument("folder", type=click.Path(file_okay=False))
@click.option("-n", "--count", "n", type=click.IntRange(min=1), default=16, show_default=True,
              help="Number of materials.")
@click.option("--seed", type=int, default=0, show_default=True, help="Random seed (same seed, same library).")
@click.option("--no-stiff", is_flag=True, help="Leave out the stiff cases (mirror, black, white, grazing).")
def command(folder, n, seed, no_stiff):
    """Write N synthetic GGX materials into FOLDER as MERL .binary tables.

    Parameter ranges are documented in docs/synthetic.md.
    """
    from brdfkit.materials.synthetic import library, table
    from brdfkit.io.merl import write_merl
    import os

    os.makedirs(folder, exist_ok=True)
    out = console()
    for m in library(n, seed, stiff=not no_stiff):
        path = os.path.join(folder, m.name + ".binary")
        write_merl(path, table(m))
        out.print(f"{path}  {m.kind}, alpha={m.alpha:.3g}")
