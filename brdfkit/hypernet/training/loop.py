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
import dataclasses
import json
import math
import os
import time

from brdfkit.atomic import refuse_overwrite_of_inputs
from brdfkit.hypernet.training.display import TrainingDisplay
from brdfkit.distributed import ProcessGroup, StopSignals
from brdfkit.errors import InputError, TrainingError
from brdfkit.hypernet.training.options import TrainOptions, lr_factor, parse_options

__all__ = ["fit", "TrainOptions", "TrainingError", "DEFAULT_STEPS"]

DEFAULT_STEPS = 2000


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
        Model file to write (``.safetensors``, via :func:`brdfkit.hypernet.network_file.save_network`);
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
        A network file or built-in name whose reference table replaces the median, so that
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


@dataclasses.dataclass
class _Run:
    """A training run in progress: the network, its optimiser and the counters that its
    checkpoint, its progress line and its network file record.

    Attributes
    ----------
    net, opt
        The :class:`~brdfkit.hypernet.network.HyperBRDF` (not wrapped in DDP) and its optimiser.
    cfg, opts
        The architecture and the :class:`TrainOptions`.
    names, digest, seed, world, reference_from
        The materials, the training set's digest, the seed, the number of processes and
        the digest of the reference's model (``None``: the median of the materials).
    t_start
        ``time.monotonic()`` at the call of :func:`fit`.
    steps, budget
        Stop at this step (``None``: no limit); ``budget``: the seconds since ``t_start``
        of ``--minutes``, turned into ``steps`` before the first step
        (:mod:`brdfkit.hypernet.training.budget`) and then ``None``.
    budget_record
        How ``--minutes`` chose ``steps`` (``None``: it did not), for the network file.
    step, elapsed_before, skipped, resumed_from
        Steps done, seconds spent by the runs this one resumes, steps skipped for a
        non-finite loss, and the steps the training was resumed at.
    consecutive_bad
        Non-finite steps in a row.
    recent
        ``(loss, mapped MSE)`` of the last 50 good steps, averaged over the processes.
    samples_total
        Query samples of this run's steps, all processes together.
    """

    net: object
    opt: object
    cfg: object
    opts: TrainOptions
    names: list
    digest: str
    seed: int
    world: int
    reference_from: object
    t_start: float
    steps: int | None
    budget: float | None
    step: int = 0
    elapsed_before: float = 0.0
    skipped: int = 0
    resumed_from: list = dataclasses.field(default_factory=list)
    consecutive_bad: int = 0
    recent: collections.deque = dataclasses.field(default_factory=lambda: collections.deque(maxlen=50))
    samples_total: float = 0.0
    budget_record: dict | None = None

    def checkpoint_state(self) -> dict:
        """The state :func:`~brdfkit.hypernet.training.checkpoint.save_checkpoint` writes."""
        return {"step": self.step, "elapsed": self.elapsed_before + (time.monotonic() - self.t_start),
                "skipped": self.skipped, "resumed_from": self.resumed_from,
                "net": self.net.state_dict(), "optimizer": self.opt.state_dict(),
                "config": self.cfg.to_json(), "options": self.opts.identity_json(), "materials": self.names,
                "data_digest": self.digest, "seed": self.seed, "world_size": self.world,
                "reference_from": self.reference_from}

    def fraction(self) -> float:
        """Share of the run done, of the steps or of the time budget, whichever is further."""
        f = self.step / self.steps if self.steps else 0.0
        if self.budget:
            f = max(f, (time.monotonic() - self.t_start) / self.budget)
        return f

    def status(self, rate: float) -> str:
        """The progress bar's status line at ``rate`` query samples per second."""
        loss_txt = f"loss {self.recent[-1][0]:.4g}" if self.recent else "loss -"
        return (f"step {self.step}{f'/{self.steps}' if self.steps else ''}  {loss_txt}  {rate:,.0f} samples/s"
                + (f"  skipped {self.skipped}" if self.skipped else ""))


def _announce(show, names, excluded, unknown, world, device):
    """The first lines of the log: what is trained, where, and unmatched exclusions."""
    show.print(f"training on {len(names)} material(s)"
               + (f", {len(excluded)} held out" if excluded else "")
               + (f", {world} processes" if world > 1 else "") + f", device {device}")
    if unknown:
        show.print(f"[yellow]warning:[/] excluded name(s) not among the inputs: {', '.join(unknown[:8])}"
                   + (" ..." if len(unknown) > 8 else ""))


def _resumable_checkpoint(ckpt, cfg, opts, names, seed, ref) -> dict:
    """The checkpoint ``ckpt`` (on the CPU), refused unless made for this architecture,
    these options, materials, seed and reference; the data's digest is checked later, by
    :func:`_resume`."""
    from brdfkit.hypernet.training.checkpoint import check_resumable, load_checkpoint

    state = load_checkpoint(ckpt, "cpu")
    check_resumable(ckpt, state, config=cfg.to_json(), options=opts.identity_json(),
                    materials=names, seed=seed)
    ref.check_resumable(ckpt, state)
    return state


def _read_tables(show, dist, paths, names, ref):
    """This process's :class:`~brdfkit.hypernet.training.dataset.TrainingSet`, with the
    reading shown; refused unless every process computed the same reference."""
    from brdfkit.hypernet.training.dataset import TrainingSet

    show.start("reading")
    tset = TrainingSet.load(paths, names, dist.rank, dist.world, reference=ref.table,
                            on_read=lambda i, p: show.update(i / len(paths), os.path.basename(p)))
    show.update(1.0, f"{len(paths)} tables, {tset.cells.size:,} cells measured in all")
    show.stop()
    digests = dist.gather_hex(tset.digest)
    if len(set(digests)) != 1:
        raise TrainingError("the processes computed different reference tables from the same data")
    return tset


def _optimizer(net, opts):
    """Adam, or AdamW when ``opts.weight_decay`` is positive, at ``opts.lr``."""
    import torch

    if opts.weight_decay > 0:
        return torch.optim.AdamW(net.parameters(), lr=opts.lr, weight_decay=opts.weight_decay)
    return torch.optim.Adam(net.parameters(), lr=opts.lr)


def _resume(run: _Run, state: dict, ckpt, show):
    """Continue ``run`` from the checkpoint ``state`` of ``ckpt`` (refused if made for
    other data): weights, optimiser and counters."""
    from brdfkit.hypernet.training.checkpoint import check_resumable

    check_resumable(ckpt, state, config=run.cfg.to_json(), options=run.opts.identity_json(),
                    materials=run.names, seed=run.seed, data_digest=run.digest)
    run.net.load_state_dict(state["net"])
    run.opt.load_state_dict(state["optimizer"])
    run.step = int(state["step"])
    run.elapsed_before = float(state.get("elapsed", 0.0))
    run.skipped = int(state.get("skipped", 0))
    run.resumed_from = [int(s) for s in state.get("resumed_from", [])] + [run.step]
    note = ""
    if int(state.get("world_size", 1)) != run.world:
        note = f" (it was written by {state.get('world_size')} process(es), now {run.world}: " \
               f"the materials are shared out differently from here on)"
    show.print(f"resuming from {ckpt} at step {run.step}{note}")


def _step(run: _Run, model, sampler, dist, stop, ckpt):
    """One optimiser step of every process (skipped by all when one has a non-finite loss
    or gradient). Returns ``(interrupted, time_up)``, as agreed by the processes."""
    import torch

    from brdfkit.hypernet import network

    net, opt, opts, device = run.net, run.opt, run.opts, dist.device
    ctx_hd, ctx_val, q_hd, q_val, q_cos = sampler.draw(run.step)
    opt.zero_grad(set_to_none=True)
    pred, weights, z = model(ctx_hd, ctx_val, q_hd)
    total, mse = network.hyper_loss(pred, q_val, q_cos, weights, z, run.cfg)
    total.backward()
    gnorm = torch.nn.utils.clip_grad_norm_(net.parameters(), opts.grad_clip)
    local_bad = ~(torch.isfinite(total.detach()) & torch.isfinite(gnorm))
    # Rank 0's clock alone decides the time budget and the schedule, so every
    # rank stops at the same step and uses the same learning rate.
    time_frac = (time.monotonic() - run.t_start) / run.budget if dist.rank == 0 and run.budget else 0.0
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
        run.skipped += 1
        run.consecutive_bad += 1
        if run.consecutive_bad >= opts.max_bad_steps:
            raise TrainingError(
                f"training stopped at step {run.step + 1}: the loss or its gradient was NaN or "
                f"infinite for {run.consecutive_bad} consecutive steps (lower the learning rate "
                f"with -O lr=..., or check the data); {ckpt} keeps the last checkpoint")
    else:
        lr = opts.lr * lr_factor(run.step, max(run.step / run.steps if run.steps else 0.0, time_frac), opts)
        for group in opt.param_groups:
            group["lr"] = lr
        opt.step()
        run.consecutive_bad = 0
        run.recent.append((loss_sum / run.world, mse_sum / run.world))
    run.step += 1
    run.samples_total += nq
    return interrupt > 0, up > 0


class _NoStop:
    """No stop signal: what :func:`_step` sees while its steps are timed."""

    requested = False


def _loop(run: _Run, model, sampler, dist, show, ckpt) -> float:
    """The steps until ``run.steps``, the time budget or a stop signal (then a checkpoint
    and :class:`KeyboardInterrupt`), with periodic checkpoints and the progress bar.
    Returns the loop's start, ``time.monotonic()``."""
    from brdfkit.hypernet.training.checkpoint import save_checkpoint

    last_ckpt = time.monotonic()
    last_show, shown_samples = time.monotonic(), 0.0
    t_loop = time.monotonic()
    start_step = run.step
    run.net.train()
    with StopSignals() as stop:
        show.start("training")
        try:
            while run.steps is None or run.step < run.steps:
                interrupt, up = _step(run, model, sampler, dist, stop, ckpt)
                if interrupt:
                    if dist.rank == 0 and run.step > start_step:
                        save_checkpoint(ckpt, run.checkpoint_state())
                    show.stop()
                    show.print(f"interrupted at step {run.step}; checkpoint {ckpt} saved "
                               f"(continue with --resume)")
                    raise KeyboardInterrupt
                if up:
                    break
                now = time.monotonic()
                if dist.rank == 0 and now - last_ckpt >= run.opts.checkpoint_minutes * 60.0:
                    save_checkpoint(ckpt, run.checkpoint_state())
                    last_ckpt = time.monotonic()
                if show.enabled and now - last_show >= 0.5:
                    rate = (run.samples_total - shown_samples) / (now - last_show)
                    show.update(run.fraction(), run.status(rate))
                    last_show, shown_samples = now, run.samples_total
            if show.enabled:
                elapsed = time.monotonic() - t_loop
                show.update(1.0, run.status(run.samples_total / elapsed if elapsed > 0 else 0.0))
        finally:
            show.stop()
    return t_loop


def _finish(run: _Run, dist, show, output, ckpt, rho_ref, excluded, t_loop, start_step):
    """Check that the processes ended with the same weights; rank 0 writes the last
    checkpoint and the network file (with its provenance) and logs them."""
    from brdfkit.hypernet.training.checkpoint import save_checkpoint
    from brdfkit.hypernet.network_file import save_network, weights_digest

    loop_time = time.monotonic() - t_loop
    recent, step, skipped = run.recent, run.step, run.skipped
    final_loss = sum(r[0] for r in recent) / len(recent) if recent else float("nan")
    final_mse = sum(r[1] for r in recent) / len(recent) if recent else float("nan")
    digests = dist.gather_hex(weights_digest(run.net))
    if len(set(digests)) != 1:
        raise TrainingError(f"the processes ended with different weights ({', '.join(f[:12] for f in digests)})")
    wall = run.elapsed_before + (time.monotonic() - run.t_start)
    meta = {"method": "hypernet", "materials": run.names, "excluded": excluded, "steps": step,
            "skipped_steps": skipped, "wall_time_s": round(wall, 3), "seed": run.seed,
            "world_size": run.world, "final_loss": final_loss, "final_mapped_mse": final_mse,
            "device": dist.device.type, "options": json.loads(run.opts.identity_json()),
            "resumed_from_steps": run.resumed_from, "rank_digests": digests,
            "reference_from": run.reference_from,  # None: the median of "materials"
            "budget": run.budget_record,  # how --minutes chose "steps" (None: --steps alone)
            "query_samples_per_s": round(run.samples_total / loop_time, 1) if loop_time > 0 else None}
    if dist.rank == 0:
        save_checkpoint(ckpt, run.checkpoint_state())
        fp = save_network(output, run.net, rho_ref, meta)
        show.print(f"trained {step} steps ({step - start_step} in this run, {loop_time:.1f} s, "
                   f"{meta['query_samples_per_s'] or 0:,.0f} query samples/s); final loss {final_loss:.4g} "
                   f"(mapped MSE {final_mse:.4g})" + (f"; {skipped} non-finite step(s) skipped" if skipped else ""))
        show.print(f"wrote {output} (digest {fp[:12]}); checkpoint {ckpt}")
    dist.barrier()


def _train(dist, paths, names, excluded, unknown, output, ckpt, cfg, opts, steps, minutes, seed,
           resume, progress, t_start, ref):
    """The training of :func:`fit` in this process of ``dist``: read the data, optimise,
    and (rank 0) write the model and its checkpoint. Returns ``output``."""
    import torch

    from brdfkit.hypernet import network
    from brdfkit.hypernet.training.dataset import BatchSampler

    rank, world, device = dist.rank, dist.world, dist.device
    show = TrainingDisplay(progress and rank == 0)
    _announce(show, names, excluded, unknown, world, device)
    # Checked before the slow reading of the data; the content after it.
    state = _resumable_checkpoint(ckpt, cfg, opts, names, seed, ref) if resume else None
    tset = _read_tables(show, dist, paths, names, ref)

    torch.manual_seed(seed)  # same initial weights on every rank
    net = network.HyperBRDF(cfg).to(device)
    run = _Run(net, _optimizer(net, opts), cfg, opts, names, tset.digest, seed, world, ref.digest, t_start,
               steps, minutes * 60.0 if minutes is not None else None)
    if state is not None:
        _resume(run, state, ckpt, show)
    elif os.path.exists(ckpt):
        show.print(f"note: starting afresh; {ckpt} will be replaced (use --resume to continue it)")
    del state  # its tensors are copied into the network and the optimiser

    model = net
    if dist.active:
        from torch.nn.parallel import DistributedDataParallel as DDP
        model = DDP(net, device_ids=[device.index] if device.type == "cuda" else None)

    sampler = BatchSampler(tset, device, opts.batch_materials, opts.query_size, opts.context_min,
                           opts.context_max, seed, rank, opts.angle_fraction, opts.mixup)
    rho_ref = tset.rho_ref
    tset.values = None  # the sampler holds them now (on the device); no second host copy
    start_step = run.step
    if run.budget is not None:
        from brdfkit.hypernet.training.budget import fit_steps_from_budget

        fit_steps_from_budget(run, lambda: _step(run, model, sampler, dist, _NoStop(), ckpt), dist, show)
    t_loop = _loop(run, model, sampler, dist, show, ckpt)
    _finish(run, dist, show, output, ckpt, rho_ref, excluded, t_loop, start_step)
    return output
