"""Training budgets in steps: ``--minutes`` turned into a step count, measured once.

A run that stops on the clock depends on the machine's speed and load: it cannot be
replayed, and the same command gives other weights on a busier machine. ``--minutes M``
therefore only *chooses* the step count: the trainer times
:data:`PROBE_STEPS` of its own steps on its state, then restores that state (weights,
optimiser, counters and random streams), and runs ``N = done + (seconds left) / (seconds
a step)`` steps (at most ``--steps``), exactly as ``--steps N`` runs them, schedule
included. ``N`` is recorded in the model file (``meta["steps"]``, and ``meta["budget"]``
says how it was chosen), so ``--steps N`` replays the run bit for bit on the same thread
count. ``brdfkit fit`` (the hypernetwork and the learnt prior) and ``brdfkit tune`` use it.
"""

from __future__ import annotations

import time

__all__ = ["PROBE_STEPS", "steps_for_budget", "fit_steps_from_budget"]

PROBE_STEPS = 8
"""Steps timed to choose a ``--minutes`` run's step count."""


def steps_for_budget(seconds_left: float, probe, save, restore, *, done: int = 0, most: int | None = None,
                     devices=(), probe_steps: int = PROBE_STEPS) -> tuple[int, dict]:
    """The step count a time budget allows, measured on the trainer's own steps.

    Parameters
    ----------
    seconds_left
        Seconds of the budget left before the first step.
    probe
        ``probe()`` runs one training step (it may change the trainer's state).
    save, restore
        ``state = save()`` before the probe; ``restore(state)`` after it puts the trainer
        back as it was (torch's default random generators are restored here).
    done
        Steps already taken (a resumed run): the count is ``done`` plus the new ones.
    most
        The ``--steps`` bound, or ``None``.
    devices
        CUDA devices whose random generators the probe may use (forked and restored).
    probe_steps
        Steps timed.

    Returns
    -------
    tuple
        ``(steps, record)``: the total step count (at least ``done + 1``) and
        ``{"minutes_left": ..., "probe_steps": ..., "seconds_per_step": ..., "steps": ...}``
        for the model file.
    """
    import torch

    state = save()
    with torch.random.fork_rng(devices=list(devices)):
        t0 = time.perf_counter()
        for _ in range(probe_steps):
            probe()
        per_step = (time.perf_counter() - t0) / probe_steps
    restore(state)
    steps = done + max(1, int(max(seconds_left, 0.0) / max(per_step, 1e-9)))
    if most is not None:
        steps = min(steps, most)
    return steps, {"minutes_left": round(seconds_left / 60.0, 4), "probe_steps": probe_steps,
                   "seconds_per_step": round(per_step, 6), "steps": steps}


def fit_steps_from_budget(run, probe, dist, show) -> None:
    """Turn a training run's ``budget`` (the private ``_Run`` of
    :mod:`brdfkit.hypernet.training.loop`) into its ``steps``: :func:`steps_for_budget` on
    ``probe()`` (one step of the run), the run's weights, optimiser and counters saved and
    restored around it; every process takes rank 0's count."""
    import copy

    import torch

    def save():
        return (copy.deepcopy(run.net.state_dict()), copy.deepcopy(run.opt.state_dict()), run.step, run.skipped,
                run.consecutive_bad, list(run.recent), run.samples_total)

    def restore(state):
        run.net.load_state_dict(state[0])
        run.opt.load_state_dict(state[1])
        run.step, run.skipped, run.consecutive_bad = state[2:5]
        run.recent.clear()
        run.recent.extend(state[5])
        run.samples_total = state[6]

    budget, run.budget = run.budget, None
    left = budget - (time.monotonic() - run.t_start)
    devices = [dist.device] if dist.device.type == "cuda" else []
    steps, record = steps_for_budget(left, probe, save, restore, done=run.step, most=run.steps, devices=devices)
    agreed = dist.sum_(torch.tensor([float(steps if dist.rank == 0 else 0)], dtype=torch.float64,
                                    device=dist.device)).tolist()[0]
    run.steps = int(agreed)
    run.budget_record = dict(record, steps=run.steps)
    show.print(f"--minutes: {run.steps:,} steps ({record['seconds_per_step']:.3g} s a step over "
               f"{record['probe_steps']} timed steps); `--steps {run.steps}` replays this run")

