"""``brdfkit decode``: expand an embedding into a dense MERL table."""

from __future__ import annotations

import click

from brdfkit.cli.common import model_option


@click.command("decode")
@click.argument("embedding", type=click.Path(dir_okay=False))
@model_option
@click.option("-o", "--output", type=click.Path(dir_okay=False), default=None,
              help="Output MERL .binary; default: <stem>.binary beside the embedding.")
def command(embedding, model_path, output):
    """Decode EMBEDDING (.emb) with the decoder that made it into a MERL .binary table.

    Without -m, the installed built-in part (PCA basis, basis residual or hypernetwork)
    whose digest the embedding records is used.
    Cells below the horizon are written as -1 (MERL's "not measured").
    """
    import os

    from brdfkit.api import decode
    from brdfkit.atomic import refuse_overwrite_of_inputs
    from brdfkit.io.embedding import read_embedding
    from brdfkit.io.merl import write_merl
    from brdfkit.embeddings import decoder_for
    from brdfkit.runtime import stage

    if output is None:
        output = os.path.splitext(embedding)[0] + ".binary"
    refuse_overwrite_of_inputs(output, [embedding])
    with stage("read embedding"):
        emb = read_embedding(embedding)
    with stage("load model"):
        dec = decoder_for(emb, model_path, name=embedding)
    refuse_overwrite_of_inputs(output, [dec.path])
    with stage("decode"):
        table = decode(emb, dec, source=embedding)
    with stage("write table"):
        write_merl(output, table)
    click.echo(f"decoded {embedding} into {output}", err=True)
