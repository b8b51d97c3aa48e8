"""``brdfkit material``: one of the real materials shipped with brdfkit, written as a MERL
table (:func:`brdfkit.materials.nbrdf_networks.write_material`)."""

from __future__ import annotations

import sys

import click


@click.command("material")
@click.argument("name", required=False)
@click.option("-o", "--output", type=click.Path(), default=None,
              help="Output MERL .binary, or a folder to write NAME.binary into [default: NAME.binary].")
@click.option("--list", "list_names", is_flag=True, help="List the shipped materials and exit.")
@click.pass_context
def command(ctx, name, output, list_names):
    """Write the shipped material NAME as a dense MERL .binary table (35 MB, in seconds).

    brdfkit ships the published NBRDF fits (Sztrajman et al. 2021) of four MERL
    materials, the real materials of `brdfkit demo`: blue-metallic-paint, teflon,
    chrome-steel and violet-rubber (--list says what each looks like). NAME's network is
    decoded on the CPU into the table the demo decodes (materials/NAME.binary of `brdfkit
    demo --keep-tables`): a table to sample, encode, render or compare against
    (docs/getting-started.md).

    With no NAME and no --list, prints this help and exits with status 2.
    """
    from brdfkit.console import console
    from brdfkit.materials.nbrdf_networks import MATERIAL_NOTES, material_names, write_material

    if list_names:
        if name is not None or output is not None:
            from brdfkit.errors import InputError

            raise InputError("--list lists the shipped materials; give it alone")
        for n in material_names():
            click.echo(f"{n:<20}  {MATERIAL_NOTES.get(n, '')}".rstrip())
        return
    if name is None:
        click.echo(ctx.get_help(), err=True)
        sys.exit(2)
    path = write_material(name, output)
    console().print(f"wrote {path} ({name}, the NBRDF fit brdfkit ships; MERL table, 1/sr)", soft_wrap=True)
