"""``brdfkit sparse``: reconstruct a dense MERL table from sparse samples."""

from __future__ import annotations

import click

from brdfkit.methods import METHODS
from brdfkit.cli.common import model_option, parse_option, require_model

_AUTO = "auto"  # brdfkit.methods.choice.AUTO, not imported here: --help stays light


def _model_from_env() -> bool:
    from click.core import ParameterSource

    return click.get_current_context().get_parameter_source("model_path") is ParameterSource.ENVIRONMENT


@click.command("sparse")
@click.argument("samples", type=click.Path(dir_okay=False))
@model_option
@click.option("-o", "--output", type=click.Path(dir_okay=False), required=True,
              help="Output dense MERL .binary table.")
@click.option("--emb", "emb_path", type=click.Path(dir_okay=False), default=None,
              help="Method hypernet: also write the latent (.emb) the table is decoded from.")
@click.option("--method", type=click.Choice([_AUTO] + sorted(METHODS)), default=_AUTO, show_default=True,
              help="Reconstruction method; auto: the model's own (`brdfkit models` lists the methods each "
                   "built-in serves, auto's first): a built-in's learnt prior, else its hypernetwork, else its "
                   "basis (ipca); a model file's own method.")
@click.option("-O", "--option", "method_options", multiple=True, metavar="KEY=VALUE",
              help="A method's option: prior's use_prior=false; ipca's lam=0.1; hypernet's steps=300.")
@click.option("--refine/--no-refine", default=None,
              help="Method hypernet: refine the encoded material on its samples, early-stopped on "
                   "held-out ones (docs/notes/generalisation.md) [default: refine].")
@click.option("--refine-target", type=click.Choice(["latent", "weights"]), default=None,
              help="What --refine fits: the latent only, or then the hyponet's weights too "
                   "[default: weights; latent with --emb, since refined weights have no embedding].")
def command(samples, model_path, output, emb_path, method, method_options, refine, refine_target):
    """Reconstruct a dense MERL table from the sample set SAMPLES (.csv or .brdf).

    Make a sample set with `brdfkit sample`, or bring an instrument's: a pbrt-v2 /
    Cornell .brdf file, or a CSV with angles in radians or degrees and RGB or one
    column per wavelength (converted to linear sRGB); the formats are in docs/formats.md.
    Cells below the horizon are written as -1. Without -m the default built-in model is
    used (`brdfkit models`): its learnt prior (method prior), the basis fitted in closed
    form around the prior mean a set encoder reads from the samples. The message line says
    which method and model ran.
    """
    from brdfkit.api import sparse
    from brdfkit.atomic import atomic_paths, refuse_overwrite_of_inputs
    from brdfkit.io.embedding import write_embedding
    from brdfkit.errors import InputError
    from brdfkit.io.merl import write_merl
    from brdfkit.methods.choice import choose
    from brdfkit.io.sample_files import read_sample_file

    if method != _AUTO and not METHODS[method].needs_model and _model_from_env():
        model_path = None  # $BRDFKIT_MODEL names a model, not meant for this method
    if method != _AUTO:  # the options a named method refuses, before its model is read
        _refuse_options(method, emb_path, refine, refine_target)
    choice = choose(method, model_path)
    method, model_path = choice.method, choice.path
    _refuse_options(method, emb_path, refine, refine_target)
    given = dict(parse_option(o) for o in method_options)
    if refine is not None or refine_target:
        if refine is False and refine_target:
            raise InputError("--refine-target needs --refine, not --no-refine")
        if refine_target == "weights" and emb_path:
            raise InputError("--emb: refined hyponet weights (--refine-target weights) have no embedding; "
                             "drop --emb or use --refine-target latent")
        given["refine"] = refine is not False
        if refine_target:
            given["refine_target"] = refine_target
    if method == "hypernet" and emb_path and "refine_target" not in given:
        given["refine_target"] = "latent"  # the embedding written must decode to the table written
    if model_path is None and method in ("hypernet", "prior"):
        require_model(None)  # nothing installed: the "no model given" error, with its advice
    inputs = [samples, model_path]
    refuse_overwrite_of_inputs(output, inputs)
    refuse_overwrite_of_inputs(emb_path, inputs + [output])
    options = METHODS[method].make_options(**given)  # refused before the samples are read
    data = read_sample_file(samples)
    table, emb = sparse(data, model_path, method=method, **given)
    with atomic_paths(output, emb_path) as (out_tmp, emb_tmp):  # both or neither
        write_merl(out_tmp, table)
        if emb_path:
            write_embedding(emb_tmp, emb)
    extra = f" and {emb_path}" if emb_path else ""
    used = f"method {method}" + (f", model {choice.label}" if choice.label else "")
    how = ""
    if method == "hypernet":
        how = f"; refined on the samples ({options.refine_target})" if options.refine else "; not refined"
    if data.note:
        click.echo(f"{samples}: {data.note}", err=True)
    click.echo(f"reconstructed {output}{extra} from {len(data)} samples ({used}){how}", err=True)


def _refuse_options(method: str, emb_path, refine, refine_target) -> None:
    """The options that only the hypernetwork takes, refused for another method in one line
    (before any work: nbrdf's takes minutes)."""
    from brdfkit.errors import InputError

    if emb_path and METHODS[method].embedding_kind is None:
        what = "the learnt prior (method prior)" if method == "prior" else f"method {method!r}"
        makers = [m for m, meth in METHODS.items() if meth.embedding_kind]
        raise InputError(f"--emb: {what} makes no embedding; --method {', '.join(makers)} does (its latent)")
    if (refine is not None or refine_target) and method != "hypernet":
        raise InputError(f"--refine/--refine-target apply to --method hypernet; method {method!r} "
                         f"{'already fits its samples in closed form' if method == 'prior' else 'has no encoder'}")
