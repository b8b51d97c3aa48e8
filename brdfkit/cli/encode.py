"""``brdfkit encode``: compress MERL tables (or CSV sample sets) into ``.emb`` files."""

from __future__ import annotations

import click

from brdfkit.console import ProgressBar, console
from brdfkit.cli.common import model_option, require_model


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
@click.option("--kind", type=click.Choice(["basis", "latent"]), default=None,
              help="basis: the coefficients of the PCA basis the model ships, refined on screen (the default "
                   "for a built-in with one: it holds for materials outside the training set); latent: the "
                   "hypernetwork's latent (the default for other models, and for sample sets).")
@click.option("--max-seconds", type=click.FloatRange(min=0, min_open=True), default=None,
              help="Also stop a table's refinement after this many seconds (off by default: a cut result "
                   "depends on the machine's speed; the output says when it cut).")
def command(inputs, model_path, output_dir, refine, steps, kind, max_seconds):
    """Encode each BRDF (.binary MERL table, .bsdf RGL file or .csv sample set) into <stem>.emb.

    A table (MERL or RGL) is encoded from all its measured cells. With a built-in model
    that ships a PCA basis it becomes a basis embedding (--kind basis, the default there):
    the coefficients of the basis's leading latent/3 components, projected and refined for
    at most --steps steps [default: 80] on renders of the objective scenes
    (docs/compression.md). Otherwise the hypernetwork's latent is refined so [default:
    40 steps] (docs/model.md). Either way a step is kept only where held-out pixels agree.
    A sample set gets the encoder's pass. A bad input is reported and skipped; the
    others are still encoded, and the exit code is 2 if any failed.
    """
    import os

    from brdfkit.api import encode, load_model
    from brdfkit.atomic import refuse_overwrite_of_inputs
    from brdfkit.io.embedding import write_embedding
    from brdfkit.errors import BrdfkitError, InputError

    model_path = require_model(model_path)
    model = load_model(model_path)
    if output_dir:
        os.makedirs(output_dir, exist_ok=True)
    out = console()
    failures: list[str] = []
    planned: dict[str, str] = {}
    cut: list[str] = []
    kinds: set[str] = set()
    done = 0

    def one(path: str) -> None:
        stem = os.path.splitext(os.path.basename(path))[0]
        target = os.path.join(output_dir if output_dir else os.path.dirname(path) or ".", stem + ".emb")
        key = os.path.realpath(target)
        if key in planned:
            raise InputError(f"{path}: would write {target}, already written for {planned[key]}; "
                             f"rename one of them")
        refuse_overwrite_of_inputs(target, [*inputs, model_path])
        emb = encode(model, path, refine=refine, steps=steps, max_seconds=max_seconds, kind=kind)
        write_embedding(target, emb)
        planned[key] = path
        kinds.add(f"basis embedding {emb.latent_dim // 3} x 3" if emb.basis else f"latent {emb.latent_dim}")
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
    how = "refined on screen" if refine and steps != 0 else ("projection" if kinds and all(
        k.startswith("basis") for k in kinds) else "encoder pass")
    made = ", ".join(sorted(kinds)) or f"latent {model.cfg.latent_dim}"
    out.print(f"encoded {done} of {len(inputs)} file{'s' if len(inputs) != 1 else ''} "
              f"({made}, model {model.short_fingerprint}, {how}) into {where}")
    if cut:
        out.print(f"note: --max-seconds cut the refinement of {', '.join(cut)}: those embeddings depend on the "
                  f"machine's speed (replay one with --steps N)", soft_wrap=True)
    if failures:
        for msg in failures:
            click.echo(f"brdfkit: error: {msg}", err=True)
        raise click.exceptions.Exit(2)
