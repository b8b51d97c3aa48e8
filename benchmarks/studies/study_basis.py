"""Decided: the built-ins' learnt priors fit a 32-component basis (Lever 6: +1.8 dB on screen
at N = 40 and +6.5 dB at N = 4000 over 8 components) with the mapping's grazing floor
``w_floor = 0.1`` and int8 components (Lever 7; the floor later became 0.005,
``docs/notes/compression.md``); none of Lever 8's changes to the prior's training was
adopted. Reported in ``docs/notes/generalisation.md``, "Lever 6 (issue 22): the basis's
size, judged by renders", "Lever 7 (issue 22): grazing angles, the mapping's floor" (and its
"Storage: int8 components") and "Lever 8 (issue 22): the log RMSE at N = 40 and the learnt
prior's training".

How large a basis, fitted how, for sparse reconstruction judged by renders? (issue 22)

Issue 22 asks the default ``brdfkit sparse`` to beat 8-component IPCA (Nielsen et al.
2015) by 1 dB of render PSNR from N = 160 samples up. At N = 4000 an 8-component basis is
at its own ceiling (the projection of the whole table); a larger basis raises the ceiling
but has more coefficients to fit from few samples. This study measures both, with the
render-aligned error of :mod:`brdfkit.render.screen` (32 px reference scene; Spearman
0.996 with 128 px reference PSNR, ``docs/notes/render-error.md``), never touching the 20 test
materials:

* bases fitted on the 64 MERL training materials outside ``benchmarks/validation.txt``
  (``brdfkit fit --method ipca PROXIES --exclude-list TEST+VALIDATION --components K``), scored on the 16 validation ones;
* samples: :func:`brdfkit.acquisition.sampling.draw_samples` (uniform over the Rusinkiewicz angles),
  draws ``--seeds``;
* fits: ``ipca`` (the basis's own ridge fit, :meth:`PcaBasis.coefficients`), ``solve``
  (the learnt prior's closed form :func:`~brdfkit.prior.model.solve` without a
  network, the likelihood ``weight``/``s2``/``lam``), ``proj`` (least squares on the whole
  table: the ceiling), ``prior`` (a learnt-prior file's own fit, its network included;
  ``--basis LABEL=PRIOR_FILE``, trained with ``brdfkit fit --method prior`` on the same 64:
  the other fits then use its basis; ``LABEL=F1+F2+...``: an ensemble of priors on one
  basis, their prior means averaged), ``joint:S2`` (the closed form with the energy
  likelihood and a joint prior over the three channels of each component: its ``3 x 3``
  second moments over the basis's training materials, projected onto the basis).

    python benchmarks/studies/study_basis.py --proxies proxies \
        --basis 8=b8.safetensors 16=b16.safetensors 32=b32.safetensors --n 40 160 400 4000 --seeds 0 1

(``proxies`` holds ``merl/`` and ``rgl/``, made by ``python ../shared/tools/nbrdf_to_merl.py merl
proxies/merl`` and ``... rgl proxies/rgl``.)
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import pathlib
import time

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
VALIDATION = HERE.parent / "validation.txt"

FITS = ("ipca", "proj", "energy:0.01", "energy:0.03", "energy:0.1", "metric:0.03", "prior", "joint:0.03")


def fit(basis, samples, table, how: str, lam: float, prior=None):
    """Coefficients ``(K, 3)`` of one fit (module docstring); ``prior`` the learnt-prior
    models ``basis`` came from (``prior``) or the channel moments (``joint:``)."""
    import torch

    from brdfkit.prior.model import sample_rows, solve

    if how == "prior":
        return ensemble_coefficients(prior, samples)
    if how.startswith("joint:"):
        return joint_fit(basis, samples, float(how.split(":")[1]), lam, prior)
    if how == "ipca":
        return basis.coefficients(samples)
    if how == "proj":
        return basis.project(table)
    weight, s2 = how.split(":")
    ok, tab, w, cos, rho, _ = sample_rows(basis, samples)
    T = lambda a: torch.from_numpy(np.ascontiguousarray(a, np.float32))[None]  # noqa: E731
    sig = torch.from_numpy(basis.sigma.astype(np.float32))[None]
    with torch.no_grad():
        c, _ = solve(T(tab), T(rho), T(w), T(cos), sig, float(s2), lam, weight=weight)
    return c[0].double().numpy().T


def ensemble_coefficients(models, samples):
    """Coefficients ``(K, 3)`` of learnt priors on one basis, their prior means (and
    spreads) averaged: the first model's fit with a network that averages the members'
    (the posterior is linear in the mean: the average of the members' fits)."""
    if len(models) == 1:
        return models[0].coefficients(samples)

    import torch

    class MeanNet(torch.nn.Module):
        def forward(self, *inputs):
            outs = [m.net(*inputs) for m in models]
            return (*(sum(o[i] for o in outs) / len(outs) for i in (0, 1)), *outs[0][2:])

    return dataclasses.replace(models[0], net=MeanNet()).coefficients(samples)


def joint_fit(basis, samples, s2: float, lam: float, moments):
    """The energy likelihood's closed form with a joint Gaussian prior over each component's
    three channel coefficients, covariance ``moments (K, 3, 3)`` (module docstring)."""
    from brdfkit.basis import EPS
    from brdfkit.basis.mapping import to_mapped
    from brdfkit.prior.model import sample_rows

    ok, tab, w, cos, rho, _ = sample_rows(basis, samples)
    k = basis.n_components
    b = to_mapped(rho, w[:, None], tab[:, :1]) - tab[:, 1:2]
    q = cos[:, None] * (rho + EPS / w[:, None]) / (1 + rho * cos[:, None]) / s2 + 1.0 / lam
    a = tab[:, 2:]
    lhs, rhs = np.zeros((3 * k, 3 * k)), np.zeros(3 * k)
    for ch in range(3):
        lhs[ch * k:(ch + 1) * k, ch * k:(ch + 1) * k] = a.T @ (q[:, ch:ch + 1] * a)
        rhs[ch * k:(ch + 1) * k] = a.T @ (q[:, ch] * b[:, ch])
    for j in range(k):
        idx = [j, k + j, 2 * k + j]
        lhs[np.ix_(idx, idx)] += np.linalg.inv(moments[j])
    return np.linalg.solve(lhs, rhs).reshape(3, k).T


def channel_moments(basis, proxies):
    """``(K, 3, 3)`` second moments of the channel coefficients of the basis's training
    materials (each table projected onto the basis), scaled so that their mean diagonal is
    ``sigma ** 2``."""
    from brdfkit.io.merl import read_merl

    c = np.stack([basis.project(read_merl(pathlib.Path(proxies) / f"{m}.binary")) for m in basis.materials])
    m2 = np.einsum("mka,mkb->kab", c, c) / len(c)
    scale = basis.sigma.astype(np.float64) ** 2 / (np.trace(m2, axis1=1, axis2=2) / 3)
    return m2 * scale[:, None, None]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--proxies", required=True, help="folder of the 100 MERL proxy .binary tables")
    ap.add_argument("--basis", nargs="+", required=True, help="LABEL=FILE ipca model files (LABEL: K, or any name)")
    ap.add_argument("--n", nargs="+", type=int, default=[40, 160, 400, 4000])
    ap.add_argument("--seeds", nargs="+", type=int, default=[0])
    ap.add_argument("--fits", nargs="+", default=list(FITS))
    ap.add_argument("--lam", type=float, default=0.1, help="IPCA likelihood variance of solve")
    ap.add_argument("--json", default=None)
    args = ap.parse_args(argv)

    from brdfkit.io.merl import read_merl
    from brdfkit.basis import load_basis
    from brdfkit.prior.prior_file import is_prior_file as _is_prior
    from brdfkit.prior.prior_file import load_prior
    from brdfkit.evaluation.metrics import brdf_log_rmse, dark_at_grazing
    from brdfkit.render.screen import screen, screen_psnr
    from brdfkit.acquisition.sampling import draw_samples

    names = VALIDATION.read_text().split()
    bases, priors, moments = {}, {}, {}
    for k, f in (s.split("=", 1) for s in args.basis):
        if _is_prior(f.split("+")[0]):
            priors[k] = [load_prior(x) for x in f.split("+")]
            bases[k] = priors[k][0].basis
        else:
            bases[k] = load_basis(f)
        if any(h.startswith("joint:") for h in args.fits):
            moments[k] = channel_moments(bases[k], args.proxies)
    sc = screen()
    rows, t0 = [], time.monotonic()
    for name in names:
        table = read_merl(pathlib.Path(args.proxies) / f"{name}.binary")
        ref_img = sc.render_table(table)
        for n in args.n:
            for seed in args.seeds:
                s = draw_samples(table, n, seed=seed, source=name)
                for k, basis in bases.items():
                    for how in args.fits:
                        if (how == "proj" and (n != args.n[0] or seed != args.seeds[0])) or \
                                (how == "prior" and k not in priors):
                            continue
                        rec = basis.decode(fit(basis, s, table, how, args.lam,
                                               moments.get(k) if how.startswith("joint:") else priors.get(k)))
                        rows.append({"material": name, "n": n, "seed": seed, "k": k, "fit": how,
                                     "psnr": screen_psnr(sc.render_table(np.nan_to_num(rec)), ref_img),
                                     "log_rmse": float(brdf_log_rmse(rec, table)),
                                     "dark_grazing": dark_at_grazing(rec, table)})
        print(f"{name} done, {time.monotonic() - t0:.0f} s", flush=True)
    print("\nmean screen PSNR (dB) / log RMSE / share of grazing cells below a tenth of the data, over the "
          "validation materials and draws")
    print("| K | fit | " + " | ".join(f"N = {n}" for n in args.n) + " |")
    print("| --- | --- |" + " ---: |" * len(args.n))
    for k in bases:
        for how in args.fits:
            cells = []
            for n in args.n:
                r = [x for x in rows if x["k"] == k and x["fit"] == how and (x["n"] == n or how == "proj")]
                cells.append(f"{np.mean([x['psnr'] for x in r]):.2f} / {np.mean([x['log_rmse'] for x in r]):.4f}"
                             f" / {np.mean([x['dark_grazing'] for x in r]):.3f}" if r else "")
            print(f"| {k} | {how} | " + " | ".join(cells) + " |")
    if args.json:
        pathlib.Path(args.json).write_text(json.dumps({"args": vars(args), "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
