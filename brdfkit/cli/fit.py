"""``brdfkit fit``: train a model on MERL tables (``--method`` picks which kind)."""

from __future__ import annotations

import click
from click.core import ParameterSource

from brdfkit.errors import InputError
from brdfkit.cli.common import parse_option
from brdfkit.training import FITTERS


@click.command("fit")
@click.argument("data", nargs=-1, required=True, type=click.Path())
@click.option("-o", "--output", type=click.Path(dir_okay=False), required=True,
              help="Model file to write (.safetensors); the checkpoint goes to OUTPUT.ckpt.")
@click.option("--method", type=click.Choice([*FITTERS, *(a for f in FITTERS.values() for a in f.aliases)]),
              default="hypernet", show_default=True,
              help="What to train: " + "; ".join(f"{f.name}, {f.summary}" for f in FITTERS.values())
                   + " (ipca: the old name of basis).")
@click.option("--latent-dim", type=click.IntRange(min=1), default=40, show_default=True,
              help="Embedding size (40 as in the paper; 7 for compression).")
@click.option("--exclude-list", type=click.Path(dir_okay=False), default=None,
              help="Text file of material names to hold out, one a line, # comments "
                   "(e.g. merl-test.txt, the paper's 20 test materials: docs/data.md).")
@click.option("--exclude", "exclude_names", multiple=True, metavar="NAME",
              help="A material name to hold out (repeatable).")
@click.option("--steps", type=click.IntRange(min=1), default=None,
              help="Optimiser steps [default: 2000 when --minutes is not given].")
@click.option("--minutes", type=float, default=None,
              help="A time budget in minutes, turned into a step count once: a few steps are timed, "
                   "then the run takes as many as fit (at most --steps), recorded in the model file so "
                   "that --steps N replays it (docs/training.md).")
@click.option("--seed", type=int, default=0, show_default=True, help="Random seed.")
@click.option("--device", default="auto", show_default=True,
              help="auto (CUDA when present), cpu or cuda.")
@click.option("--resume", is_flag=True, help="Continue from OUTPUT.ckpt (same data and options).")
@click.option("--batch-materials", type=click.IntRange(min=1), default=None,
              help="Materials per step and process [default: min(8, share)].")
@click.option("--checkpoint-minutes", type=float, default=None,
              help="Minutes between checkpoints [default: 2].")
@click.option("-O", "--option", "options", multiple=True, metavar="KEY=VALUE",
              help="Advanced option (query_size, context_min, context_max, lr, lr_schedule, "
                   "warmup_steps, architecture ...); see docs/training.md.")
@click.option("--components", type=click.IntRange(min=1), default=None,
              help="Principal components of --method basis [default: 8, as Nielsen et al. 2015].")
@click.option("-q", "--quiet", is_flag=True, help="No progress display.")
def command(data, output, method, latent_dim, exclude_list, exclude_names, steps, minutes, seed,
            device, resume, batch_materials, checkpoint_minutes, components, options, quiet):
    """Train a model on the MERL tables DATA (files or folders of .binary files).

    Under `torchrun --nproc_per_node K --no-python brdfkit fit ...` each process trains on
    its share of the materials (DistributedDataParallel); only the first writes files.
    Ctrl-C saves a checkpoint; --resume continues from it.
    """
    from brdfkit.atomic import refuse_overwrite_of_inputs

    exclude = list(exclude_names)
    if exclude_list:
        from brdfkit.io.folders import read_exclude_list
        exclude += read_exclude_list(exclude_list)
    refuse_overwrite_of_inputs(output, list(data) + ([exclude_list] if exclude_list else []))
    from brdfkit.training import get_fitter

    chosen = get_fitter(method)
    if chosen.name != method:
        from brdfkit.console import console

        console().print(f"note: fit --method {method} is now fit --method {chosen.name}")
    given = dict(parse_option(o) for o in options)
    # Then the options the user gave (each method's fit has its own defaults and refuses
    # the options it does not take).
    source = click.get_current_context().get_parameter_source
    given.update((key, value) for key, value in (
        ("latent_dim", latent_dim), ("steps", steps), ("minutes", minutes), ("seed", seed), ("device", device),
        ("resume", resume), ("batch_materials", batch_materials), ("checkpoint_minutes", checkpoint_minutes),
        ("components", components)) if source(key) is not ParameterSource.DEFAULT)
    takes = chosen.options() if callable(chosen.options) else (chosen.options or ())
    if components is not None and chosen.name != "basis" and "components" not in takes:
        raise InputError("--components applies to --method basis or prior only")
    chosen.fit(list(data), output, exclude=exclude, progress=not quiet, **given)
