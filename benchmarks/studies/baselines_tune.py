#!/usr/bin/env python3
"""Decided: IPCA's ridge weight ``lam = 0.1`` (``DEFAULT_LAMBDA``) and NBRDF's learning rate
1e-3 (``DEFAULT_LR``), both chosen on training materials only. Reported in
``docs/notes/baselines.md``, "IPCA's ridge weight" and "NBRDF's learning rate".

How the baselines' fixed settings were chosen, on training materials only.

``lambda``: the ridge weight of ``ipca``. The 80 training materials (all tables in
``--data`` not named in ``--test-list``) are split: every 4th (sorted by name) is a
validation material, the other 60 fit a basis of ``--components`` components; each
validation material is sampled at N = 40, 400, 4000 (seeds 1 and 2) and reconstructed with
each lambda; prints the mean and median ``brdf_log_rmse`` per (N, lambda).

``nbrdf-lr``: the learning rate of ``nbrdf``. Five training materials (every 16th from the
3rd), N = 40, 400, 4000 (sample seed 1, weight seed 0), Adam at each learning rate, at
most 6000 steps, patience 400; prints error, steps and seconds per (N, lr).

Example (the figures in docs/baselines.md)::

    python benchmarks/studies/baselines_tune.py lambda --data proxies/merl --test-list ../shared/data/merl-test.txt
    python benchmarks/studies/baselines_tune.py nbrdf-lr --data proxies/merl --test-list ../shared/data/merl-test.txt

(``proxies/merl``: the reference proxies, made by
``python ../shared/tools/nbrdf_to_merl.py merl proxies/merl``; ``docs/data.md``.)
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np


def _training(args):
    test = {ln.strip() for ln in open(args.test_list) if ln.strip() and not ln.startswith("#")}
    files = sorted(f for f in os.listdir(args.data) if f.endswith(".binary"))
    return [os.path.join(args.data, f) for f in files if f[:-7] not in test]


def tune_lambda(args) -> None:
    from brdfkit.basis import fit_basis
    from brdfkit.io.merl import read_merl
    from brdfkit.evaluation.metrics import brdf_log_rmse
    from brdfkit.acquisition.sampling import draw_samples

    train = _training(args)
    val = train[::4]
    fit = [f for f in train if f not in val]
    t = time.perf_counter()
    basis = fit_basis(fit, args.components)
    print(f"basis: {len(fit)} materials, {time.perf_counter() - t:.1f} s; validation: {len(val)}", flush=True)
    res: dict = {}
    for f in val:
        table = read_merl(f)
        for n in (40, 400, 4000):
            for seed in (1, 2):
                samples = draw_samples(table, n, seed=seed)
                for lam in args.lambdas:
                    res.setdefault((n, lam), []).append(brdf_log_rmse(basis.reconstruct(samples, lam=lam), table))
    print("| N | lambda | mean log-RMSE | median |")
    print("| ---: | ---: | ---: | ---: |")
    for (n, lam), v in sorted(res.items()):
        print(f"| {n} | {lam:g} | {np.mean(v):.4f} | {np.median(v):.4f} |")


def tune_nbrdf(args) -> None:
    import torch

    from brdfkit.methods.nbrdf import fit_nbrdf
    from brdfkit.io.merl import read_merl
    from brdfkit.evaluation.metrics import brdf_log_rmse
    from brdfkit.acquisition.sampling import draw_samples

    torch.set_num_threads(1)
    val = _training(args)[2::16]
    print("materials:", ", ".join(os.path.basename(v)[:-7] for v in val), flush=True)
    res: dict = {}
    for f in val:
        table = read_merl(f)
        for n in (40, 400, 4000):
            samples = draw_samples(table, n, seed=1)
            for lr in args.lrs:
                m = fit_nbrdf(samples, steps=6000, lr=lr, patience=400, seed=0)
                e = brdf_log_rmse(m.to_table(), table)
                res.setdefault((n, lr), []).append((e, m.steps, m.seconds))
                print(os.path.basename(f)[:-7], n, lr, round(e, 4), m.steps, round(m.seconds, 1),
                      file=sys.stderr, flush=True)
    print("| N | lr | mean log-RMSE | median | median steps | median s |")
    print("| ---: | ---: | ---: | ---: | ---: | ---: |")
    for (n, lr), v in sorted(res.items()):
        v = np.array(v)
        print(f"| {n} | {lr:g} | {v[:, 0].mean():.4f} | {np.median(v[:, 0]):.4f} | "
              f"{np.median(v[:, 1]):.0f} | {np.median(v[:, 2]):.1f} |")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("what", choices=["lambda", "nbrdf-lr"])
    ap.add_argument("--data", required=True, help="folder of MERL .binary tables")
    ap.add_argument("--test-list", required=True, help="names never used here (one a line)")
    ap.add_argument("--components", type=int, default=8)
    ap.add_argument("--lambdas", type=float, nargs="+", default=[0.01, 0.03, 0.1, 0.3, 1, 3])
    ap.add_argument("--lrs", type=float, nargs="+", default=[1e-3, 5e-3, 1e-2])
    args = ap.parse_args(argv)
    (tune_lambda if args.what == "lambda" else tune_nbrdf)(args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
