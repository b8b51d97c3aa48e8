"""``brdfkit fit``: train a model on MERL tables (``--method`` picks which kind)."""

from __future__ import annotations

import json

import click

from ..errors import InputError


def _fit_hypernet(data, output, common: dict) -> str:
    """The hypernetwork of Gokbudak et al. 2024 (:func:`brdfkit.training.fit`)."""
    from ..training import fit

    return fit(data, output, latent_dim=common["latent_dim"], steps=common["steps"],
               minutes=common["minutes"], seed=common["seed"], device=common["device"],
               exclude=common["exclude"], resume=common["resume"], progress=common["progress"],
               **common["advanced"])


def _fit_ipca(data, output, common: dict) -> str:
    """The PCA baseline of Nielsen et al. 2015 (:func:`brdfkit.baselines.ipca.fit_ipca`)."""
    from ..baselines.ipca import DEFAULT_COMPONENTS, fit_ipca
    from ..trainset import collect_materials

    advanced = dict(common["advanced"])
    components = advanced.pop("components", DEFAULT_COMPONENTS)
    if advanced or common["resume"]:
        extra = sorted(advanced) + (["resume"] if common["resume"] else [])
        raise InputError(f"--method ipca takes only --components and --exclude/--exclude-list, "
                         f"not {', '.join(extra)}")
    paths, names, _, unknown = collect_materials(data, common["exclude"])
    if unknown:
        click.echo(f"brdfkit: warning: excluded name(s) matched no input: {', '.join(unknown)}", err=True)
    fit_ipca(paths, components, names=names).save(output)
    click.echo(f"wrote PCA basis ({components} components, {len(names)} materials) to {output}", err=True)
    return output


# method name -> function(data, output, common) -> output path. ``common`` holds the
# options below: latent_dim, steps, minutes, seed, device, exclude (names), resume,
# progress, advanced (dict of -O KEY=VALUE and the per-method options).
METHODS = {
    "hypernet": _fit_hypernet,
    "ipca": _fit_ipca,
}


def _parse_option(text: str) -> tuple[str, object]:
    if "=" not in text:
        raise InputError(f"-O {text!r}: expected KEY=VALUE (see docs/training.md for the keys)")
    key, value = text.split("=", 1)
    key = key.strip().replace("-", "_")
    try:
        parsed = json.loads(value)
    except ValueError:
        parsed = value  # a bare word, e.g. lr_schedule=cosine
    if isinstance(parsed, list):
        parsed = tuple(parsed)
    return key, parsed


@click.command("fit")
@click.argument("data", nargs=-1, required=True, type=click.Path())
@click.option("-o", "--output", type=click.Path(dir_okay=False), required=True,
              help="Model file to write (.safetensors); the checkpoint goes to OUTPUT.ckpt.")
@click.option("--method", type=click.Choice(list(METHODS)), default="hypernet", show_default=True,
              help="What to train.")
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
              help="Wall-clock budget in minutes; stops at --steps or here, whichever first.")
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
              help="Principal components of --method ipca [default: 8, as Nielsen et al. 2015].")
@click.option("-q", "--quiet", is_flag=True, help="No progress display.")
def command(data, output, method, latent_dim, exclude_list, exclude_names, steps, minutes, seed,
            device, resume, batch_materials, checkpoint_minutes, components, options, quiet):
    """Train a model on the MERL tables DATA (files or folders of .binary files).

    Under `torchrun --nproc_per_node K --no-python brdfkit fit ...` each process trains on
    its share of the materials (DistributedDataParallel); only the first writes files.
    Ctrl-C saves a checkpoint; --resume continues from it.
    """
    from ..atomic import refuse_overwrite_of_inputs

    exclude = list(exclude_names)
    if exclude_list:
        from ..trainset import read_exclude_list
        exclude += read_exclude_list(exclude_list)
    refuse_overwrite_of_inputs(output, list(data) + ([exclude_list] if exclude_list else []))
    advanced = dict(_parse_option(o) for o in options)
    if batch_materials is not None:
        advanced["batch_materials"] = batch_materials
    if checkpoint_minutes is not None:
        advanced["checkpoint_minutes"] = checkpoint_minutes
    if components is not None:
        if method != "ipca":
            raise InputError("--components applies to --method ipca only")
        advanced["components"] = components
    common = {"latent_dim": latent_dim, "steps": steps, "minutes": minutes, "seed": seed,
              "device": device, "exclude": exclude, "resume": resume, "progress": not quiet,
              "advanced": advanced}
    METHODS[method](list(data), output, common)
