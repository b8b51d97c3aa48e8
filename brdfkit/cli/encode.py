"""``brdfkit encode``: compress MERL tables (or CSV sample sets) into ``.emb`` files."""

from __future__ import annotations

import os

import click

from brdfkit.console import ProgressBar, console
from brdfkit.cli.common import model_option
from brdfkit.embeddings.registry import KINDS


def _kind_names() -> list:
    """The ``--kind`` values: each kind's name, then the old names it still takes."""
    return [k.name for k in KINDS.values()] + [a for k in KINDS.values() for a in k.aliases]


@click.command("encode")
# No click-side checks of the inputs: a missing file or a folder among many is reported
# with the other failures at the end instead of stopping the whole run.
@click.argument("inputs", nargs=-1, required=True, type=click.Path())
@model_option
@click.option("-o", "--output-dir", type=click.Path(file_okay=False), default=None,
              help="Folder for the .emb files (created if missing); default: beside each input.")
@click.option("--refine/--no-refine", default=True, show_default=True,
              help="Refine a table's embedding on renders after its first estimate (Levenberg-Marquardt on a basis or "
                   "residual embedding's coefficients, Adam on a latent; --no-refine: the projection onto the "
                   "basis, or the paper's single encoder pass).")
@click.option("--steps", type=click.IntRange(min=0), default=None,
              help="Most refinement iterations per table [default: 8 Levenberg-Marquardt iterations for a residual or "
                   "basis embedding, 40 Adam steps for a latent]; fewer when held-out pixels stop improving. The "
                   "same input gives the same bytes, however busy the machine.")
@click.option("--kind", type=click.Choice(_kind_names()), default=None,
              help="What the numbers are: " + "; ".join(f"{k.name}: {k.summary}" for k in KINDS.values())
                   + ". Default: for a built-in, the first of these it serves at --size (`brdfkit models` lists "
                     "the kinds and sizes each serves); for a file, the part it is; for sample sets, hypernet. "
                     "(latent: the old name of hypernet.)")
@click.option("--size", type=click.IntRange(min=1), default=None,
              help="Numbers per material: a basis or residual embedding holds 3 a component (3, 6, 9 ... up to "
                   "3 x the basis's components; default 39); a hypernet embedding the network's latent size.")
@click.option("--max-seconds", type=click.FloatRange(min=0, min_open=True), default=None,
              help="Also stop a latent's refinement after this many seconds (off by default: a cut result "
                   "depends on the machine's speed; the output says when it cut). A hypernet embedding's "
                   "only: a basis or residual refinement is counted in iterations.")
@click.option("--jobs", "-j", type=click.IntRange(min=1, max=256), default=1, show_default=True,
              help="Processes encoding at once (each loads the model once; the same output bytes "
                   "whatever the count).")
def command(inputs, model_path, output_dir, refine, steps, kind, size, max_seconds, jobs):
    """Encode each BRDF (.binary MERL table, .bsdf RGL file or .csv sample set) into <stem>.emb.

    A table (MERL or RGL) is encoded from all its measured cells. With a built-in model
    it becomes, by default, the first kind the model ships a part for that offers --size:
    a residual embedding (merl-rgl-l40, the default, and merl80-l40: at 9, 21, 39
    numbers; `brdfkit models`) or a basis embedding (--kind basis): the coefficients of
    the basis's --size/3 leading components, projected and refined by at most --steps
    Levenberg-Marquardt iterations [default: 8] on renders of the objective scenes
    (docs/compression.md). With a hypernetwork (--kind hypernet, or a network file) the
    latent is refined by Adam steps [default: 40] (docs/model.md).
    Either way an iterate is kept only where held-out pixels agree. A sample set gets the
    hypernetwork encoder's pass. Many files are read one ahead of the encode, with the
    model loaded once (--jobs N: in N processes). A bad input is reported and skipped;
    the others are still encoded, and the exit code is 2 if any failed.
    """
    from brdfkit.errors import InputError
    from brdfkit.embeddings import choose_decoder, get_kind, kind_of_part
    from brdfkit.embeddings.batch import EncodeJob, encode_files

    tables = [p for p in inputs if not p.lower().endswith(".csv")]
    samples = [p for p in inputs if p.lower().endswith(".csv")]
    latent = kind_of_part("network").name
    if samples and size is not None:
        raise InputError(f"{samples[0]}: --size sets a table's embedding; a .csv sample set is encoded as the "
                         f"hypernetwork's latent, of the model's size (encode the sample sets without --size)")
    if samples and kind is not None and get_kind(kind).name != latent:
        raise InputError(f"{samples[0]}: --kind {kind} is made from a table; a .csv sample set is encoded as a "
                         f"{latent} latent (encode the sample sets without --kind)")
    from brdfkit.api import encode, load_input
    from brdfkit.embeddings.batch import Reader
    from brdfkit.runtime import stage

    job = EncodeJob(model_path, kind, size, steps, refine, max_seconds, output_dir, read=load_input, encode=encode)
    reader = Reader(job)
    if jobs == 1 or len(inputs) == 1:
        reader.start(inputs[0])  # the first table is read while the model loads
    try:
        _check_decoders(choose_decoder, get_kind, kind, model_path, size, max_seconds, tables, samples, latent)
    except BaseException:
        reader.close()
        raise
    out = console()
    if len(inputs) > 1:
        with ProgressBar("encoding", total=len(inputs), count=True, out=out) as bar:
            outcomes = encode_files(inputs, job, jobs=jobs, reader=reader, on_done=lambda o: bar.update(
                advance=1, description=f"encoded {os.path.basename(o.path)}"))
    else:
        outcomes = encode_files(inputs, job, reader=reader)
        if outcomes[0].error:
            raise InputError(outcomes[0].error)
    with stage("report"):
        _report(out, outcomes, job)


def _check_decoders(choose_decoder, get_kind, kind, model_path, size, max_seconds, tables, samples, latent):
    """The decoders loaded (and a size checked) before any work (workers load their own)."""
    from brdfkit.errors import InputError
    from brdfkit.runtime import stage

    with stage("load model"):
        dec = choose_decoder(kind, model_path, size=size) if tables else None
    if samples:
        choose_decoder(latent, model_path)
    if size is not None and dec is not None:
        dec.check_size(size)
    if max_seconds is not None and dec is not None and not get_kind(dec.kind).wall_clock:
        raise InputError(f"--max-seconds caps a hypernetwork latent's refinement; a {dec.kind} embedding's is "
                         f"counted in iterations (--steps N)")


def _report(out, outcomes, job) -> None:
    """The summary line, the note on cut refinements, the failures (exit 2)."""
    from brdfkit.embeddings import get_kind

    done = [o for o in outcomes if o.error is None]
    kinds = sorted({f"{o.kind} {o.size} numbers, {o.label}" for o in done})
    starts = " or ".join(sorted({get_kind(o.kind).start for o in done} - {""}))
    how = "refined on screen" if job.refine and job.steps != 0 else f"{starts or 'no refinement'}, not refined"
    where = job.output_dir if job.output_dir else "beside the inputs"
    n = len(outcomes)
    out.print(f"encoded {len(done)} of {n} file{'s' if n != 1 else ''} ({'; '.join(kinds) or 'none'}; {how}) "
              f"into {where}", soft_wrap=True)
    cut = [f"{os.path.splitext(os.path.basename(o.path))[0]} ({o.refinement['steps']} steps)" for o in done
           if o.refinement and o.refinement["stopped"] == "max_seconds"]
    if cut:
        out.print(f"note: --max-seconds cut the refinement of {', '.join(cut)}: those embeddings depend on the "
                  f"machine's speed (replay one with --steps N)", soft_wrap=True)
    failures = [o.error for o in outcomes if o.error is not None]
    if failures:
        for msg in failures:
            click.echo(f"brdfkit: error: {msg}", err=True)
        raise click.exceptions.Exit(2)
