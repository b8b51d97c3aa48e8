"""``brdfkit view``: one self-contained HTML page that renders BRDFs live in WebGL2."""

from __future__ import annotations

import click

from brdfkit.cli.common import model_option


@click.command("view")
@click.argument("inputs", nargs=-1, required=True, metavar="FILE...")
@model_option
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False), help="The page (.html).")
@click.option("--live", is_flag=True,
              help="Basis and residual embeddings are decoded by the page's shader from their numbers "
                   "(one basis for all of them); other inputs travel as tables.")
@click.option("--no-compress", is_flag=True,
              help="Do not gzip the page's data (for a browser without DecompressionStream; a bigger page).")
def command(inputs, model_path, output, live, no_compress):
    """Write one HTML page that renders each input live in WebGL2 on the reference scene's
    sphere: MERL .binary tables, RGL .bsdf files, .emb embeddings (decoded with -m MODEL,
    or their built-in) and sample files (.csv, .brdf; shown as points).

    The page works from disk, with no network: open it in a browser. Light: the
    reference scene's environment, integrated as `brdfkit render` integrates it, or a
    directional light dragged on a sphere; exposure; Delta E 2000 against the first
    input; the in-plane lobe of `brdfkit plot` at the light's angle. Add
    #still=1&size=256 to its address for the reference scene alone (docs/view.md).
    """
    from brdfkit.console import console
    from brdfkit.view.page import write_page

    out = console()
    done = write_page(inputs, output, model_path=model_path, live=live, compress=not no_compress)
    kinds = ", ".join(f"{label} ({kind})" for label, kind in done["materials"])
    points = f"; points: {', '.join(done['samples'])}" if done["samples"] else ""
    out.print(f"{output}: {done['bytes'] / 1e6:.1f} MB ({done['bytes']:,} bytes): {kinds}{points}", soft_wrap=True)
