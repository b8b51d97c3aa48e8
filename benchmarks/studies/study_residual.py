"""Decided: a hyponet that predicts a residual function over the basis fit learns nothing that
carries over, while a network that gives the prior mean of the basis coefficients (``--coef
--align --prior --mixup 0.5``) beat IPCA on the validation materials at N = 40, 400 and
4000; it became the learnt prior, ``--method prior``, the default of ``brdfkit sparse``.
Reported in ``docs/notes/generalisation.md``, "Lever 2: a network on top of the basis fit"
and "The method as shipped".

Study: the hypernetwork as a residual over the closed-form basis fit (issue 12).

The model contains the linear basis as a special case: a material's samples are first
fitted by the 8-component PCA basis in closed form (:func:`study_pca.gauss_newton`: IPCA's
ridge plus the evaluation metric's likelihood, linearised), then a hypernetwork encodes
the samples' *residuals* against that fit and its hyponet predicts the residual
everywhere, scaled by a learnt factor that starts at 0.01 (so the untrained model is the
basis fit). Training materials are fitted with a basis from which their own fold (of 5)
was left out, so that the residuals the network learns from look like those of a
material the basis has never seen. The loss is the evaluation metric itself: the mean
square of ``ln(1 + rho_hat cos_i) - ln(1 + rho cos_i)`` over query cells drawn uniformly.

Prints, for the fixed validation split (``validation.txt``), the mean log RMSE at
N = 40 / 400 / 4000 of IPCA, of the basis fit alone and of the residual model, at each
evaluation and at the end, with the training time.

    python benchmarks/studies/study_residual.py --proxies PROXIES --minutes 10 [--rgl]
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import pathlib
import time

import numpy as np
import torch

from brdfkit.geometry import N_THETA_D, N_PHI_D, N_CELLS, grid_cosine_weight, grid_hd
from brdfkit.basis import EPS, fit_basis
from brdfkit.basis.mapping import from_mapped, to_mapped
from brdfkit.hypernet.network import HyperBRDF, HyperConfig, hyponet_forward
from brdfkit.acquisition.sampling import draw_samples

from study_data import load_library, validation_materials
from study_pca import gauss_newton, sample_rows


def basis_at_cells(model, cells):
    """``(P, K + 2)`` float32 ``[reference, mean, components]`` of an IPCA model at ``cells``."""
    return np.ascontiguousarray(model.lookup_table()[cells], dtype=np.float32)


def gn_batch(tab, rho, w, cos, sigma, s2, lam, mu=None):
    """Batched :func:`study_pca.gauss_newton` on cells: ``tab (B, C, K + 2)``, ``rho (B, C, 3)``,
    ``w``, ``cos`` ``(B, C)``, ``sigma (B, K)``; coefficients ``(B, 3, K)`` (float64 solve)."""
    ref, mean, comp = tab[..., 0:1], tab[..., 1:2], tab[..., 2:].double()
    b = to_mapped(rho, w[..., None], ref) - mean  # (B, C, 3)
    g = cos[..., None] * (rho + EPS / w[..., None]) / (1 + rho * cos[..., None])
    q = (g ** 2 / s2 + 1.0 / lam).double()  # (B, C, 3)
    lhs = torch.einsum("bck,bcj,bcl->blkj", comp, comp, q)  # (B, 3, K, K)
    lhs = lhs + torch.diag_embed(1.0 / sigma.double() ** 2)[:, None]
    rhs = torch.einsum("bck,bcl->blk", comp, q * b.double())
    if mu is not None:  # a prior mean (B, 3, K) instead of 0: c = argmin ... + |(c - mu) / sigma|^2
        rhs = rhs + mu.double() / sigma.double()[:, None] ** 2
    return torch.linalg.solve(lhs, rhs).float(), b


def predict(tab, c, resid, w):
    """Values in 1/sr (clamped at 0) from the basis rows ``tab (B, Q, K + 2)``, coefficients
    ``(B, 3, K)``, a residual ``(B, Q, 3)`` in IPCA's mapped space and the mapping's weight
    ``w`` (broadcastable to ``(B, Q, 1)``)."""
    ref, mean, comp = tab[..., 0:1], tab[..., 1:2], tab[..., 2:]
    mapped = mean + torch.einsum("bqk,blk->bql", comp, c) + resid
    return from_mapped(mapped.clamp(max=30), w, ref, floor=0)


class Residual(torch.nn.Module):
    """``zero_init``: the decoder MLPs of the hyponet's last layer start at zero (its output
    is exactly 0, the basis fit), instead of a learnt output scale starting at 0.01."""

    def __init__(self, cfg, zero_init=False):
        super().__init__()
        self.net = HyperBRDF(cfg)
        if zero_init:
            with torch.no_grad():
                for nets in (self.net.decoder.weight_nets, self.net.decoder.bias_nets):
                    nets[-1][-1].weight.zero_()
                    nets[-1][-1].bias.zero_()
            self.register_buffer("alpha", torch.tensor(1.0))
        else:
            self.alpha = torch.nn.Parameter(torch.tensor(0.01))

    def forward(self, ctx_hd, ctx_resid, q_hd):
        z = self.net.encode(ctx_hd, ctx_resid)
        weights = self.net.hyponet_weights(z)
        return self.alpha * hyponet_forward(weights, q_hd), weights, z


class CoefNet(torch.nn.Module):
    """The other way for the network to sit on the basis: a set encoder of the samples'
    residuals whose head corrects the basis coefficients themselves, ``c = c_fit + dc
    sigma`` (in units of the basis's standard deviations; the head starts at zero). The
    output is 3K numbers, not a function: far less room to memorise materials."""

    def __init__(self, k, width=128, latent=40):
        super().__init__()
        mlp = lambda *sz: torch.nn.Sequential(*[m for a, b in zip(sz[:-1], sz[1:])  # noqa: E731
                                               for m in (torch.nn.Linear(a, b), torch.nn.ReLU())][:-1])
        self.enc = mlp(9, width, width, latent)
        self.head = mlp(latent + 3 * k + 1, width, width, 3 * k)
        with torch.no_grad():
            self.head[-1].weight.zero_()
            self.head[-1].bias.zero_()

    def forward(self, ctx_hd, ctx_resid, c, sigma, n, delta_only=False):
        z = self.enc(torch.cat([ctx_hd, ctx_resid], -1)).mean(1)
        b, k = c.shape[0], c.shape[-1]
        feats = torch.cat([z, (c / sigma[:, None]).reshape(b, -1),
                           torch.full((b, 1), math.log(n) / math.log(4000))], -1)
        dc = self.head(feats).view(b, 3, k)
        if delta_only:  # the prior mean: dc sigma (zero at the start: the basis's own prior)
            return dc * sigma[:, None], z, dc
        return c + dc * sigma[:, None], z, dc


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--proxies", required=True)
    ap.add_argument("--minutes", type=float, default=10)
    ap.add_argument("--rgl", action="store_true", help="train on the RGL proxies too")
    ap.add_argument("--components", type=int, default=8)
    ap.add_argument("--folds", type=int, default=5)
    ap.add_argument("--s2", type=float, default=1e-2)
    ap.add_argument("--lam", type=float, default=0.1)
    ap.add_argument("--batch", type=int, default=8)
    ap.add_argument("--query", type=int, default=4096)
    ap.add_argument("--lr", type=float, default=1e-3)
    ap.add_argument("--lambda-w", type=float, default=1e-3)
    ap.add_argument("--lambda-z", type=float, default=1e-3)
    ap.add_argument("--latent", type=int, default=40)
    ap.add_argument("--eval-minutes", type=float, default=2.5)
    ap.add_argument("--eval-cells", type=int, default=200_000, help="cells per interim evaluation")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--zero-init", action="store_true")
    ap.add_argument("--no-basis", action="store_true", help="control: no basis fit (c = 0)")
    ap.add_argument("--coef", action="store_true", help="the network corrects the coefficients (CoefNet)")
    ap.add_argument("--align", action="store_true", help="rotate the fold bases onto the full basis")
    ap.add_argument("--ema", type=float, default=0.999, help="weight EMA decay for evaluation (0: off)")
    ap.add_argument("--final-seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--prior", action="store_true", help="with --coef: the network gives the prior mean")
    ap.add_argument("--mixup", type=float, default=0.0, help="share of batch materials mixed with another")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--save", default=None, help="write the trained state here (torch.save)")
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    torch.manual_seed(args.seed)
    t0 = time.time()
    lib = load_library(args.proxies)
    val = validation_materials()
    train = [n for n in lib.names if n not in val and (args.rgl or not n.startswith("rgl:"))]
    cells = lib.cells
    K, F = args.components, args.folds
    full = fit_basis([lib.table(n) for n in train], K, names=train)
    full_tab = basis_at_cells(full, cells)
    merl_train = [n for n in train if not n.startswith("rgl:")]
    fold_of = {n: i % F for i, n in enumerate(sorted(train))}
    # The fold bases take minutes; cached beside the proxies, keyed by what they depend on.
    key = hashlib.sha256(json.dumps([sorted(train), K, F]).encode()).hexdigest()[:12]
    cache = pathlib.Path(args.proxies) / f"study-folds-{key}.npz"
    if cache.exists():
        z = np.load(cache)
        tabs, sigmas = list(z["tabs"]), list(z["sigmas"])
    else:
        tabs, sigmas = [], []
        for f in range(F):
            keep = [n for n in train if fold_of[n] != f]
            fold = fit_basis([lib.table(n) for n in keep], K, names=keep)
            tabs.append(basis_at_cells(fold, cells))
            sigmas.append(fold.sigma)
        np.savez(cache, tabs=np.stack(tabs), sigmas=np.stack(sigmas))
    if args.align:
        # Each fold's principal directions differ from the full basis's by signs and
        # rotations; a coefficient corrector needs one meaning per coefficient. Rotate each
        # fold's components onto the full basis (orthogonal Procrustes over the cells) and
        # carry its prior's variances along (the diagonal of R^T diag(sigma^2) R).
        full_comp = full_tab[:, 2:].astype(np.float64)
        for f in range(F):
            comp = tabs[f][:, 2:].astype(np.float64)
            u, _, vt = np.linalg.svd(comp.T @ full_comp)
            r = u @ vt
            tabs[f] = np.concatenate([tabs[f][:, :2], (comp @ r).astype(np.float32)], 1)
            sigmas[f] = np.sqrt(np.einsum("ij,i,ij->j", r, sigmas[f].astype(np.float64) ** 2, r)).astype(np.float32)
    fold_sig = torch.from_numpy(np.stack(sigmas))  # (F, K)
    fold_members = [torch.tensor([lib.index(n) for n in train if fold_of[n] == f]) for f in range(F)]
    print(f"library {len(lib.names)}, train {len(train)} ({len(merl_train)} MERL), validation {len(val)}; "
          f"bases (full + {F} folds) {time.time() - t0:.0f} s", flush=True)

    fold_tab = torch.from_numpy(np.stack(tabs))  # (F, P, K + 2)
    mat_index = torch.tensor([lib.index(n) for n in train])
    mat_fold = torch.tensor([fold_of[n] for n in train])
    values = torch.from_numpy(lib.values)  # (M, P, 3)
    hd_all = torch.from_numpy(np.ascontiguousarray(grid_hd()[cells]))
    w_all = torch.from_numpy(np.clip(grid_cosine_weight()[cells], 1e-6, None).astype(np.float32))
    cos_all = torch.from_numpy(lib.cos_i)
    row = torch.from_numpy(cells // (N_THETA_D * N_PHI_D))
    cdf = torch.cumsum((2 * row + 1).double(), 0)
    cdf /= cdf[-1].clone()
    P = cells.size

    cfg = HyperConfig(latent_dim=args.latent)
    model = CoefNet(K, latent=args.latent) if args.coef else Residual(cfg, zero_init=args.zero_init)
    opt = torch.optim.Adam(model.parameters(), lr=args.lr)
    # Evaluated with an exponential moving average of the weights (Polyak averaging): the
    # raw weights' validation error at N = 40 swings by 0.05 from one snapshot to the next.
    ema = torch.optim.swa_utils.AveragedModel(
        model, multi_avg_fn=torch.optim.swa_utils.get_ema_multi_avg_fn(args.ema)) if args.ema else None
    g = torch.Generator().manual_seed(args.seed)

    def evaluate(n_cells=None, seeds=(0,)):
        nonlocal model
        live = model
        if ema is not None:
            model = ema.module
        try:
            return _evaluate(n_cells, seeds)
        finally:
            model = live

    def _evaluate(n_cells=None, seeds=(0,)):
        sub = np.sort(np.random.default_rng(1).choice(P, n_cells, replace=False)) if n_cells else None
        out = {k: {n: [] for n in (40, 400, 4000)} for k in ("ipca", "basis", "residual")}
        model.eval()
        for name in val:
            table = lib.table(name)
            for n in (40, 400, 4000):
                for seed in seeds:
                    s = draw_samples(table, n, seed=seed)
                    c0 = full.coefficients(s)
                    c = gauss_newton(full, s, s2=args.s2, density=False, ipca_term=True, lam=args.lam)
                    ok, at, wts, cos_s, rho = sample_rows(full, s)
                    b = to_mapped(rho, wts[:, None], at[:, 0:1]) - at[:, 1:2]
                    cm = np.zeros_like(c) if args.no_basis else c
                    r = b - at[:, 2:] @ cm
                    ctx_hd = torch.from_numpy(s.hd()[ok].astype(np.float32))[None]
                    ctx_r = torch.from_numpy(r.astype(np.float32))[None]
                    pc = cells if sub is None else cells[sub]
                    tab = torch.from_numpy(full_tab if sub is None else full_tab[sub])[None]
                    qhd = hd_all if sub is None else hd_all[sub]
                    wq = w_all if sub is None else w_all[sub]
                    truth = lib.values[lib.index(name)] if sub is None else lib.values[lib.index(name)][sub]
                    with torch.no_grad():
                        if args.coef:
                            cn, _, _ = model(ctx_hd, ctx_r, torch.from_numpy(c.T.astype(np.float32))[None],
                                             torch.from_numpy(full.sigma.astype(np.float32))[None], int(ok.sum()),
                                             delta_only=args.prior)
                            if args.prior:
                                T = lambda a: torch.from_numpy(np.ascontiguousarray(a, np.float32))[None]  # noqa: E731
                                sig1 = torch.from_numpy(full.sigma.astype(np.float64))[None]
                                cn, _ = gn_batch(T(at), T(rho), T(wts), T(cos_s), sig1, args.s2, args.lam, mu=cn)
                            cm = cn[0].double().numpy().T
                            res = torch.zeros(1, qhd.shape[0], 3)
                        else:
                            z = model.net.encode(ctx_hd, ctx_r)
                            weights = model.net.hyponet_weights(z)
                            res = torch.cat([model.alpha * hyponet_forward(weights, qhd[None, i:i + 262144])
                                             for i in range(0, qhd.shape[0], 262144)], 1)
                        for key, cc, rr in (("basis", c, torch.zeros_like(res)), ("residual", cm, res)):
                            ct = torch.from_numpy(cc.T.astype(np.float32))[None]
                            x = predict(tab, ct, rr, wq[:, None])[0]
                            out[key][n].append(_log_rmse(x.numpy(), truth, lib.cos_i[sub] if sub is not None else lib.cos_i))
                    x0 = full.decode(c0).reshape(N_CELLS, 3)[pc]
                    out["ipca"][n].append(_log_rmse(x0, truth, lib.cos_i[sub] if sub is not None else lib.cos_i))
        model.train()
        return {k: {n: float(np.mean(v)) for n, v in d.items()} for k, d in out.items()}

    def show(tag, e, seconds):
        print(f"[{tag} {seconds / 60:.1f} min] " + "  ".join(
            f"{k}: " + "/".join(f"{v:.4f}" for v in d.values()) for k, d in e.items()), flush=True)

    show("step 0", evaluate(args.eval_cells), 0)
    t_train, step, t_eval = time.time(), 0, time.time()
    losses = []
    while time.time() - t_train < args.minutes * 60:
        u = float(torch.rand((), generator=g))
        n_ctx = int(round(math.exp(math.log(40) + u * (math.log(4000) - math.log(40)))))
        mi = torch.randint(0, len(train), (args.batch,), generator=g)
        mats, folds = mat_index[mi], mat_fold[mi]
        c_pos = torch.searchsorted(cdf, torch.rand((args.batch, n_ctx), generator=g, dtype=torch.float64)).clamp_(max=P - 1)
        q_pos = torch.randint(0, P, (args.batch, args.query), generator=g)
        ctab = fold_tab[folds[:, None], c_pos]
        qtab = fold_tab[folds[:, None], q_pos]
        crho = values[mats[:, None], c_pos].clamp(min=0)
        qrho = values[mats[:, None], q_pos].clamp(min=0)
        if args.mixup > 0:
            # A partner from the same fold (so the fold's basis has seen neither), mixed
            # linearly in IPCA's mapped space: (x + eps) = (x1 + eps)^t (x2 + eps)^(1 - t)
            # with x = rho w, whatever the reference (0 here).
            partner = torch.stack([fold_members[int(f)][int(torch.randint(0, len(fold_members[int(f)]), (), generator=g))]
                                   for f in folds])
            t = torch.rand(args.batch, generator=g)
            t = torch.where(torch.rand(args.batch, generator=g) < args.mixup, t, torch.ones_like(t))[:, None, None]
            for rho, pos in ((crho, c_pos), (qrho, q_pos)):
                w = w_all[pos][..., None]
                other = values[partner[:, None], pos].clamp(min=0)
                mixed = t * to_mapped(rho, w, 0.0) + (1 - t) * to_mapped(other, w, 0.0)
                rho.copy_(from_mapped(mixed, w, 0.0, floor=0))
        c, b = gn_batch(ctab, crho, w_all[c_pos], cos_all[c_pos], fold_sig[folds], args.s2, args.lam)
        if args.no_basis:  # the control: the hypernetwork alone, relative to the mean material
            c = torch.zeros_like(c)
        with torch.no_grad():
            ctx_r = b - torch.einsum("bck,blk->bcl", ctab[..., 2:], c)
        if args.coef and args.prior:
            # The network predicts the prior mean of the coefficients; the fit to the
            # samples is solved again around it, so many samples outweigh it.
            mu, z, dc = model(hd_all[c_pos], ctx_r, c, fold_sig[folds].float(), n_ctx, delta_only=True)
            c, _ = gn_batch(ctab, crho, w_all[c_pos], cos_all[c_pos], fold_sig[folds], args.s2, args.lam, mu=mu)
            resid = torch.zeros(())
            reg = args.lambda_w * (dc ** 2).mean() + args.lambda_z * (z ** 2).mean()
        elif args.coef:
            c, z, dc = model(hd_all[c_pos], ctx_r, c, fold_sig[folds].float(), n_ctx)
            resid = torch.zeros(())
            reg = args.lambda_w * (dc ** 2).mean() + args.lambda_z * (z ** 2).mean()
        else:
            resid, weights, z = model(hd_all[c_pos], ctx_r, hd_all[q_pos])
            reg = args.lambda_w * sum((w ** 2).mean() + (bb ** 2).mean() for w, bb in weights) / len(weights) \
                + args.lambda_z * (z ** 2).mean()
        x = predict(qtab, c, resid, w_all[q_pos][..., None])
        qc = cos_all[q_pos][..., None]
        loss = ((torch.log1p(x * qc) - torch.log1p(qrho * qc)) ** 2).mean()
        opt.zero_grad()
        (loss + reg).backward()
        torch.nn.utils.clip_grad_norm_(model.parameters(), 1.0)
        frac = min(1.0, (time.time() - t_train) / (args.minutes * 60))
        for grp in opt.param_groups:  # cosine decay to a tenth over the budget
            grp["lr"] = args.lr * (0.1 + 0.9 * 0.5 * (1 + math.cos(math.pi * frac)))
        opt.step()
        if ema is not None:
            ema.update_parameters(model)
        losses.append(float(loss.detach()))
        step += 1
        if time.time() - t_eval > args.eval_minutes * 60:
            el = time.time() - t_train
            print(f"  step {step}, {step / el:.1f} steps/s, loss {np.mean(losses[-200:]):.5f}, "
                  f"alpha {float(getattr(model, 'alpha', 1.0)):.3f}", flush=True)
            show(f"step {step}", evaluate(args.eval_cells), el)
            t_eval = time.time()
    el = time.time() - t_train
    print(f"trained {step} steps in {el / 60:.1f} min, loss {np.mean(losses[-200:]):.5f}", flush=True)
    show(f"final step {step}, all cells, seeds {args.final_seeds}", evaluate(None, tuple(args.final_seeds)), el)
    if args.save:
        torch.save({"state": model.state_dict(), "args": vars(args)}, args.save)


def _log_rmse(pred, truth, cos_i):
    c = cos_i[:, None].astype(np.float64)
    return float(np.sqrt(np.mean((np.log1p(np.asarray(pred, np.float64) * c)
                                  - np.log1p(np.asarray(truth, np.float64) * c)) ** 2)))


if __name__ == "__main__":
    main()
