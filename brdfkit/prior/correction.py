"""The correction of a sparse reconstruction: a hypernetwork residual of the basis, trained
on the coefficients the learnt prior fits from ``N`` samples (``brdfkit fit --method
correction``).

The learnt prior (:mod:`brdfkit.prior.model`) gives a material's ``K`` basis coefficients
a channel from its samples in closed form; the basis decodes them linearly. The correction
is the paper's idea on top (Gokbudak et al. 2024): a hypernetwork reads those
coefficients, and the sample count, and predicts the weights of a small hyponet over the
cells' Rusinkiewicz HD vectors whose output is added to the basis's mapped table
(:mod:`brdfkit.residual.network`, ``ResidualConfig(count=True)``). It is trained for what
a sparse reconstruction gives it:

- **Coefficients as the reconstruction fits them.** Each step draws ``N`` log-uniform in
  ``[context_min, context_max]`` (8 to 4,000), ``batch`` materials, their ``N`` samples
  (uniform Rusinkiewicz angles) and ``cells`` query cells, exactly as the prior's
  training draws them (:func:`brdfkit.prior.fit.draw_batch`, mixup included), and fits
  the coefficients with the learnt prior (frozen) as
  :meth:`~brdfkit.prior.model.PriorModel.coefficients` does.
- **Held-out bases.** Each material is fitted with the basis of its fold, fitted without
  it (:func:`brdfkit.prior.training_data.fold_bases`, the prior's own folds): the
  coefficients and the basis's error are those of a material no basis has seen, which is
  what the correction meets.
- **Loss** (``loss``): ``"metric"``, the evaluation metric's mean square at the query
  cells, ``ln(1 + rho_hat cos_i) - ln(1 + rho cos_i)`` (the learnt prior's own loss);
  ``"mapped"``, the mean square of the mapped error, the basis's own objective (the
  compression residual's, :mod:`brdfkit.residual.training`); ``"relative"``, that of
  each row over the basis's own error of the row, so that a fit from 4,000 samples
  counts as much as one from 8.

Adam, a cosine learning rate to ``lr_end`` of itself, a budget in steps, seeded; a
checkpoint every ``checkpoint_every`` steps (``OUTPUT.ckpt``, ``--resume`` continues it to
the bit); under ``torchrun`` each process draws its own batch and the gradients are
averaged (PyTorch DDP). The output is a residual file (:mod:`brdfkit.residual.residual_file`)
of one network, ``K`` the basis's components, naming the basis it corrects and, in its
record, the learnt prior whose fits it corrects (``prior_digest``).
"""

from __future__ import annotations

import json
import math
import os
import time

import numpy as np

from brdfkit.errors import InputError

__all__ = ["CORRECTION_DEFAULTS", "fit_correction"]

CORRECTION_DEFAULTS = {"steps": 8000, "batch": 8, "cells": 4096, "lr": 1e-3, "lr_end": 0.05, "width": 32,
                       "hidden": 64, "mixup": 0.5, "folds": 5, "context_min": 8, "context_max": 4000, "seed": 0,
                       "loss": "metric", "latent": 0, "checkpoint_every": 500, "storage": "float32"}
"""The options of :func:`fit_correction` and their defaults (``-O KEY=VALUE``)."""


def _options(given: dict) -> dict:
    unknown = sorted(set(given) - set(CORRECTION_DEFAULTS) - {"minutes", "prior", "basis"})
    if unknown or given.get("minutes") is not None:
        raise InputError(f"fit --method correction takes -O prior=PRIOR, -O {', '.join(sorted(CORRECTION_DEFAULTS))} "
                         f"and --steps (a budget in steps), not {', '.join(unknown) or '--minutes'}")
    opts = dict(CORRECTION_DEFAULTS)
    for k, v in given.items():
        if k in CORRECTION_DEFAULTS and v is not None:
            want = type(CORRECTION_DEFAULTS[k])
            try:
                opts[k] = want(v) if not isinstance(v, bool) else None
            except (TypeError, ValueError):
                opts[k] = None
            if opts[k] is None or (want is int and opts[k] != v):
                raise InputError(f"-O {k}={v!r}: expected a {want.__name__}")
    for k in ("steps", "batch", "cells", "width", "hidden", "checkpoint_every", "context_min"):
        if opts[k] < 1:
            raise InputError(f"-O {k}={opts[k]}: must be at least 1")
    if not (opts["lr"] > 0 and 0 < opts["lr_end"] <= 1 and 0 <= opts["mixup"] <= 1 and opts["folds"] >= 2
            and opts["context_max"] >= opts["context_min"]):
        raise InputError("correction options: lr > 0, 0 < lr_end <= 1, 0 <= mixup <= 1, folds >= 2 and "
                         "context_max >= context_min")
    from brdfkit.residual.residual_file import STORAGES

    if opts["storage"] not in STORAGES:
        raise InputError(f"-O storage={opts['storage']}: one of {', '.join(STORAGES)}")
    if opts["loss"] not in LOSSES:
        raise InputError(f"-O loss={opts['loss']}: one of {', '.join(LOSSES)}")
    return opts


LOSSES = ("metric", "mapped", "relative")
"""The losses :func:`fit_correction` takes (module docstring)."""


def _identity(names, basis_digest, prior_digest, opts) -> str:
    keep = {k: v for k, v in opts.items() if k not in ("checkpoint_every", "storage")}
    return json.dumps({"materials": names, "basis": basis_digest, "prior": prior_digest, "options": keep},
                      sort_keys=True)


def _prior_and_basis(prior, basis):
    """``(PriorModel, basis path, basis storage)``: the learnt prior ``prior`` (a file or a
    built-in's name) and the basis file it was trained on (``basis``, or the built-in's),
    refused in one line when they differ."""
    from brdfkit.basis import load_basis, storage_of
    from brdfkit.io.tensorfile import open_safetensors
    from brdfkit.models.builtin import resolve_basis, resolve_prior
    from brdfkit.prior.prior_file import load_prior

    if prior is None:
        raise InputError("fit --method correction needs -O prior=PRIOR (a learnt-prior file or a built-in's name)")
    model = load_prior(resolve_prior(prior))
    if basis is None:
        if os.path.exists(os.fspath(prior)):
            raise InputError("fit --method correction: give the basis file the prior was trained on, -O basis=BASIS")
        basis = prior
    bpath = resolve_basis(basis)
    full = load_basis(bpath)
    if full.n_components != model.basis.n_components or not np.array_equal(full.reference, model.basis.reference) \
            or not np.array_equal(full.mean, model.basis.mean):
        raise InputError(f"fit --method correction: {bpath} is not the basis of the learnt prior {prior}")
    with open_safetensors(bpath) as f:
        storage = storage_of(f.metadata() or {})
    return model, bpath, full, storage


def fit_correction(data, output, *, prior=None, basis=None, exclude=(), progress: bool = True,
                   resume: bool = False, device=None, **options) -> str:
    """Train the correction of a learnt prior's sparse fits on the MERL tables ``data`` and
    write it to ``output`` (a residual file of one network).

    Parameters
    ----------
    data
        ``.binary`` files or folders of them (:func:`brdfkit.io.folders.collect_materials`):
        the prior's training materials.
    prior, basis
        The learnt prior (a file or a built-in's name) and the basis file it was trained
        on (a built-in's name gives both).
    options
        :data:`CORRECTION_DEFAULTS`'s keys (module docstring).

    Returns
    -------
    str
        ``output``.
    """
    import torch

    from brdfkit.atomic import refuse_overwrite_of_inputs
    from brdfkit.distributed import ProcessGroup, StopSignals
    from brdfkit.io.digest import file_digest
    from brdfkit.io.folders import collect_materials
    from brdfkit.prior.training_data import fold_bases, to_device, training_cells

    opts = _options(options)
    model, bpath, full, storage = _prior_and_basis(prior, basis)
    paths, names, _, _ = collect_materials(data, exclude)
    refuse_overwrite_of_inputs(output, [*paths, bpath])
    if len(paths) < 2 * opts["folds"]:
        raise InputError(f"--method correction needs at least {2 * opts['folds']} training materials, got {len(paths)}")
    group = ProcessGroup(device)
    say = (lambda m: print(f"fit correction: {m}", flush=True)) if progress and group.rank == 0 else (lambda m: None)
    t0 = time.monotonic()
    cells, values = training_cells(paths, full)
    fold_of = np.arange(len(paths)) % opts["folds"]
    tabs, sigmas = fold_bases(paths, fold_of, opts["folds"], full, cells, full.n_components, storage, say)
    d = to_device(values, cells, full, fold_of, opts["folds"], tabs, sigmas, group.device)
    del values, tabs, sigmas
    say(f"{len(paths)} tables, {d.n_cells:,} cells, {opts['folds']} fold bases in {time.monotonic() - t0:.0f} s")
    run = _Run(os.fspath(output) + ".ckpt", _identity(names, file_digest(bpath), model.digest, opts), opts, group,
               say)
    with StopSignals() as stop:
        state, step = run.train(d, model, stop, resume)
    if state is None:
        say(f"stopped at step {step}; --resume continues from {run.ckpt}")
        group.close()
        return os.fspath(output)
    digests = group.gather_hex(_state_digest(state))
    if len(set(digests)) != 1:
        from brdfkit.errors import TrainingError

        raise TrainingError(f"the processes ended with different weights ({', '.join(x[:12] for x in digests)})")
    if group.rank == 0:
        from brdfkit.residual.residual_file import save_residual

        meta = {"materials": names, "steps": opts["steps"], "seed": opts["seed"], "options": opts,
                "world_size": group.world, "rank_digests": digests, "purpose": "sparse",
                "prior_digest": model.digest}
        save_residual(output, [(run.cfg(full), state)], basis_digest=file_digest(bpath), basis_file=bpath, offered=(),
                      meta=meta, storage=opts["storage"])
        say(f"wrote {output}: {time.monotonic() - t0:.0f} s")
    group.barrier()
    group.close()
    return os.fspath(output)


def _state_digest(state: dict) -> str:
    import hashlib

    h = hashlib.sha256()
    for name, t in sorted(state.items()):
        h.update(name.encode())
        h.update(t.detach().cpu().float().contiguous().numpy().tobytes())
    return h.hexdigest()


def _lr_factor(step: int, steps: int, end: float) -> float:
    return end + (1.0 - end) * 0.5 * (1.0 + math.cos(math.pi * min(step, steps) / steps))


class _Run:
    """The training: its network, checkpoints (``ckpt``, checked by ``identity``), the DDP
    group, the log."""

    def __init__(self, ckpt, identity, opts, group, say):
        self.ckpt, self.identity, self.opts, self.group, self.say = ckpt, identity, opts, group, say

    def cfg(self, full):
        from brdfkit.residual.network import ResidualConfig

        k = full.n_components
        return ResidualConfig(k, k, self.opts["width"], self.opts["hidden"], 0, count=True, latent=self.opts["latent"])

    def _start(self, full, resume):
        """``(net, opt, step)``: fresh, or the checkpoint's."""
        import torch

        from brdfkit.residual.network import ResidualNet

        torch.manual_seed(self.opts["seed"])
        net = ResidualNet(self.cfg(full)).to(self.group.device)
        opt = torch.optim.Adam(net.parameters(), lr=self.opts["lr"])
        if not resume:
            return net, opt, 0
        if not os.path.isfile(self.ckpt):
            raise InputError(f"--resume: no checkpoint {self.ckpt}")
        saved = torch.load(self.ckpt, weights_only=True)
        if saved.get("identity") != self.identity:
            raise InputError(f"--resume: {self.ckpt} was made from other tables, basis, prior or options")
        net.load_state_dict(saved["net"])
        opt.load_state_dict(saved["opt"])
        self.say(f"resumed at step {saved['step']}")
        return net, opt, int(saved["step"])

    def save(self, net, opt, step) -> None:
        import torch

        from brdfkit.atomic import atomic_path

        with atomic_path(self.ckpt) as tmp:
            torch.save({"identity": self.identity, "net": net.state_dict(), "opt": opt.state_dict(), "step": step},
                       tmp)

    def train(self, d, model, stop, resume):
        """``(state, step)``: the trained network's tensors, or ``None`` when stopped."""
        import torch

        from brdfkit.prior.model import prior_net

        opts, group = self.opts, self.group
        full = model.basis
        prior = prior_net(model.cfg).to(group.device)
        prior.load_state_dict({k: torch.as_tensor(v) for k, v in model.net.state_dict().items()})
        prior.eval().requires_grad_(False)
        net, opt, step = self._start(full, resume)
        ddp = torch.nn.parallel.DistributedDataParallel(net) if group.active else net
        shown, seen = 0.0, 0.0
        while step < opts["steps"] and not stop.requested:
            for pg in opt.param_groups:
                pg["lr"] = opts["lr"] * _lr_factor(step, opts["steps"], opts["lr_end"])
            g = torch.Generator(device=group.device).manual_seed(
                (opts["seed"] * 7_919 + group.rank) * 1_000_003 + step)
            rows = _step_rows(d, prior, model.cfg, opts, g, group.device)
            loss, base = _loss(ddp(rows[0], rows[1], rows[4]), rows, opts["loss"], d.mapping)
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            step += 1
            shown, seen = shown + float(loss.detach()), seen + base
            if step % 250 == 0:
                self.say(f"step {step} of {opts['steps']}: {opts['loss']} loss {shown / 250:.5f} (the basis alone "
                         f"{seen / 250:.5f})")
                shown, seen = 0.0, 0.0
            if group.rank == 0 and (step % opts["checkpoint_every"] == 0 or stop.requested):
                self.save(net, opt, step)
        if step < opts["steps"]:
            return None, step
        return {k: v.detach().cpu().clone() for k, v in net.state_dict().items()}, step


def _loss(pred, rows, kind: str, mapping):
    """``(loss, the basis alone's loss as a number)`` of the predicted corrections
    ``pred (3 B, C)`` for one step's ``rows`` (:func:`_step_rows`)."""
    import torch

    _, _, target, (mapped_basis, w, ref, cos, rho) = rows[:4]
    if kind == "mapped":
        return ((pred - target) ** 2).mean(), float((target ** 2).mean())
    if kind == "relative":
        scale = (target ** 2).mean(1, keepdim=True).clamp_min(1e-12)
        return ((pred - target) ** 2 / scale).mean(), 1.0

    def metric(extra):
        x = mapping.from_mapped((mapped_basis + extra).clamp(max=30), w, ref, floor=0.0)
        return ((torch.log1p(x * cos) - torch.log1p(rho * cos)) ** 2).mean()

    with torch.no_grad():
        base = float(metric(0.0))
    return metric(pred), base


def _step_rows(d, prior, cfg, opts, g, dev):
    """One step's rows, a row a material and channel: the network's inputs ``(3 B, 2 K +
    1)`` (the fitted coefficients in their fold's standard deviations, the mask, the
    count), the query cells' HD vectors ``(3 B, C, 6)``, the basis's mapped error there
    ``(3 B, C)``, and what the metric's loss needs there: the basis's mapped values, the
    weights, references, ``cos_i`` and the true values, each ``(3 B, C)``."""
    import torch

    from brdfkit.prior.fit import context_fit, draw_batch
    from brdfkit.residual.network import COUNT_REF

    bt = draw_batch(d, g, dev, opts["batch"], opts["cells"], opts["context_min"], opts["context_max"], opts["mixup"])
    with torch.no_grad():
        c, _, _ = context_fit(d, prior, cfg, bt)  # (B, 3, K)
        qtab = d.fold_tab[bt.folds[:, None], bt.q_pos]
        ref, mean, comp = qtab[..., 0:1], qtab[..., 1:2], qtab[..., 2:]
        mapped = d.mapping.to_mapped(bt.qrho, d.weight[bt.q_pos][..., None], ref)
        target = mapped - mean - torch.einsum("bqk,blk->bql", comp, c)  # (B, C, 3)
    b, k = c.shape[0], c.shape[-1]
    zc = (c / d.fold_sig[bt.folds][:, None]).reshape(3 * b, k)
    count = torch.full((3 * b, 1), math.log(max(bt.n, 1)) / math.log(COUNT_REF), device=dev)
    z = torch.cat([zc, torch.ones(3 * b, k, device=dev), count], 1)
    hd = d.hd[bt.q_pos].repeat_interleave(3, dim=0)
    rows = lambda a: a.permute(0, 2, 1).reshape(3 * b, -1)  # noqa: E731  (B, C, 3) -> (3 B, C)
    per_cell = lambda a: a.repeat_interleave(3, dim=0)  # noqa: E731  (B, C) -> (3 B, C)
    extra = (rows(mapped - target), per_cell(d.weight[bt.q_pos]), per_cell(ref[..., 0]), per_cell(d.cos[bt.q_pos]),
             rows(bt.qrho))
    return z, hd, rows(target), extra, _sample_rows(d, bt, c, rows) if opts["latent"] else None


def _sample_rows(d, bt, c, rows):
    """A set encoder's input, a row a channel: the samples' directions and what the basis's
    fit ``c (B, 3, K)`` leaves at them in the mapped space, ``(3 B, N, 6)`` and ``(3 B, N)``."""
    import torch

    with torch.no_grad():
        ctab = d.fold_tab[bt.folds[:, None], bt.c_pos]
        resid = (d.mapping.to_mapped(bt.crho, d.weight[bt.c_pos][..., None], ctab[..., 0:1]) - ctab[..., 1:2]
                 - torch.einsum("bsk,blk->bsl", ctab[..., 2:], c))  # (B, N, 3)
    return d.hd[bt.c_pos].repeat_interleave(3, dim=0), rows(resid)
