"""``brdfkit sparse``: reconstruct a dense MERL table from sparse samples."""

from __future__ import annotations

import click

from ..methods import METHODS
from .common import model_option, optional_model, require_model


def _model_from_env() -> bool:
    from click.core import ParameterSource

    return click.get_current_context().get_parameter_source("model_path") is ParameterSource.ENVIRONMENT


@click.command("sparse")
@click.argument("samples", type=click.Path(dir_okay=False))
@model_option
@click.option("-o", "--output", type=click.Path(dir_okay=False), required=True,
              help="Output dense MERL .binary table.")
@click.option("--emb", "emb_path", type=click.Path(dir_okay=False), default=None,
              help="Also write the embedding (.emb) (hypernet only).")
@click.option("--method", type=click.Choice(sorted(METHODS)), default="hypernet", show_default=True,
              help="Reconstruction method.")
def command(samples, model_path, output, emb_path, method):
    """Reconstruct a dense MERL table from the sample set SAMPLES (.csv).

    Make a sample set with `brdfkit sample`; its format is in docs/formats.md.
    Cells below the horizon are written as -1. The hypernet method without -m uses the
    default built-in model (`brdfkit models`).
    """
    from ..atomic import refuse_overwrite_of_inputs
    from ..embedding import write_embedding
    from ..errors import InputError
    from ..merl import write_merl
    from ..samples import read_samples

    chosen = METHODS[method]
    if not chosen.needs_model and _model_from_env():
        model_path = None  # $BRDFKIT_MODEL names a hypernetwork, not meant for this method
    model_path = optional_model(model_path)
    inputs = [samples, model_path]
    refuse_overwrite_of_inputs(output, inputs)
    refuse_overwrite_of_inputs(emb_path, inputs + [output])
    data = read_samples(samples)
    if model_path is None and method == "hypernet":
        # The built-ins are hypernetworks: only this method takes the default one.
        model_path = require_model(None)
        refuse_overwrite_of_inputs(output, [model_path])
        refuse_overwrite_of_inputs(emb_path, [model_path])
    table, emb = chosen.sparse(data, model_path)
    if emb_path and emb is None:
        raise InputError(f"--emb: method {method!r} makes no embedding")
    write_merl(output, table)
    if emb_path:
        write_embedding(emb_path, emb)
    extra = f" and {emb_path}" if emb_path else ""
    click.echo(f"reconstructed {output}{extra} from {len(data)} samples ({method})", err=True)
