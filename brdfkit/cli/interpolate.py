"""``brdfkit interpolate``: blend two embeddings (material editing)."""

from __future__ import annotations

import click

from ..console import console
from .common import model_option, parse_float, require_model


@click.command("interpolate")
@click.argument("a", type=click.Path(dir_okay=False))
@click.argument("b", type=click.Path(dir_okay=False))
@click.option("-t", "--t", "t_text", required=True, metavar="T",
              help="Blend weight: 0 gives A, 1 gives B.")
@click.option("-o", "--output", type=click.Path(dir_okay=False), required=True, help="Output .emb.")
@click.option("--binary", "binary", type=click.Path(dir_okay=False), default=None,
              help="Also decode the blend into this MERL .binary (needs the model).")
@click.option("--allow-extrapolation", is_flag=True, help="Accept T outside [0, 1].")
@model_option
def command(a, b, t_text, output, binary, allow_extrapolation, model_path):
    """Write the embedding (1 - T) A + T B; both must come from the same model."""
    from ..api import decode, interpolate, load_model
    from ..atomic import refuse_overwrite_of_inputs
    from ..embedding import read_embedding, write_embedding

    t = parse_float(t_text, "--t")
    if not allow_extrapolation and not 0.0 <= t <= 1.0:
        from ..errors import InputError

        raise InputError(f"--t {t:g} is outside [0, 1]; add --allow-extrapolation to extrapolate")
    refuse_overwrite_of_inputs(output, [a, b, model_path])
    refuse_overwrite_of_inputs(binary, [a, b, model_path, output])
    ea, eb = read_embedding(a), read_embedding(b)
    # Named by their files: a mismatch message must say which file to fix (two embeddings
    # encoded from the same samples.csv share their source), and the blend's provenance
    # reads "interpolate(a.emb, b.emb, t=0.3)".
    ea.source, eb.source = a, b
    mix = interpolate(ea, eb, t, allow_extrapolation=allow_extrapolation)
    table = None
    if binary:
        model = load_model(require_model(model_path, mix.model_fingerprint))
        table = decode(model, mix, source=output)
    write_embedding(output, mix)
    if table is not None:
        from ..merl import write_merl

        write_merl(binary, table)
    console().print(f"wrote {output}{f' and {binary}' if binary else ''} (t = {t:g})")
