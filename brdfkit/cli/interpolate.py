"""``brdfkit interpolate``: blend two embeddings (material editing), once (``--t``) or as
a strip of renders from A to B (``--sheet``)."""

from __future__ import annotations

import click

from brdfkit.console import console
from brdfkit.figures.interpolation_strip import MAX_SIZE, MAX_STEPS, MIN_SIZE, SIZE, STEPS
from brdfkit.cli.common import model_option, parse_float


def _mode(t_text, output, binary, allow_extrapolation, sheet, steps, tile) -> str:
    """``"blend"`` or ``"strip"``, or an InputError naming the options that do not go
    together: ``--t T -o OUT.emb`` writes one blend, ``--sheet FILE.png`` (with
    ``--steps``, ``--tile``) draws the strip from t = 0 to 1."""
    from brdfkit.errors import InputError

    blend_opts = [flag for flag, v in (("--t", t_text), ("-o", output), ("--binary", binary),
                                       ("--allow-extrapolation", allow_extrapolation)) if v]
    if sheet is not None:
        if blend_opts:
            raise InputError(f"{', '.join(blend_opts)}: --sheet draws the strip from t = 0 to 1 and writes only "
                             f"the PNG; blend once with --t T -o OUT.emb in a separate call")
        return "strip"
    strip_opts = [flag for flag, v in (("--steps", steps), ("--tile", tile)) if v is not None]
    if strip_opts:
        raise InputError(f"{', '.join(strip_opts)}: options of the strip; add --sheet FILE.png "
                         f"(or blend once with --t T -o OUT.emb)")
    if t_text is None or output is None:
        missing = "-o OUT.emb" if t_text is not None else "--t T" if output is not None else "--t T -o OUT.emb"
        raise InputError(f"missing {missing}: --t T -o OUT.emb writes one blend; --sheet FILE.png "
                         f"[--steps N] draws the strip from A to B")
    return "blend"


@click.command("interpolate")
@click.argument("a", type=click.Path(dir_okay=False))
@click.argument("b", type=click.Path(dir_okay=False))
@click.option("-t", "--t", "t_text", default=None, metavar="T",
              help="Blend weight: 0 gives A, 1 gives B (with -o).")
@click.option("-o", "--output", type=click.Path(dir_okay=False), default=None, help="Output .emb of the blend.")
@click.option("--binary", "binary", type=click.Path(dir_okay=False), default=None,
              help="Also decode the blend into this MERL .binary (needs the model).")
@click.option("--allow-extrapolation", is_flag=True, help="Accept T outside [0, 1].")
@click.option("--sheet", type=click.Path(dir_okay=False), default=None,
              help="Instead: render --steps blends from A (t = 0) to B (t = 1) in the reference scene "
                   "into this PNG strip, each labelled with its t.")
@click.option("--steps", type=click.IntRange(min=2, max=MAX_STEPS), default=None,
              help=f"Materials in the --sheet strip, t evenly spaced from 0 to 1 [default: {STEPS}].")
@click.option("--tile", type=click.IntRange(min=MIN_SIZE, max=MAX_SIZE), default=None, metavar="PX",
              help=f"Pixels per tile side of the --sheet strip (one render each) [default: {SIZE}].")
# The old spelling of --tile (--size is the numbers per material in `encode`): still taken, with a note.
@click.option("--size", "old_tile", type=click.IntRange(min=MIN_SIZE, max=MAX_SIZE), default=None, hidden=True)
@model_option
def command(a, b, t_text, output, binary, allow_extrapolation, sheet, steps, tile, old_tile, model_path):
    """Write the embedding (1 - T) A + T B; both must be of the same kind, size and decoder.

    With --sheet FILE.png instead of --t and -o: render --steps materials from A (t = 0)
    to B (t = 1) in the reference scene, --tile pixels square each, and write them as one
    labelled strip, the paper's editing figure (docs/editing.md).
    """
    from brdfkit.api import decode, interpolate
    from brdfkit.atomic import refuse_overwrite_of_inputs
    from brdfkit.io.embedding import write_embedding

    tile = _tile(tile, old_tile)
    mode = _mode(t_text, output, binary, allow_extrapolation, sheet, steps, tile)
    if mode == "strip":
        _strip(a, b, sheet, steps, tile, model_path)
        return
    t = parse_float(t_text, "--t")
    if not allow_extrapolation and not 0.0 <= t <= 1.0:
        from brdfkit.errors import InputError

        raise InputError(f"--t {t:g} is outside [0, 1]; add --allow-extrapolation to extrapolate")
    refuse_overwrite_of_inputs(output, [a, b, model_path])
    refuse_overwrite_of_inputs(binary, [a, b, model_path, output])
    ea, eb = _read_named(a, b)
    mix = interpolate(ea, eb, t, allow_extrapolation=allow_extrapolation)
    table = None
    if binary:
        table = decode(mix, model_path, source=output)
    write_embedding(output, mix)
    if table is not None:
        from brdfkit.io.merl import write_merl

        write_merl(binary, table)
    console().print(f"wrote {output}{f' and {binary}' if binary else ''} (t = {t:g})")


def _tile(tile, old_tile):
    """``--tile``, or its old spelling ``--size`` with a note on stderr (both: they must agree)."""
    if old_tile is None:
        return tile
    from brdfkit.errors import InputError

    click.echo("note: interpolate --size is now --tile", err=True)
    if tile is not None and tile != old_tile:
        raise InputError(f"--tile {tile} and --size {old_tile}: --size is the old spelling of --tile; give --tile only")
    return old_tile


def _read_named(a, b):
    from brdfkit.io.embedding import read_embedding

    ea, eb = read_embedding(a), read_embedding(b)
    # Named by their files: a mismatch message must say which file to fix (two embeddings
    # encoded from the same samples.csv share their source), and the blend's provenance
    # reads "interpolate(a.emb, b.emb, t=0.3)".
    ea.source, eb.source = a, b
    return ea, eb


def _strip(a, b, sheet, steps, tile, model_path):
    from brdfkit.atomic import refuse_overwrite_of_inputs
    from brdfkit.errors import InputError
    from brdfkit.figures.interpolation_strip import check_strip, interpolation_strip

    refuse_overwrite_of_inputs(sheet, [a, b, model_path])
    if not sheet.lower().endswith(".png"):
        raise InputError(f"{sheet}: the strip is written as PNG; name it .png")
    steps, tile = steps or STEPS, tile or SIZE
    check_strip(steps, tile)  # before the model loads
    ea, eb = _read_named(a, b)
    from brdfkit.embeddings import decoder_for

    tiles = interpolation_strip(decoder_for(ea, model_path, name=a), ea, eb, sheet, steps=steps, size=tile,
                                progress=True)
    console().print(f"wrote {sheet} ({len(tiles)} materials, t = "
                    f"{', '.join(f'{t:.3g}' for t, _ in tiles)}; {tile} px each)", soft_wrap=True)
