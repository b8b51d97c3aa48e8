"""Training of the learnt-prior model (``brdfkit fit --method prior``).

The recipe is the one
``benchmarks/studies/study_residual.py --coef --align --prior --mixup 0.5`` ranked first
on the validation split (``docs/generalisation.md``):

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

import math
import os
import sys
import tempfile
import time

import numpy as np

from brdfkit.errors import InputError
from brdfkit.geometry import N_CELLS, N_PHI_D, N_THETA_D
from brdfkit.methods.ipca import DEFAULT_COMPONENTS, EPS, IpcaModel, fit_ipca, load_ipca, save_ipca, storage_of
from brdfkit.methods.prior.model import PriorConfig, PriorModel, prior_net, solve

__all__ = ["fit_prior", "FIT_OPTIONS"]

FIT_OPTIONS = ("latent_dim", "steps", "minutes", "seed", "device", "batch_materials", "components", "basis",
               "folds", "mixup", "query_size", "lr", "lambda_w", "lambda_z", "ema", "width", "s2", "lam", "weight",
               "spread", "context_min", "context_max")


def _storage(path: str) -> dict:
    from brdfkit.io.tensorfile import open_safetensors

    with open_safetensors(path) as f:
        meta = f.metadata() or {}
    return storage_of(meta)


def _as_stored(basis: IpcaModel, storage: dict) -> IpcaModel:
    """The basis as a file with ``storage`` gives it back."""
    if not storage["half"] and storage["phi_stride"] == 1 and not storage.get("int8"):
        return basis
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "basis.safetensors")
        save_ipca(path, basis, **storage)
        return load_ipca(path)


def _resolve_basis(spec) -> str:
    from brdfkit.models.builtin import resolve_basis

    return resolve_basis(spec)


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
        A PCA basis file (``brdfkit fit --method ipca``), or a built-in model's name
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
    from brdfkit.io.merl import read_merl
    from brdfkit.methods.prior.prior_file import save_prior

    if steps is None and minutes is None:
        steps = 3000

    def real(v):  # -O values arrive parsed as JSON: a word or a bool is no number
        return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)

    def count(v, least=1):
        return isinstance(v, int) and not isinstance(v, bool) and v >= least

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

    if basis is not None:
        bpath = _resolve_basis(basis)
        storage = _storage(bpath)
        full = load_ipca(bpath)
        components = full.n_components
    else:
        storage = {"half": False, "phi_stride": 1, "int8": False}
        say(f"fitting the {components}-component basis to {len(paths)} materials")
        full = fit_ipca(paths, components, names=names)  # Nielsen's mapping (w_floor 0): give -O basis= for another
    # Training cells: measured in every training table and covered by the basis.
    covered = np.zeros(N_CELLS, bool)
    covered[full.cells] = True
    tables = []
    for p in paths:
        t = read_merl(p).reshape(N_CELLS, 3)
        covered &= np.isfinite(t).all(1)
        tables.append(t.astype(np.float32))
    cells = np.flatnonzero(covered)
    if cells.size == 0:
        raise InputError("no cell is measured in every training table and covered by the basis")
    values = torch.from_numpy(np.stack([np.clip(t[cells], 0, None) for t in tables]))  # (M, P, 3)
    del tables
    P, K = cells.size, components

    fold_of = np.arange(len(paths)) % folds
    full_comp = full._table()[cells][:, 2:].astype(np.float64)
    tabs, sigmas = [], []
    for f in range(folds):
        say(f"fitting the basis of fold {f + 1} of {folds}")
        keep = [p for p, fo in zip(paths, fold_of) if fo != f]
        fb = _as_stored(fit_ipca(keep, K, w_floor=full.w_floor), storage)
        tab = fb._table()[cells].astype(np.float64)
        if not np.isfinite(tab).all():
            tab = np.nan_to_num(tab)  # a cell only the held-out fold measured: the reference
        # Procrustes: one meaning per coefficient in every fold basis.
        u, _, vt = np.linalg.svd(tab[:, 2:].T @ full_comp)
        r = u @ vt
        tabs.append(np.concatenate([tab[:, :2], tab[:, 2:] @ r], 1).astype(np.float32))
        sigmas.append(np.sqrt(np.einsum("ij,i,ij->j", r, fb.sigma.astype(np.float64) ** 2, r)).astype(np.float32))
    fold_tab = torch.from_numpy(np.stack(tabs)).to(dev)
    fold_sig = torch.from_numpy(np.stack(sigmas)).to(dev)
    del tabs
    from brdfkit.geometry import cos_theta_i, grid_angles, grid_hd
    values = values.to(dev)
    hd_all = torch.from_numpy(np.ascontiguousarray(grid_hd()[cells], np.float32)).to(dev)
    w_all = torch.from_numpy(np.clip(full.cell_weight(cells), 1e-6, None).astype(np.float32)).to(dev)
    th, td, pd = np.meshgrid(*grid_angles(), indexing="ij")
    cos_all = torch.from_numpy(np.clip(cos_theta_i(th, td, pd).reshape(N_CELLS)[cells], 0, None)
                               .astype(np.float32)).to(dev)
    # Cells weighted by the solid angle a uniform draw over the angles gives each theta_h row.
    row = torch.from_numpy(cells // (N_THETA_D * N_PHI_D)).double()
    cdf = torch.cumsum(2 * row + 1, 0)
    cdf = (cdf / cdf[-1]).to(dev)
    mat_fold = torch.from_numpy(fold_of).to(dev)
    members = [torch.from_numpy(np.flatnonzero(fold_of == f)).to(dev) for f in range(folds)]

    cfg = PriorConfig(n_components=K, latent_dim=latent_dim, width=width, s2=float(s2), lam=float(lam),
                      weight=weight, spread=spread)
    net = prior_net(cfg).to(dev)
    opt = torch.optim.Adam(net.parameters(), lr=lr)
    avg = torch.optim.swa_utils.AveragedModel(net, multi_avg_fn=torch.optim.swa_utils.get_ema_multi_avg_fn(ema))
    g = torch.Generator(device=dev).manual_seed(seed)
    say(f"training on {len(paths)} materials, {P:,} cells, device {dev}")
    t_train, step, losses, last_say = time.monotonic(), 0, [], time.monotonic()
    budget = None if minutes is None else minutes * 60

    def rand(*shape, dtype=torch.float32):
        return torch.rand(shape, generator=g, device=dev, dtype=dtype)

    while (steps is None or step < steps) and (budget is None or time.monotonic() - t_train < budget):
        n_ctx = int(round(math.exp(math.log(context_min) + float(rand()) * math.log(context_max / context_min))))
        mats = torch.randint(0, len(paths), (batch_materials,), generator=g, device=dev)
        folds_b = mat_fold[mats]
        c_pos = torch.searchsorted(cdf, rand(batch_materials, n_ctx, dtype=torch.float64)).clamp_(max=P - 1)
        q_pos = torch.randint(0, P, (batch_materials, query_size), generator=g, device=dev)
        crho, qrho = values[mats[:, None], c_pos], values[mats[:, None], q_pos]
        if mixup > 0:
            partner = torch.stack([members[int(f)][int(torch.randint(0, len(members[int(f)]), (), generator=g,
                                                                      device=dev))] for f in folds_b])
            t = torch.where(rand(batch_materials) < mixup, rand(batch_materials),
                            torch.ones(batch_materials, device=dev))[:, None, None]
            for rho, pos in ((crho, c_pos), (qrho, q_pos)):
                w = w_all[pos][..., None]
                other = values[partner[:, None], pos]
                mixed = (torch.exp(t * torch.log(rho * w + EPS) + (1 - t) * torch.log(other * w + EPS)) - EPS) / w
                rho.copy_(mixed.clamp(min=0))
        ctab, qtab, sig = fold_tab[folds_b[:, None], c_pos], fold_tab[folds_b[:, None], q_pos], fold_sig[folds_b]
        rows = (ctab, crho, w_all[c_pos], cos_all[c_pos])
        c, b = solve(*rows, sig, cfg.s2, cfg.lam, weight=weight)
        with torch.no_grad():
            resid = b - torch.einsum("bck,blk->bcl", ctab[..., 2:], c)
        mu, sd, z, dc = net(hd_all[c_pos], resid, c, sig, n_ctx)
        c, _ = solve(*rows, sd, cfg.s2, cfg.lam, mu=mu, weight=weight)
        ref, mean, comp = qtab[..., 0:1], qtab[..., 1:2], qtab[..., 2:]
        mapped = mean + torch.einsum("bqk,blk->bql", comp, c)
        x = (torch.expm1(mapped.clamp(max=30)) * (ref + EPS) + ref) / w_all[q_pos][..., None]
        qc = cos_all[q_pos][..., None]
        loss = ((torch.log1p(x.clamp(min=0) * qc) - torch.log1p(qrho * qc)) ** 2).mean()
        reg = lambda_w * (dc ** 2).mean() + lambda_z * (z ** 2).mean()
        opt.zero_grad()
        (loss + reg).backward()
        torch.nn.utils.clip_grad_norm_(net.parameters(), 1.0)
        frac = step / steps if budget is None else (time.monotonic() - t_train) / budget
        if steps is not None and budget is not None:
            frac = max(frac, step / steps)
        for grp in opt.param_groups:
            grp["lr"] = lr * (0.1 + 0.9 * 0.5 * (1 + math.cos(math.pi * min(frac, 1.0))))
        opt.step()
        avg.update_parameters(net)
        losses.append(float(loss.detach()))
        step += 1
        if time.monotonic() - last_say > 30:
            last_say = time.monotonic()
            say(f"step {step}, {step / (last_say - t_train):.1f} steps/s, loss {np.mean(losses[-200:]):.5f}")
    if not losses or not np.isfinite(losses[-1]):
        raise InputError("training gave no finite loss")
    final = prior_net(cfg)
    final.load_state_dict({k: v.detach().cpu() for k, v in avg.module.state_dict().items()})
    final.eval()
    wall = time.monotonic() - t0
    meta = {"materials": names, "steps": step, "wall_time_s": round(wall, 1), "seed": seed,
            "training": {"folds": folds, "mixup": mixup, "batch_materials": batch_materials, "query_size": query_size,
                         "lr": lr, "lambda_w": lambda_w, "lambda_z": lambda_z, "ema": ema,
                         "context": [context_min, context_max],
                         "basis": os.path.basename(str(basis)) if basis else None}}
    save_prior(output, PriorModel(full, final, cfg, meta), **storage)
    say(f"wrote learnt-prior model ({step} steps, {wall / 60:.1f} min, loss {np.mean(losses[-200:]):.5f}) "
        f"to {output}")
    return output
