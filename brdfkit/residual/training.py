"""Training a basis residual (``brdfkit fit --method residual``).

The training pairs are the training tables' channels, each a separate observation: its
least-squares coefficients on the basis's ``k_max`` leading components (in training
standard deviations) and its mapped table less the basis's mean, at every basis cell
(float16). Each row of a step draws its size ``K`` in ``k_min .. k_max``; its target is the
residual of its ``K`` leading components at ``cells`` cells drawn uniformly, and the loss
the mean square of the mapped error (the basis's own objective). With probability
``mixup`` a row is blended with another in the mapped space, where a blend of two
materials has exactly the blend of their coefficients and residuals (NeuMaDiff's blends).

One network is trained for each size of ``sizes`` (its ``K`` always), in turn: the
shipped way, measured against one network for every size (``shared``: each row draws
``K`` in ``k_min .. k_max``), which lost 1.3 to 1.6 dB at equal steps
(``docs/notes/compression.md``). The file holds them all.

A budget in steps (a network), seeded; a checkpoint every ``checkpoint_every`` steps
(``OUTPUT.ckpt``, ``--resume`` continues it to the bit); under ``torchrun`` each process
draws its own rows and the gradients are averaged (PyTorch DDP), so ``world`` processes
take steps of ``world x batch`` rows.
"""

from __future__ import annotations

import json
import os
import time

import numpy as np

from brdfkit.errors import InputError

__all__ = ["TRAIN_DEFAULTS", "fit_residual", "write_finished", "training_pairs"]

TRAIN_DEFAULTS = {"steps": 8000, "batch": 24, "cells": 4096, "lr": 1e-3, "lr_end": 1.0, "mixup": 0.5,
                  "sizes": "9,21,39", "shared": False, "k_min": 1, "k_max": 13, "width": 32, "hidden": 64,
                  "codes_lr": 0.0, "render_weight": 0.0, "members": 1, "seed": 0, "checkpoint_every": 1000,
                  "storage": "float32"}
"""The options of :func:`fit_residual` and their defaults (``-O KEY=VALUE``)."""


def training_pairs(basis, paths, k_max: int, say=lambda m: None, pools: bool = False, seed: int = 0):
    """``(z, mapped, pools)``: coefficients in training standard deviations ``(3 M, k_max)``
    float32, mapped tables less the mean ``(3 M, P)`` float16, a row per channel, NaN where
    the table is unmeasured (such cells are left out of the loss: the network learns what
    was measured, not to cancel the basis at a table's holes), and with ``pools`` each row's
    cells drawn in proportion to its render weights (int32 ``(3 M, POOL)``,
    :mod:`brdfkit.residual.render_weights`; else ``None``)."""
    from brdfkit.io.merl import read_merl

    part = basis.leading(k_max)
    sigma = part.sigma.astype(np.float64)
    zs, rows, drawn = [], [], []
    if pools:
        from brdfkit.residual.render_weights import cell_pool, render_weights, scene_maps

        maps = scene_maps(basis)
    for i, p in enumerate(paths):
        table = read_merl(p)
        mapped = part.mapped_table(table) - part.mean[:, None]
        zs.append((part.project(table) / sigma[:, None]).T)
        rows.append(mapped.T.astype(np.float16))
        if pools:
            g = render_weights(basis, table, maps)
            drawn.extend(cell_pool(g[:, ch], seed=(seed * 1_000_003 + i) * 3 + ch) for ch in range(3))
        if (i + 1) % 20 == 0:
            say(f"read {i + 1} of {len(paths)} tables")
    return np.concatenate(zs).astype(np.float32), np.concatenate(rows), (np.stack(drawn) if pools else None)


_NEUTRAL = ("lr_end", "codes_lr", "render_weight", "members")
"""Options that, at their defaults, train exactly as before they existed: left out of a
checkpoint's identity there, so that a checkpoint written before them still resumes."""


def _identity(names, basis_digest, opts) -> str:
    keep = {k: v for k, v in opts.items() if k not in ("checkpoint_every", "storage")
            and not (k in _NEUTRAL and v == TRAIN_DEFAULTS[k])}
    return json.dumps({"materials": names, "basis": basis_digest, "options": keep}, sort_keys=True)


def plan(opts: dict) -> list:
    """The ``(k_min, k_max, member)`` of each network to train, in order: ``members``
    networks a size (each its own initialisation and draws)."""
    if opts["shared"]:
        return [(opts["k_min"], opts["k_max"], m) for m in range(opts["members"])]
    return [(s // 3, s // 3, m) for s in _sizes(opts["sizes"]) for m in range(opts["members"])]


def _sizes(text) -> list:
    try:
        sizes = sorted({int(s) for s in str(text).replace(" ", "").split(",") if s})
    except ValueError:
        sizes = []
    if not sizes or any(s < 3 or s % 3 for s in sizes):
        raise InputError(f"-O sizes={text}: a comma-separated list of sizes, each 3 numbers a component (9,21,39)")
    return sizes


def _step_batch(g, zt, mapped, comp, sigma, opts, torch, k_min, k_max, pools=None):
    """One step's rows: inputs ``(B, 2 k_max)`` (differentiable in ``zt``, the coefficients
    ``(3 M, >= k_max)`` in standard deviations), cell indices ``(B, C)``, targets ``(B, C)``
    and whether each target was measured (``None``: all were). With ``pools``, a share
    ``render_weight`` of each row's cells comes from its pool (in proportion to its render
    weights), the rest uniform."""
    n, p, b = zt.shape[0], mapped.shape[1], opts["batch"]
    rows = torch.randint(n, (b,), generator=g)
    cells = torch.randint(p, (b, opts["cells"]), generator=g)
    if pools is not None:
        pick = torch.rand(b, opts["cells"], generator=g) < opts["render_weight"]
        at = torch.randint(pools.shape[1], (b, opts["cells"]), generator=g)
        cells = torch.where(pick, torch.as_tensor(pools[rows.numpy()[:, None], at.numpy()]).long(), cells)
    zt = zt[:, :k_max]
    zb = zt[rows]
    tb = torch.as_tensor(mapped[rows.numpy()[:, None], cells.numpy()], dtype=torch.float32)
    other = torch.randint(n, (b,), generator=g)
    t = torch.rand(b, generator=g) * (torch.rand(b, generator=g) < opts["mixup"])
    zb = (1 - t[:, None]) * zb + t[:, None] * zt[other]
    to = torch.as_tensor(mapped[other.numpy()[:, None], cells.numpy()], dtype=torch.float32)
    tb = torch.where(t[:, None] > 0, (1 - t[:, None]) * tb + t[:, None] * to, tb)
    ks = torch.randint(k_min, k_max + 1, (b,), generator=g)
    mask = (torch.arange(k_max)[None, :] < ks[:, None]).float()
    zb = zb * mask
    measured = torch.isfinite(tb)
    measured = None if bool(measured.all()) else measured
    if measured is not None:
        tb = torch.nan_to_num(tb)
    tb = tb - torch.einsum("bk,kbc->bc", zb * sigma[:k_max], comp[:k_max][:, cells])
    return torch.cat([zb, mask], dim=1), cells, tb, measured


def _loss(pred, target, measured):
    """Mean square over the measured targets (all of them when ``measured`` is ``None``)."""
    err = (pred - target) ** 2
    if measured is None:
        return err.mean()
    return (err * measured).sum() / measured.sum().clamp_min(1)


def _lr_factor(step: int, steps: int, end: float) -> float:
    """The learning rate's factor at ``step``: a cosine from 1 to ``end`` over ``steps``
    (``end`` 1: constant)."""
    import math

    return end + (1.0 - end) * 0.5 * (1.0 + math.cos(math.pi * min(step, steps) / steps))


def fit_residual(data, output, *, basis=None, exclude=(), progress: bool = True, resume: bool = False,
                 device=None, **options) -> str:
    """Train a residual of ``basis`` on the MERL tables ``data`` and write it to ``output``.

    Parameters
    ----------
    data
        ``.binary`` files or folders of them (:func:`brdfkit.io.folders.collect_materials`).
    basis
        The basis file (or a built-in's name) it corrects; required.
    options
        :data:`TRAIN_DEFAULTS`'s keys: ``steps`` (a network), ``batch`` (rows a process
        and step), ``cells`` (cells a row), ``lr`` (Adam), ``mixup``, ``sizes`` (a network
        each), or ``shared`` with ``k_min``/``k_max`` (one network for those component
        counts), ``width``/``hidden`` (the networks), ``seed``, ``checkpoint_every``,
        ``storage`` (:data:`brdfkit.residual.residual_file.STORAGES`).

    Returns
    -------
    str
        ``output``.
    """
    import torch

    from brdfkit.atomic import refuse_overwrite_of_inputs
    from brdfkit.distributed import ProcessGroup, StopSignals
    from brdfkit.io.folders import collect_materials
    from brdfkit.residual.network import ResidualConfig, ResidualNet

    opts = _options(options)
    if basis is None:
        raise InputError("fit --method residual needs -O basis=BASIS (a basis file or a built-in's name)")
    from brdfkit.basis.basis_file import load_basis
    from brdfkit.io.digest import file_digest
    from brdfkit.models.builtin import resolve_basis

    bpath = resolve_basis(basis)
    pca = load_basis(bpath)
    nets_plan = plan(opts)
    k_top = max(k for _, k, _ in nets_plan)
    if k_top > pca.n_components:
        raise InputError(f"a network of {k_top} components: the basis has {pca.n_components}")
    paths, names, _, _ = collect_materials(data, exclude)
    refuse_overwrite_of_inputs(output, [*paths, bpath])
    group = ProcessGroup(device)
    say = (lambda m: print(f"fit residual: {m}", flush=True)) if progress and group.rank == 0 else (lambda m: None)
    t0 = time.monotonic()
    z, mapped, pools = training_pairs(pca, paths, k_top, say, pools=opts["render_weight"] > 0, seed=opts["seed"])
    say(f"{len(paths)} tables, {mapped.shape[1]:,} cells, {z.shape[0]} channels in {time.monotonic() - t0:.0f} s")
    part = pca.leading(k_top)
    data_t = (z, mapped, torch.as_tensor(part.components), torch.as_tensor(part.sigma), _cell_hd(part), pools)
    run = _Run(os.fspath(output) + ".ckpt", _identity(names, file_digest(bpath), opts), opts, group, say)
    done = run.resume() if resume else []
    with StopSignals() as stop:
        for i in range(len(done), len(nets_plan)):
            k_min, k_max, member = nets_plan[i]
            state = run.train(i, ResidualConfig(k_min, k_max, opts["width"], opts["hidden"], member), data_t, stop,
                              done)
            if state is None:
                say(f"stopped; --resume continues from {run.ckpt}")
                group.close()
                return os.fspath(output)
            done.append(state)
    digests = group.gather_hex(_states_digest(done))
    if len(set(digests)) != 1:
        from brdfkit.errors import TrainingError

        raise TrainingError(f"the processes ended with different weights ({', '.join(d[:12] for d in digests)})")
    if group.rank == 0:
        cfgs = [ResidualConfig(lo, hi, opts["width"], opts["hidden"], m) for lo, hi, m in nets_plan]
        _write(output, list(zip(cfgs, done)), bpath, opts, names, group.world, digests)
        say(f"wrote {output}: {len(done)} network(s), {time.monotonic() - t0:.0f} s")
    group.barrier()
    group.close()
    return os.fspath(output)


def write_finished(data, output, *, basis=None, exclude=(), **options) -> int:
    """Write the networks that the checkpoint ``output.ckpt`` of a cut training holds
    finished, as a residual file ``output``: what :func:`fit_residual` would have written of
    them (the networks are trained in turn, each from its own seed), the checkpoint kept so
    that ``--resume`` still finishes the rest. The same arguments as the training's.

    Returns
    -------
    int
        The networks written (a size with fewer members than planned decodes with those).

    Raises
    ------
    InputError
        No checkpoint, one of other tables, basis or options, or no network finished.
    """
    from brdfkit.atomic import refuse_overwrite_of_inputs
    from brdfkit.io.digest import file_digest
    from brdfkit.io.folders import collect_materials
    from brdfkit.models.builtin import resolve_basis
    from brdfkit.residual.network import ResidualConfig

    opts = _options(options)
    if basis is None:
        raise InputError("the residual's basis is needed: basis=BASIS (a basis file or a built-in's name)")
    bpath = resolve_basis(basis)
    paths, names, _, _ = collect_materials(data, exclude)
    refuse_overwrite_of_inputs(output, [*paths, bpath])
    run = _Run(os.fspath(output) + ".ckpt", _identity(names, file_digest(bpath), opts), opts, None, lambda m: None)
    done = run.resume()
    if not done:
        raise InputError(f"{run.ckpt}: no network finished yet")
    cfgs = [ResidualConfig(lo, hi, opts["width"], opts["hidden"], m) for lo, hi, m in plan(opts)[:len(done)]]
    meta_opts = {**opts, "networks_finished": f"{len(done)} of {len(plan(opts))}"}
    _write(output, list(zip(cfgs, done)), bpath, meta_opts, names, 1, [_states_digest(done)])
    return len(done)


def _options(given: dict) -> dict:
    unknown = sorted(set(given) - set(TRAIN_DEFAULTS) - {"minutes"})
    if unknown or given.get("minutes") is not None:
        raise InputError(f"fit --method residual takes -O {', '.join(sorted(TRAIN_DEFAULTS))} and --steps (a budget "
                         f"in steps), not {', '.join(unknown) or '--minutes'}")
    opts = dict(TRAIN_DEFAULTS)
    for k, v in given.items():
        if v is not None:
            try:
                opts[k] = type(TRAIN_DEFAULTS[k])(v) if not isinstance(TRAIN_DEFAULTS[k], bool) else \
                    str(v).lower() in ("1", "true", "yes")
            except (TypeError, ValueError):
                raise InputError(f"-O {k}={v!r}: expected a {type(TRAIN_DEFAULTS[k]).__name__}") from None
    for k in ("steps", "batch", "cells", "k_min", "k_max", "width", "hidden", "checkpoint_every", "members"):
        if opts[k] < 1:
            raise InputError(f"-O {k}={opts[k]}: must be at least 1")
    if not (opts["lr"] > 0 and 0 <= opts["mixup"] <= 1 and opts["k_min"] <= opts["k_max"]
            and 0 <= opts["render_weight"] <= 1 and 0 < opts["lr_end"] <= 1 and opts["codes_lr"] >= 0):
        raise InputError("residual options: lr > 0, 0 <= mixup <= 1, k_min <= k_max, 0 <= render_weight <= 1, "
                         "0 < lr_end <= 1 and codes_lr >= 0")
    from brdfkit.residual.residual_file import STORAGES

    if opts["storage"] not in STORAGES:
        raise InputError(f"-O storage={opts['storage']}: one of {', '.join(STORAGES)}")
    _sizes(opts["sizes"])
    return opts


def _cell_hd(part):
    import torch

    from brdfkit.geometry import grid_hd

    return torch.as_tensor(np.ascontiguousarray(grid_hd()[part.cells]))


class _Run:
    """The networks' training: checkpoints (``ckpt``, checked by ``identity``), the DDP
    group, the log."""

    def __init__(self, ckpt, identity, opts, group, say):
        self.ckpt, self.identity, self.opts, self.group, self.say = ckpt, identity, opts, group, say
        self.saved = None  # the checkpoint being resumed from, until its network is rebuilt

    def resume(self) -> list:
        """The finished networks' states of the checkpoint; its current network continues."""
        import torch

        if not os.path.isfile(self.ckpt):
            raise InputError(f"--resume: no checkpoint {self.ckpt}")
        state = torch.load(self.ckpt, weights_only=True)
        if state.get("identity") != self.identity:
            raise InputError(f"--resume: {self.ckpt} was made from other tables, basis or options")
        self.saved = state
        self.say(f"resumed at network {state['index'] + 1}, step {state['step']}")
        return list(state["done"])

    def save(self, index, net, opt, step, done, codes=None) -> None:
        import torch

        from brdfkit.atomic import atomic_path

        state = {"identity": self.identity, "index": index, "done": done, "net": net.state_dict(),
                 "opt": opt.state_dict(), "step": step}
        if codes is not None:
            state["codes"], state["codes_opt"] = codes.detach().clone(), codes.opt.state_dict()
        with atomic_path(self.ckpt) as tmp:
            torch.save(state, tmp)

    def train(self, index, cfg, data_t, stop, done):
        """Network ``index`` trained to ``steps``; its state, or ``None`` when stopped."""
        import torch

        from brdfkit.residual.network import ResidualNet

        opts, group = self.opts, self.group
        torch.manual_seed(opts["seed"] * 1_009 + index)
        net = ResidualNet(cfg).to(group.device)
        opt = torch.optim.Adam(net.parameters(), lr=opts["lr"])
        codes = _codes(data_t[0].shape[0], cfg.k_max, opts["codes_lr"]) if opts["codes_lr"] > 0 else None
        step = 0
        if self.saved is not None and self.saved["index"] == index:
            net.load_state_dict(self.saved["net"])
            opt.load_state_dict(self.saved["opt"])
            if codes is not None:
                with torch.no_grad():
                    codes.copy_(self.saved["codes"])
                codes.opt.load_state_dict(self.saved["codes_opt"])
            step, self.saved = int(self.saved["step"]), None
        model = torch.nn.parallel.DistributedDataParallel(net) if group.active else net
        step = self._loop(index, cfg, (model, net, opt, codes), data_t, step, stop, done)
        if step < opts["steps"]:
            return None
        return {k: v.detach().cpu().clone() for k, v in net.state_dict().items()}

    def _loop(self, index, cfg, nets, data_t, step, stop, done) -> int:
        import torch

        (model, net, opt, codes), (opts, group) = nets, (self.opts, self.group)
        z, mapped, comp, sigma, hd, pools = data_t
        zt = torch.as_tensor(z)
        shown, seen = 0.0, 0.0
        while step < opts["steps"] and not stop.requested:
            for o, lr in ((opt, opts["lr"]), *(((codes.opt, opts["codes_lr"]),) if codes is not None else ())):
                for pg in o.param_groups:
                    pg["lr"] = lr * _lr_factor(step, opts["steps"], opts["lr_end"])
            # Each (seed, network, rank, step) draws its own rows: a resumed run draws what
            # it would have.
            g = torch.Generator().manual_seed(((opts["seed"] * 101 + index) * 7_919 + group.rank) * 1_000_003 + step)
            zb, cells, tb, measured = _step_batch(g, zt if codes is None else zt[:, :cfg.k_max] + codes, mapped,
                                                  comp, sigma, opts, torch, cfg.k_min, cfg.k_max, pools)
            dev = group.device
            measured = None if measured is None else measured.to(dev)
            loss = _loss(model(zb.to(dev), hd[cells].to(dev)), tb.to(dev), measured)
            opt.zero_grad(set_to_none=True)
            if codes is not None:
                codes.opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            if codes is not None:
                if group.active:  # every rank moves every code alike: the gradients averaged
                    group.sum_(codes.grad).div_(group.world)
                codes.opt.step()
            step += 1
            shown, seen = shown + float(loss.detach()), seen + float(_loss(tb.detach(), 0.0, measured))
            if step % 500 == 0:
                self.say(f"network {index + 1} (K {cfg.k_min}-{cfg.k_max}) step {step} of {opts['steps']}: mapped "
                         f"MSE {shown / 500:.5f} (the basis alone {seen / 500:.5f})")
                shown, seen = 0.0, 0.0
            if group.rank == 0 and (step % opts["checkpoint_every"] == 0 or stop.requested):
                self.save(index, net, opt, step, done, codes)
        return step


def _codes(rows: int, k: int, lr: float):
    """Learnt offsets of the training channels' coefficients (standard deviations) ``(rows, k)``,
    zero at the start, with their own Adam (``.opt``): the coefficients become a code the
    network and the basis decode together, as ``encode``'s fit through the correction makes
    them (an auto-decoder; Park et al. 2019, DeepSDF)."""
    import torch

    codes = torch.zeros(rows, k, requires_grad=True)
    codes.opt = torch.optim.Adam([codes], lr=lr)
    return codes


def _states_digest(states: list) -> str:
    """SHA-256 of the networks' weights (names sorted, float32 bytes): the ranks must agree."""
    import hashlib

    h = hashlib.sha256()
    for i, state in enumerate(states):
        for name, t in sorted(state.items()):
            h.update(f"{i}.{name}".encode())
            h.update(t.detach().cpu().float().contiguous().numpy().tobytes())
    return h.hexdigest()


def _write(output, nets, bpath, opts, names, world, digests) -> None:
    from brdfkit.io.digest import file_digest
    from brdfkit.residual.residual_file import save_residual

    meta = {"materials": names, "steps": opts["steps"], "seed": opts["seed"], "options": opts, "world_size": world,
            "rank_digests": digests}  # no clock in the file: its digest names it in embeddings
    save_residual(output, nets, basis_digest=file_digest(bpath), basis_file=os.path.basename(bpath), meta=meta,
                  storage=opts["storage"])
