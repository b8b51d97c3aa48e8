"""``brdfkit decode``: expand an embedding into a dense MERL table."""

from __future__ import annotations

import click

from brdfkit.cli.common import model_option, require_model


@click.command("decode")
@click.argument("embedding", type=click.Path(dir_okay=False))
@model_option
@click.option("-o", "--output", type=click.Path(dir_okay=False), default=None,
              help="Output MERL .binary; default: <stem>.binary beside the embedding.")
def command(embedding, model_path, output):
    """Decode EMBEDDING (.emb) with the model that made it into a MERL .binary table.

    Without -m, the built-in model whose fingerprint the embedding records is used.
    Cells below the horizon are written as -1 (MERL's "not measured").
    """
    import os

    from brdfkit.api import decode, load_model
    from brdfkit.atomic import refuse_overwrite_of_inputs
    from brdfkit.io.embedding import read_embedding
    from brdfkit.io.merl import write_merl

    if output is None:
        output = os.path.splitext(embedding)[0] + ".binary"
    refuse_overwrite_of_inputs(output, [embedding])
    emb = read_embedding(embedding)
    model_path = require_model(model_path, emb.model_fingerprint)
    refuse_overwrite_of_inputs(output, [model_path])
    model = load_model(model_path)
    table = decode(model, emb, source=embedding)
    write_merl(output, table)
    click.echo(f"decoded {embedding} into {output}", err=True)
