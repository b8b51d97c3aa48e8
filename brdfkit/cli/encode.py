"""``brdfkit encode``: compress MERL tables (or CSV sample sets) into ``.emb`` files."""

from __future__ import annotations

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
              help="Refine a table's latent on screen after the encoder's pass (--no-refine: the "
                   "paper's single pass).")
@click.option("--steps", type=click.IntRange(min=0), default=None,
              help="Most refinement steps per table [default: 80 for a basis embedding, 40 for a latent]; a "
                   "latent's stops sooner when held-out pixels stop improving. The same input gives the same "
                   "bytes, however busy the machine.")
@click.option("--kind", type=click.Choice(_kind_names()), default=None,
              help="What the numbers are: " + "; ".join(f"{k.name}: {k.summary}" for k in KINDS.values())
                   + ". Default: for a built-in, the first of these it ships a part for that offers --size; for a "
                     "file, the part it is; for sample sets, hypernet. (latent: the old name of hypernet.)")
@click.option("--size", type=click.IntRange(min=1), default=None,
              help="Numbers per material: a basis or residual embedding holds 3 a component (3, 6, 9 ... up to "
                   "3 x the basis's components; default 39); a hypernet embedding the network's latent size.")
@click.option("--max-seconds", type=click.FloatRange(min=0, min_open=True), default=None,
              help="Also stop a latent's refinement after this many seconds (off by default: a cut result "
                   "depends on the machine's speed; the output says when it cut).")
def command(inputs, model_path, output_dir, refine, steps, kind, size, max_seconds):
    """Encode each BRDF (.binary MERL table, .bsdf RGL file or .csv sample set) into <stem>.emb.

    A table (MERL or RGL) is encoded from all its measured cells. With a built-in model
    that ships a PCA basis (or a basis file) it becomes a basis embedding (--kind basis,
    the default there): the coefficients of the basis's --size/3 leading components,
    projected and refined for at most --steps steps [default: 80] on renders of the
    objective scenes (docs/compression.md). Otherwise the hypernetwork's latent is refined
    so [default: 40 steps] (docs/model.md). Either way a step is kept only where held-out
    pixels agree. A sample set gets the hypernetwork encoder's pass. A bad input is
    reported and skipped; the others are still encoded, and the exit code is 2 if any
    failed.
    """
    import os

    from brdfkit.api import encode
    from brdfkit.atomic import refuse_overwrite_of_inputs
    from brdfkit.errors import BrdfkitError, InputError
    from brdfkit.io.embedding import write_embedding
    from brdfkit.embeddings import choose_decoder, get_kind, kind_of_part

    tables = [p for p in inputs if not p.lower().endswith(".csv")]
    # One decoder for the tables, loaded once; sample sets take the hypernetwork's latent.
    dec = choose_decoder(kind, model_path, size=size) if tables else None
    lat = choose_decoder(kind_of_part("network").name, model_path) if len(tables) < len(inputs) else None
    if size is not None and dec is not None:
        dec.check_size(size)  # before any work
    if output_dir:
        os.makedirs(output_dir, exist_ok=True)
    out = console()
    failures: list[str] = []
    planned: dict[str, str] = {}
    cut: list[str] = []
    kinds: set[str] = set()
    starts: set[str] = set()  # what each kind is before refinement (EmbeddingKind.start)
    done = 0

    def one(path: str) -> None:
        stem = os.path.splitext(os.path.basename(path))[0]
        target = os.path.join(output_dir if output_dir else os.path.dirname(path) or ".", stem + ".emb")
        key = os.path.realpath(target)
        if key in planned:
            raise InputError(f"{path}: would write {target}, already written for {planned[key]}; "
                             f"rename one of them")
        samples = path.lower().endswith(".csv")
        refuse_overwrite_of_inputs(target, [*inputs, (lat if samples else dec).path])
        emb = encode(path, lat if samples else dec, size=None if samples else size, refine=refine, steps=steps,
                     max_seconds=max_seconds)
        write_embedding(target, emb)
        planned[key] = path
        kinds.add(f"{emb.kind} {emb.size} numbers, {(lat if samples else dec).label}")
        starts.add(get_kind(emb.kind).start)
        if emb.refinement and emb.refinement["stopped"] == "max_seconds":
            cut.append(f"{stem} ({emb.refinement['steps']} steps)")

    if len(inputs) > 1:
        with ProgressBar("encoding", total=len(inputs), count=True, out=out) as bar:
            for path in inputs:
                bar.update(description=f"encoding {os.path.basename(path)}")
                try:
                    one(path)
                    done += 1
                except (BrdfkitError, OSError) as e:
                    failures.append(str(e) if isinstance(e, BrdfkitError) else f"{path}: {e.strerror or e}")
                bar.update(advance=1)
    else:
        one(inputs[0])
        done = 1
    where = output_dir if output_dir else "beside the inputs"
    start = " or ".join(sorted(s for s in starts if s))
    how = "refined on screen" if refine and steps != 0 else f"{start or 'no refinement'}, not refined"
    out.print(f"encoded {done} of {len(inputs)} file{'s' if len(inputs) != 1 else ''} "
              f"({'; '.join(sorted(kinds)) or 'none'}; {how}) into {where}", soft_wrap=True)
    if cut:
        out.print(f"note: --max-seconds cut the refinement of {', '.join(cut)}: those embeddings depend on the "
                  f"machine's speed (replay one with --steps N)", soft_wrap=True)
    if failures:
        for msg in failures:
            click.echo(f"brdfkit: error: {msg}", err=True)
        raise click.exceptions.Exit(2)
