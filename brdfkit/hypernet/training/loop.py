"""Training the hypernetwork BRDF model (Gokbudak et al. 2024) on MERL tables.

:func:`fit` reads the training tables (:class:`brdfkit.hypernet.training.dataset.TrainingSet`), builds the
reference table of the mapping (per-cell median of the training materials, eq. 1, or
another model's, ``reference``), and optimises :class:`brdfkit.hypernet.network.HyperBRDF`
with the paper's loss (eq. 3) on batches drawn on the fly
(:class:`brdfkit.hypernet.training.dataset.BatchSampler`): per step ``B`` materials, each with a query set
for the loss and a separate context set of random size for the encoder, so that one
model serves any number of samples. Adam, gradient clipping, non-finite steps skipped,
periodic atomic checkpoints (:mod:`brdfkit.hypernet.training.checkpoint`) and resume, Ctrl-C saved, and
data-parallel training under ``torchrun`` (one process per share of the materials).
``docs/training.md`` documents the options and the measured throughput.
"""

from __future__ import annotations

import collections
import json
import math
import os
import time

from brdfkit.atomic import refuse_overwrite_of_inputs
from brdfkit.hypernet.training.distributed import ProcessGroup, StopSignals
from brdfkit.errors import InputError, TrainingError
from brdfkit.hypernet.training.options import TrainOptions, lr_factor, parse_options

__all__ = ["fit", "TrainOptions", "TrainingError", "DEFAULT_STEPS"]

DEFAULT_STEPS = 2000


class _Display:
    """Rank 0's progress on stderr (Rich); silent when ``progress`` is off."""

    def __init__(self, enabled: bool):
        self.enabled = enabled
        self.console = None
        self.bar = None
        if enabled:
            from brdfkit.console import console
            self.console = console()

    def print(self, *args, **kw):
        if self.console:
            self.console.print(*args, **kw)

    def start(self, description: str):
        if not self.enabled:
            return self
        from brdfkit.console import ProgressBar

        self.bar = ProgressBar(f"[bold]{description}", total=1.0, status=True, transient=False,
                               out=self.console).start()
        return self

    def update(self, fraction: float, status: str):
        if self.bar is not None:
            self.bar.update(min(max(fraction, 0.0), 1.0), status=status)

    def stop(self):
        if self.bar is not None:
            self.bar.stop()
            self.bar = None


def fit(data, output, *, latent_dim: int = 40, steps: int | None = None, minutes: float | None = None,
        seed: int = 0, device=None, exclude=(), resume: bool = False, progress: bool = True,
        reference=None, **advanced) -> str:
    """Train a hypernetwork BRDF model on MERL tables and save it.

    Parameters
    ----------
    data
        A ``.binary`` file or folder, or a sequence of them (folders: their ``*.binary``
        files). Materials are named by file stem and sorted by name.
    output
        Model file to write (``.safetensors``, via :func:`brdfkit.hypernet.model_file.save_model`);
        the checkpoint goes to ``<output>.ckpt``.
    latent_dim
        Embedding size (40 as in the paper; 7 for compression).
    steps, minutes
        Stop after this many optimiser steps or this many wall-clock minutes since the
        call (data loading included), whichever comes first; with neither,
        ``steps = 2000``.
    seed
        Seeds the initial weights (identical on every rank) and the batch sampler.
    device
        ``"auto"`` / ``None`` (CUDA when present), ``"cpu"`` or ``"cuda"``.
    exclude
        Material names to hold out (e.g. a test split).
    resume
        Continue from ``<output>.ckpt``; refused if it was made for other data or options.
    progress
        Show a progress bar and messages on stderr (rank 0 only).
    reference
        A model file or built-in name whose reference table replaces the median, so that
        models trained on other materials share one reference file (``docs/training.md``).
    **advanced
        :class:`TrainOptions` fields and :class:`~brdfkit.hypernet.network.HyperConfig` fields
        (architecture), e.g. ``query_size=256, hypo_hidden=16`` for tiny tests.

    Returns
    -------
    str
        ``output``.

    Raises
    ------
    InputError
        No materials, unreadable files, bad options, output equal to an input (the
        reference model too), no such reference model, or a checkpoint that does not match.
    FormatError
        A training table or the reference model is not what it should be.
    TrainingError
        The loss stayed non-finite for ``max_bad_steps`` consecutive steps, or the ranks
        of a distributed run disagree.
    KeyboardInterrupt
        After SIGINT/SIGTERM, once a checkpoint of the last completed step is written.
    """
    t_start = time.monotonic()
    opts, cfg = parse_options(latent_dim, advanced)
    if steps is None and minutes is None:
        steps = DEFAULT_STEPS
    if steps is not None and (isinstance(steps, bool) or not isinstance(steps, int) or steps < 1):
        raise InputError(f"steps must be a positive integer, got {steps!r}")
    if minutes is not None and not (isinstance(minutes, (int, float)) and minutes > 0 and math.isfinite(minutes)):
        raise InputError(f"minutes must be a positive number, got {minutes!r}")
    if isinstance(exclude, str):
        exclude = [exclude]

    from brdfkit.hypernet.training.checkpoint import checkpoint_path
    from brdfkit.hypernet.training.dataset import given_reference

    output = os.fspath(output)
    ckpt = checkpoint_path(output)
    paths, names, excluded, unknown = _collect(data, exclude)
    ref = given_reference(reference)
    refuse_overwrite_of_inputs(output, [*paths, ref.path])
    refuse_overwrite_of_inputs(ckpt, [*paths, ref.path])
    folder = os.path.dirname(os.path.abspath(output))
    if not os.path.isdir(folder):
        raise InputError(f"{output}: output folder {folder} does not exist")
    if os.path.isdir(output):
        raise InputError(f"{output}: is a directory, expected an output file path")

    dist = ProcessGroup(device)
    try:
        return _train(dist, paths, names, excluded, unknown, output, ckpt, cfg, opts, steps, minutes,
                      seed, resume, progress, t_start, ref)
    finally:
        dist.close()


def _collect(data, exclude):
    from brdfkit.io.folders import collect_materials
    return collect_materials(data, exclude)


def _train(dist, paths, names, excluded, unknown, output, ckpt, cfg, opts, steps, minutes, seed,
           resume, progress, t_start, ref):
    import torch

    from brdfkit.hypernet import network
    from brdfkit.hypernet.training.checkpoint import check_resumable, load_checkpoint, save_checkpoint
    from brdfkit.hypernet.model_file import save_model, weights_fingerprint
    from brdfkit.hypernet.training.dataset import BatchSampler, TrainingSet

    rank, world, device = dist.rank, dist.world, dist.device
    show = _Display(progress and rank == 0)
    show.print(f"training on {len(names)} material(s)"
               + (f", {len(excluded)} held out" if excluded else "")
               + (f", {world} processes" if world > 1 else "") + f", device {device}")
    if unknown:
        show.print(f"[yellow]warning:[/] excluded name(s) not among the inputs: {', '.join(unknown[:8])}"
                   + (" ..." if len(unknown) > 8 else ""))

    state = None
    if resume:  # checked before the slow reading of the data; the content after it
        state = load_checkpoint(ckpt, "cpu")
        check_resumable(ckpt, state, config=cfg.to_json(), options=opts.identity_json(),
                        materials=names, seed=seed)
        ref.check_resumable(ckpt, state)

    show.start("reading")
    tset = TrainingSet.load(paths, names, rank, world, reference=ref.table,
                            on_read=lambda i, p: show.update(i / len(paths), os.path.basename(p)))
    show.update(1.0, f"{len(paths)} tables, {tset.cells.size:,} cells measured in all")
    show.stop()
    digests = dist.gather_hex(tset.digest)
    if len(set(digests)) != 1:
        raise TrainingError("the processes computed different reference tables from the same data")

    torch.manual_seed(seed)  # same initial weights on every rank
    net = network.HyperBRDF(cfg).to(device)
    if opts.weight_decay > 0:
        opt = torch.optim.AdamW(net.parameters(), lr=opts.lr, weight_decay=opts.weight_decay)
    else:
        opt = torch.optim.Adam(net.parameters(), lr=opts.lr)
    step, elapsed_before, skipped, resumed_from = 0, 0.0, 0, []
    if state is not None:
        check_resumable(ckpt, state, config=cfg.to_json(), options=opts.identity_json(),
                        materials=names, seed=seed, data_digest=tset.digest)
        net.load_state_dict(state["net"])
        opt.load_state_dict(state["optimizer"])
        step = int(state["step"])
        elapsed_before = float(state.get("elapsed", 0.0))
        skipped = int(state.get("skipped", 0))
        resumed_from = [int(s) for s in state.get("resumed_from", [])] + [step]
        note = ""
        if int(state.get("world_size", 1)) != world:
            note = f" (it was written by {state.get('world_size')} process(es), now {world}: " \
                   f"the materials are shared out differently from here on)"
        show.print(f"resuming from {ckpt} at step {step}{note}")
        del state
    elif os.path.exists(ckpt):
        show.print(f"note: starting afresh; {ckpt} will be replaced (use --resume to continue it)")

    model = net
    if dist.active:
        from torch.nn.parallel import DistributedDataParallel as DDP
        model = DDP(net, device_ids=[device.index] if device.type == "cuda" else None)

    sampler = BatchSampler(tset, device, opts.batch_materials, opts.query_size, opts.context_min,
                           opts.context_max, seed, rank, opts.angle_fraction, opts.mixup)
    rho_ref = tset.rho_ref
    tset.values = None  # the sampler holds them now (on the device); no second host copy

    def checkpoint_state():
        return {"step": step, "elapsed": elapsed_before + (time.monotonic() - t_start),
                "skipped": skipped, "resumed_from": resumed_from,
                "net": net.state_dict(), "optimizer": opt.state_dict(),
                "config": cfg.to_json(), "options": opts.identity_json(), "materials": names,
                "data_digest": tset.digest, "seed": seed, "world_size": world, "reference_from": ref.fingerprint}

    recent = collections.deque(maxlen=50)  # (loss, mse) of the last good steps, summed over ranks
    consecutive_bad = 0
    last_ckpt = time.monotonic()
    last_show, shown_samples = time.monotonic(), 0.0
    samples_total, t_loop = 0.0, time.monotonic()
    budget = minutes * 60.0 if minutes is not None else None
    start_step = step

    def fraction():
        f = step / steps if steps else 0.0
        if budget:
            f = max(f, (time.monotonic() - t_start) / budget)
        return f

    def status(rate):
        loss_txt = f"loss {recent[-1][0]:.4g}" if recent else "loss -"
        return (f"step {step}{f'/{steps}' if steps else ''}  {loss_txt}  {rate:,.0f} samples/s"
                + (f"  skipped {skipped}" if skipped else ""))

    net.train()
    with StopSignals() as stop:
        show.start("training")
        try:
            while steps is None or step < steps:
                ctx_hd, ctx_val, q_hd, q_val, q_cos = sampler.draw(step)
                opt.zero_grad(set_to_none=True)
                pred, weights, z = model(ctx_hd, ctx_val, q_hd)
                total, mse = network.hyper_loss(pred, q_val, q_cos, weights, z, cfg)
                total.backward()
                gnorm = torch.nn.utils.clip_grad_norm_(net.parameters(), opts.grad_clip)
                local_bad = ~(torch.isfinite(total.detach()) & torch.isfinite(gnorm))
                # Rank 0's clock alone decides the time budget and the schedule, so every
                # rank stops at the same step and uses the same learning rate.
                time_frac = (time.monotonic() - t_start) / budget if rank == 0 and budget else 0.0
                time_up = time_frac >= 1.0
                flags = torch.stack([local_bad.float().to(torch.float64),
                                     torch.tensor(float(stop.requested), dtype=torch.float64, device=device),
                                     torch.tensor(float(time_up), dtype=torch.float64, device=device),
                                     total.detach().to(torch.float64), mse.detach().to(torch.float64),
                                     torch.tensor(float(q_val.shape[0] * q_val.shape[1]),
                                                  dtype=torch.float64, device=device),
                                     torch.tensor(time_frac, dtype=torch.float64, device=device)])
                bad, interrupt, up, loss_sum, mse_sum, nq, time_frac = dist.sum_(flags).tolist()
                if bad > 0:
                    # No update: Adam's moments and the weights stay as they were.
                    skipped += 1
                    consecutive_bad += 1
                    if consecutive_bad >= opts.max_bad_steps:
                        raise TrainingError(
                            f"training stopped at step {step + 1}: the loss or its gradient was NaN or "
                            f"infinite for {consecutive_bad} consecutive steps (lower the learning rate "
                            f"with -O lr=..., or check the data); {ckpt} keeps the last checkpoint")
                else:
                    lr = opts.lr * lr_factor(step, max(step / steps if steps else 0.0, time_frac), opts)
                    for group in opt.param_groups:
                        group["lr"] = lr
                    opt.step()
                    consecutive_bad = 0
                    recent.append((loss_sum / world, mse_sum / world))
                step += 1
                samples_total += nq
                if interrupt > 0:
                    if rank == 0 and step > start_step:
                        save_checkpoint(ckpt, checkpoint_state())
                    show.stop()
                    show.print(f"interrupted at step {step}; checkpoint {ckpt} saved "
                               f"(continue with --resume)")
                    raise KeyboardInterrupt
                if up > 0:
                    break
                now = time.monotonic()
                if rank == 0 and now - last_ckpt >= opts.checkpoint_minutes * 60.0:
                    save_checkpoint(ckpt, checkpoint_state())
                    last_ckpt = time.monotonic()
                if show.enabled and now - last_show >= 0.5:
                    rate = (samples_total - shown_samples) / (now - last_show)
                    show.update(fraction(), status(rate))
                    last_show, shown_samples = now, samples_total
            if show.enabled:
                elapsed = time.monotonic() - t_loop
                show.update(1.0, status(samples_total / elapsed if elapsed > 0 else 0.0))
        finally:
            show.stop()

    loop_time = time.monotonic() - t_loop
    final_loss = sum(r[0] for r in recent) / len(recent) if recent else float("nan")
    final_mse = sum(r[1] for r in recent) / len(recent) if recent else float("nan")
    fingerprints = dist.gather_hex(weights_fingerprint(net))
    if len(set(fingerprints)) != 1:
        raise TrainingError(f"the processes ended with different weights ({', '.join(f[:12] for f in fingerprints)})")
    wall = elapsed_before + (time.monotonic() - t_start)
    meta = {"method": "hypernet", "materials": names, "excluded": excluded, "steps": step,
            "skipped_steps": skipped, "wall_time_s": round(wall, 3), "seed": seed,
            "world_size": world, "final_loss": final_loss, "final_mapped_mse": final_mse,
            "device": device.type, "options": json.loads(opts.identity_json()),
            "resumed_from_steps": resumed_from, "rank_fingerprints": fingerprints,
            "reference_from": ref.fingerprint,  # None: the median of "materials"
            "query_samples_per_s": round(samples_total / loop_time, 1) if loop_time > 0 else None}
    if rank == 0:
        save_checkpoint(ckpt, checkpoint_state())
        fp = save_model(output, net, rho_ref, meta)
        show.print(f"trained {step} steps ({step - start_step} in this run, {loop_time:.1f} s, "
                   f"{meta['query_samples_per_s'] or 0:,.0f} query samples/s); final loss {final_loss:.4g} "
                   f"(mapped MSE {final_mse:.4g})" + (f"; {skipped} non-finite step(s) skipped" if skipped else ""))
        show.print(f"wrote {output} (fingerprint {fp[:12]}); checkpoint {ckpt}")
    dist.barrier()
    return output
