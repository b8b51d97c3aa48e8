"""Training of the learnt-prior model (``brdfkit fit --method prior``).

The recipe is the one
``benchmarks/studies/study_residual.py --coef --align --prior --mixup 0.5`` ranked first
on the validation split (``docs/notes/generalisation.md``):

- **Basis**: the ``K``-component PCA basis of the training tables (or a given basis
  file, e.g. the one shipped with the package).
- **Held-out fits**: the training materials are dealt into ``folds`` folds; a
  material's samples are fitted with a basis fitted without its fold, so that the
  residuals the network learns from look like those of a material no basis has seen.
  Each fold basis is rotated onto the main basis (orthogonal Procrustes over the cells),
  so that a coefficient means the same in all of them, and stored as the main basis is
  stored (float16, half ``phi_d``) so that it is as coarse as what ships.
- **Batches**: ``batch_materials`` materials a step, each with a context of ``N``
  samples (one ``N`` a step, log-uniform in [``context_min``, ``context_max``], by
  default [40, 4000], cells drawn with the density of uniform Rusinkiewicz angles) and
  ``query_size`` query cells uniform over the grid.
  With probability ``mixup`` a material is mixed with another of its fold, linearly in
  IPCA's mapped space at a uniform ratio.
- **Loss**: the evaluation metric itself, the mean square of
  ``ln(1 + rho_hat cos_i) - ln(1 + rho cos_i)`` at the query cells, plus
  ``lambda_w`` times the mean square of the head's output and ``lambda_z`` that of the
  latent. Adam, cosine decay to a tenth over the budget, gradient norm clipped at 1;
  the saved weights are an exponential moving average (decay ``ema``).
"""

from __future__ import annotations

import dataclasses
import functools
import math
import os
import sys
import time

import numpy as np

from brdfkit.errors import InputError
from brdfkit.basis import DEFAULT_COMPONENTS
from brdfkit.prior.model import PriorConfig, PriorModel, prior_net, solve
from brdfkit.prior.training_data import TrainingTensors, fold_bases, main_basis, to_device, training_cells

__all__ = ["fit_prior", "FIT_OPTIONS", "Batch", "draw_batch", "context_fit"]

FIT_OPTIONS = ("latent_dim", "steps", "minutes", "seed", "device", "batch_materials", "components", "basis",
               "folds", "mixup", "query_size", "lr", "lambda_w", "lambda_z", "ema", "width", "s2", "lam", "weight",
               "spread", "context_min", "context_max")


def _real(v) -> bool:
    """A finite number (``-O`` values arrive parsed as JSON: a word or a bool is no number)."""
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _count(v, least=1) -> bool:
    """An integer (not a bool) of at least ``least``."""
    return isinstance(v, int) and not isinstance(v, bool) and v >= least


def _check_options(*, steps, minutes, folds, mixup, ema, batch_materials, query_size, lr, lambda_w, lambda_z,
                   latent_dim, width, components, s2, lam, weight, spread, context_min, context_max):
    """Raise :class:`InputError` on the first of :func:`fit_prior`'s options out of range."""
    real, count = _real, _count
    for key, value, ok in (("steps", steps, steps is None or count(steps)),
                           ("minutes", minutes, minutes is None or (real(minutes) and minutes > 0)),
                           ("folds", folds, count(folds, 2)),
                           ("mixup", mixup, real(mixup) and 0.0 <= mixup <= 1.0),
                           ("ema", ema, real(ema) and 0.0 <= ema < 1.0),
                           ("batch_materials", batch_materials, count(batch_materials)),
                           ("query_size", query_size, count(query_size)), ("lr", lr, real(lr) and lr > 0),
                           ("lambda_w", lambda_w, real(lambda_w) and lambda_w >= 0),
                           ("lambda_z", lambda_z, real(lambda_z) and lambda_z >= 0),
                           ("latent_dim", latent_dim, count(latent_dim)), ("width", width, count(width)),
                           ("components", components, count(components)),
                           ("s2", s2, real(s2) and s2 > 0), ("lam", lam, real(lam) and lam > 0),
                           ("weight", weight, weight in ("metric", "energy")),
                           ("spread", spread, isinstance(spread, bool)),
                           ("context_min", context_min, count(context_min)),
                           ("context_max", context_max, count(context_max) and count(context_min)
                            and context_max >= context_min)):
        if not ok:
            raise InputError(f"--method prior: option {key} = {value!r} is out of range")


@dataclasses.dataclass(frozen=True)
class _Recipe:
    """The training options of :func:`fit_prior` (its docstring)."""

    steps: int | None
    minutes: float | None
    batch_materials: int
    query_size: int
    context_min: int
    context_max: int
    mixup: float
    lr: float
    lambda_w: float
    lambda_z: float
    ema: float


def _rand(g, dev, *shape, dtype=None):
    """A uniform draw in [0, 1) of the generator ``g`` on ``dev``, of ``shape``, float32
    unless ``dtype`` says otherwise."""
    import torch

    return torch.rand(shape, generator=g, device=dev, dtype=torch.float32 if dtype is None else dtype)


def _mixup(d: TrainingTensors, folds_b, c_pos, q_pos, crho, qrho, mixup, g, dev):
    """Mix, in place, each material's context and query values ``crho``, ``qrho``
    (``(B, N, 3)``, ``(B, Q, 3)`` at cell positions ``c_pos``, ``q_pos``) with another
    material of its fold (``folds_b``, ``(B,)``), with probability ``mixup``, linearly in
    IPCA's mapped space at a uniform ratio."""
    import torch

    members, w_all, values = d.members, d.weight, d.values
    batch_materials = folds_b.shape[0]
    rand = functools.partial(_rand, g, dev)
    partner = torch.stack([members[int(f)][int(torch.randint(0, len(members[int(f)]), (), generator=g,
                                                              device=dev))] for f in folds_b])
    t = torch.where(rand(batch_materials) < mixup, rand(batch_materials),
                    torch.ones(batch_materials, device=dev))[:, None, None]
    for rho, pos in ((crho, c_pos), (qrho, q_pos)):
        w = w_all[pos][..., None]
        other = values[partner[:, None], pos]
        # A blend in the mapped space, where the reference cancels (the fold's, as the
        # mapping's resolution depends on it).
        ref = d.fold_tab[folds_b[:, None], pos][..., 0:1]
        m = d.mapping
        rho.copy_(m.from_mapped(t * m.to_mapped(rho, w, ref) + (1 - t) * m.to_mapped(other, w, ref), w, ref, floor=0.0))


@dataclasses.dataclass
class Batch:
    """One training batch (:func:`draw_batch`): ``B`` materials (their indices ``mats``
    and folds ``folds``), each with ``n`` context samples at cell positions ``c_pos``
    (values ``crho``) and query cells ``q_pos`` (values ``qrho``), mixed already."""

    n: int
    mats: object
    folds: object
    c_pos: object
    q_pos: object
    crho: object
    qrho: object


def draw_batch(d: TrainingTensors, g, dev, batch_materials: int, query_size: int, context_min: int, context_max: int,
               mixup: float) -> Batch:
    """A batch drawn with ``g``: one context size ``N`` log-uniform in ``[context_min,
    context_max]``, the materials, their context cells (uniform Rusinkiewicz angles) and
    query cells (uniform over the cells), mixed with probability ``mixup``
    (:func:`_mixup`)."""
    import torch

    P = d.n_cells
    rand = functools.partial(_rand, g, dev)
    n_ctx = int(round(math.exp(math.log(context_min) + float(rand()) * math.log(context_max / context_min))))
    mats = torch.randint(0, d.n_materials, (batch_materials,), generator=g, device=dev)
    folds_b = d.mat_fold[mats]
    c_pos = torch.searchsorted(d.cdf, rand(batch_materials, n_ctx, dtype=torch.float64)).clamp_(max=P - 1)
    q_pos = torch.randint(0, P, (batch_materials, query_size), generator=g, device=dev)
    crho, qrho = d.values[mats[:, None], c_pos], d.values[mats[:, None], q_pos]
    if mixup > 0:
        _mixup(d, folds_b, c_pos, q_pos, crho, qrho, mixup, g, dev)
    return Batch(n_ctx, mats, folds_b, c_pos, q_pos, crho, qrho)


def context_fit(d: TrainingTensors, net, cfg: PriorConfig, bt: Batch):
    """The coefficients ``(B, 3, K)`` of the batch's contexts, fitted as a reconstruction
    fits them (:meth:`PriorModel.coefficients`: the plain closed form, the network's
    prior, the closed form again), each material with its fold's basis; also the
    network's raw output and latent (what the prior's training penalises)."""
    import torch

    ctab, sig = d.fold_tab[bt.folds[:, None], bt.c_pos], d.fold_sig[bt.folds]
    rows = (ctab, bt.crho, d.weight[bt.c_pos], d.cos[bt.c_pos])
    c, b = solve(*rows, sig, cfg.s2, cfg.lam, weight=cfg.weight, mapping=d.mapping)
    with torch.no_grad():
        resid = b - torch.einsum("bck,blk->bcl", ctab[..., 2:], c)
    mu, sd, z, dc = net(d.hd[bt.c_pos], resid, c, sig, bt.n)
    c, _ = solve(*rows, sd, cfg.s2, cfg.lam, mu=mu, weight=cfg.weight, mapping=d.mapping)
    return c, dc, z


def _batch_loss(d: TrainingTensors, net, cfg: PriorConfig, recipe: _Recipe, g, dev):
    """One batch drawn with ``g`` (:func:`draw_batch`) and its losses: ``(loss, reg)``,
    the metric's mean square at the query cells after the two closed-form fits (the
    basis's prior, then the network's), and the penalty on the head's output and the
    latent."""
    import torch

    bt = draw_batch(d, g, dev, recipe.batch_materials, recipe.query_size, recipe.context_min, recipe.context_max,
                    recipe.mixup)
    c, dc, z = context_fit(d, net, cfg, bt)
    q_pos, qrho, w_all, cos_all = bt.q_pos, bt.qrho, d.weight, d.cos
    qtab = d.fold_tab[bt.folds[:, None], q_pos]
    ref, mean, comp = qtab[..., 0:1], qtab[..., 1:2], qtab[..., 2:]
    mapped = mean + torch.einsum("bqk,blk->bql", comp, c)
    x = d.mapping.from_mapped(mapped.clamp(max=30), w_all[q_pos][..., None], ref, floor=0.0)
    qc = cos_all[q_pos][..., None]
    loss = ((torch.log1p(x * qc) - torch.log1p(qrho * qc)) ** 2).mean()
    reg = recipe.lambda_w * (dc ** 2).mean() + recipe.lambda_z * (z ** 2).mean()
    return loss, reg


def _steps_for_minutes(recipe: _Recipe, net, opt, avg, g, probe, t_train, say):
    """``recipe.minutes`` as a step count (:func:`brdfkit.hypernet.training.budget.steps_for_budget`:
    steps timed on the network, its optimiser, average and generator, then restored)."""
    import copy

    from brdfkit.hypernet.training.budget import steps_for_budget

    def save():
        return (copy.deepcopy(net.state_dict()), copy.deepcopy(opt.state_dict()), copy.deepcopy(avg.state_dict()),
                g.get_state())

    def restore(state):
        net.load_state_dict(state[0])
        opt.load_state_dict(state[1])
        avg.load_state_dict(state[2])
        g.set_state(state[3])

    left = recipe.minutes * 60 - (time.monotonic() - t_train)
    steps, record = steps_for_budget(left, probe, save, restore, most=recipe.steps)
    say(f"--minutes: {steps:,} steps ({record['seconds_per_step']:.3g} s a step); `--steps {steps}` replays this run")
    return steps, record


def _train(d: TrainingTensors, cfg: PriorConfig, recipe: _Recipe, seed, dev, say):
    """Adam on the network of ``cfg`` until ``recipe.steps`` or ``recipe.minutes``, the
    learning rate decayed on a cosine to a tenth. Returns ``(averaged, steps, losses)``:
    the exponential moving average of the weights, the steps taken and their losses."""
    import torch

    net = prior_net(cfg).to(dev)
    opt = torch.optim.Adam(net.parameters(), lr=recipe.lr)
    avg = torch.optim.swa_utils.AveragedModel(net, multi_avg_fn=torch.optim.swa_utils.get_ema_multi_avg_fn(recipe.ema))
    g = torch.Generator(device=dev).manual_seed(seed)
    say(f"training on {d.n_materials} materials, {d.n_cells:,} cells, device {dev}")
    t_train, step, losses, last_say = time.monotonic(), 0, [], time.monotonic()
    steps, lr = recipe.steps, recipe.lr

    def one_step(step):
        loss, reg = _batch_loss(d, net, cfg, recipe, g, dev)
        opt.zero_grad()
        (loss + reg).backward()
        torch.nn.utils.clip_grad_norm_(net.parameters(), 1.0)
        for grp in opt.param_groups:
            grp["lr"] = lr * (0.1 + 0.9 * 0.5 * (1 + math.cos(math.pi * (min(step / steps, 1.0) if steps else 0.0))))
        opt.step()
        avg.update_parameters(net)
        return float(loss.detach())

    budget_record = None
    if recipe.minutes is not None:  # a step count chosen once: --steps replays the run
        steps, budget_record = _steps_for_minutes(recipe, net, opt, avg, g, lambda: one_step(0), t_train, say)
    while step < steps:
        losses.append(one_step(step))
        step += 1
        if time.monotonic() - last_say > 30:
            last_say = time.monotonic()
            say(f"step {step}, {step / (last_say - t_train):.1f} steps/s, loss {np.mean(losses[-200:]):.5f}")
    if not losses or not np.isfinite(losses[-1]):
        raise InputError("training gave no finite loss")
    return avg, step, losses, budget_record


def fit_prior(data, output, *, exclude=(), progress: bool = True, latent_dim: int = 40, steps: int | None = None,
              minutes: float | None = None, seed: int = 0, device=None, batch_materials: int = 8,
              components: int = DEFAULT_COMPONENTS, basis: str | None = None, folds: int = 5, mixup: float = 0.5,
              query_size: int = 4096, lr: float = 1e-3, lambda_w: float = 1e-3, lambda_z: float = 1e-3,
              ema: float = 0.999, width: int = 128, s2: float = PriorConfig.s2, lam: float = PriorConfig.lam,
              weight: str = PriorConfig.weight, spread: bool = PriorConfig.spread, context_min: int = 40,
              context_max: int = 4000) -> str:
    """Train a learnt-prior model on MERL tables and save it to ``output``.

    Parameters
    ----------
    data
        ``.binary`` files or folders of them (:func:`brdfkit.io.folders.collect_materials`).
    exclude
        Material names held out.
    steps, minutes
        Stop at this many steps or after this many minutes of training, whichever first
        (neither: 3000 steps).
    basis
        A PCA basis file (``brdfkit fit --method basis``), or a built-in model's name
        (its basis); ``None``: fit one with ``components`` components to the data.
    folds, mixup, batch_materials, query_size, lr, lambda_w, lambda_z, ema
        The recipe of the module docstring.
    latent_dim, width
        The set encoder's sizes (:class:`PriorConfig`).
    s2, lam, weight
        The closed-form fit's likelihood (:class:`PriorConfig`), in training and in the
        saved model.
    spread
        Whether the network also predicts the prior's spread (:class:`PriorConfig`).
    context_min, context_max
        The range of the training contexts' sample counts (log-uniform).

    Returns
    -------
    str
        ``output``.
    """
    import torch

    from brdfkit.atomic import refuse_overwrite_of_inputs
    from brdfkit.runtime import resolve_device
    from brdfkit.io.folders import collect_materials
    from brdfkit.prior.prior_file import save_prior

    if steps is None and minutes is None:
        steps = 3000
    _check_options(steps=steps, minutes=minutes, folds=folds, mixup=mixup, ema=ema, batch_materials=batch_materials,
                   query_size=query_size, lr=lr, lambda_w=lambda_w, lambda_z=lambda_z, latent_dim=latent_dim,
                   width=width, components=components, s2=s2, lam=lam, weight=weight, spread=spread,
                   context_min=context_min, context_max=context_max)
    t0 = time.monotonic()
    say = (lambda msg: print(f"brdfkit: {msg}", file=sys.stderr, flush=True)) if progress else (lambda msg: None)
    paths, names, _, unknown = collect_materials(data, exclude)
    refuse_overwrite_of_inputs(output, paths + ([basis] if basis and os.path.exists(basis) else []))
    if unknown:
        say(f"warning: excluded name(s) matched no input: {', '.join(unknown)}")
    if len(paths) < 2 * folds:
        raise InputError(f"--method prior needs at least {2 * folds} training materials ({folds} folds of two), "
                         f"got {len(paths)}")
    dev = resolve_device(device)
    torch.manual_seed(seed)

    full, storage, components = main_basis(basis, components, paths, names, say)
    cells, values = training_cells(paths, full)
    fold_of = np.arange(len(paths)) % folds
    tabs, sigmas = fold_bases(paths, fold_of, folds, full, cells, components, storage, say)
    d = to_device(values, cells, full, fold_of, folds, tabs, sigmas, dev)
    del values, tabs, sigmas

    cfg = PriorConfig(n_components=components, latent_dim=latent_dim, width=width, s2=float(s2), lam=float(lam),
                      weight=weight, spread=spread)
    recipe = _Recipe(steps=steps, minutes=minutes, batch_materials=batch_materials, query_size=query_size,
                     context_min=context_min, context_max=context_max, mixup=mixup, lr=lr, lambda_w=lambda_w,
                     lambda_z=lambda_z, ema=ema)
    avg, step, losses, budget_record = _train(d, cfg, recipe, seed, dev, say)
    final = prior_net(cfg)
    final.load_state_dict({k: v.detach().cpu() for k, v in avg.module.state_dict().items()})
    final.eval()
    wall = time.monotonic() - t0
    meta = {"materials": names, "steps": step, "wall_time_s": round(wall, 1), "seed": seed,
            "training": {"folds": folds, "mixup": mixup, "batch_materials": batch_materials, "query_size": query_size,
                         "lr": lr, "lambda_w": lambda_w, "lambda_z": lambda_z, "ema": ema,
                         "context": [context_min, context_max],
                         "basis": os.path.basename(str(basis)) if basis else None}}
    if budget_record is not None:  # how --minutes chose "steps"
        meta["budget"] = budget_record
    save_prior(output, PriorModel(full, final, cfg, meta), **storage)
    say(f"wrote learnt-prior model ({step} steps, {wall / 60:.1f} min, loss {np.mean(losses[-200:]):.5f}) "
        f"to {output}")
    return output
