"""``brdfkit tune``: the auto-decoder stage of a trained hypernetwork, fitted on renders."""

from __future__ import annotations

import click

from brdfkit.cli.common import model_option, parse_option, require_model


@click.command("tune")
@click.argument("data", nargs=-1, required=True, type=click.Path())
@model_option
@click.option("-o", "--output", type=click.Path(dir_okay=False), required=True,
              help="Tuned network file to write (.safetensors); the checkpoint goes to OUTPUT.ckpt.")
@click.option("--exclude-list", type=click.Path(dir_okay=False), default=None,
              help="Text file of material names to leave out, one a line.")
@click.option("--exclude", "exclude_names", multiple=True, metavar="NAME", help="A material to leave out.")
@click.option("--steps", type=click.IntRange(min=1), default=None, help="Steps (materials x batch each).")
@click.option("--minutes", type=click.FloatRange(min=0, min_open=True), default=None,
              help="Wall-clock budget in minutes; stops at --steps or here, whichever first.")
@click.option("--seed", type=int, default=0, show_default=True, help="Random seed.")
@click.option("--device", default="auto", show_default=True, help="auto (CUDA when present), cpu or cuda.")
@click.option("--resume", is_flag=True, help="Continue from OUTPUT.ckpt (same model, data and options).")
@click.option("-O", "--option", "options", multiple=True, metavar="KEY=VALUE",
              help="lr_decoder, lr_latent, lr_encoder, batch, pairs_per_pixel, scenes, map_weight, "
                   "lambda_z, query, context, resolution, floor_weight, floor_ratio (docs/training.md).")
@click.option("-q", "--quiet", is_flag=True, help="No progress messages.")
def command(data, model_path, output, exclude_list, exclude_names, steps, minutes, seed, device, resume, options,
            quiet):
    """Tune the model -m on renders of the MERL tables DATA (its training materials):
    one latent per material and the decoder fitted to renders of the objective scenes
    (never a judged one), the set encoder trained to reach those latents. Ctrl-C saves a checkpoint; --resume
    continues from it."""
    from brdfkit.console import console
    from brdfkit.errors import InputError
    from brdfkit.hypernet.tuning import TuneOptions, tune

    if steps is None and minutes is None:
        raise InputError("tune needs --steps or --minutes")
    exclude = list(exclude_names)
    if exclude_list:
        from brdfkit.io.folders import read_exclude_list
        exclude += read_exclude_list(exclude_list)
    opts = TuneOptions.parse(dict(parse_option(o) for o in options))
    out = console()
    say = None if quiet else (lambda msg: out.print(msg, markup=False))
    done = tune(require_model(model_path), list(data), output, exclude=exclude, steps=steps, minutes=minutes,
                seed=seed, resume=resume, options=opts, device=device, progress=say)
    out.print(f"wrote {output}: {done['steps']} steps, {done['wall_time_s']:.0f} s, screen PSNR (moving mean) "
              f"{done['screen_psnr_ema']:.2f} dB", markup=False)
