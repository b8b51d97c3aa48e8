"""BRDF log RMSE of sparse reconstructions on a list of materials, without rendering.

For a learnt-prior model (a file or a built-in name): the learnt prior, the plain basis
fit (the network unused) and IPCA's ridge fit with the same basis; or, with ``--ipca``
alone, IPCA's fit with that basis; optionally a hypernetwork model beside them. The
samples of each (material, N, draw) are those of the benchmarks' one sampling protocol,
:class:`brdfkit.acquisition.protocol.SamplingProtocol` (``docs/bench.md``, "Sampling"), the samples
``brdfkit bench`` reconstructs for the same material, N and seed: uniform over the
angles, and/or (``--sampling planned``) the table measured at ``brdfkit plan``'s
directions for the basis (``--plan-model``, default the prior's or ``--ipca``'s; the
design ``--plan-design``, as ``brdfkit bench`` takes it). Mean
over the materials and draws. The quick check behind the built-in models' validation
figures (``docs/models.md``); the full comparison with renders is ``brdfkit bench``.

    python benchmarks/eval_sparse.py --prior merl80-l40 --list ../shared/data/merl-test.txt \
        --data PROXIES/merl [--hypernet merl80-l40] [--sampling uniform planned --n 10 20 40]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

import common


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--prior", default=None, help="learnt-prior model file or built-in name")
    ap.add_argument("--ipca", default=None, help="PCA basis file or built-in name (IPCA alone, without --prior)")
    ap.add_argument("--hypernet", default=None, help="also a hypernetwork model (file or built-in name)")
    ap.add_argument("--data", required=True, help="folder of MERL .binary tables")
    ap.add_argument("--list", required=True, help="material names, one a line")
    ap.add_argument("--n", type=int, nargs="+", default=[40, 400, 4000])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2], help="draw indices")
    ap.add_argument("--sampling", nargs="+", default=["uniform"], choices=["uniform", "planned"],
                    help="samplings of the protocol (brdfkit.acquisition.protocol)")
    ap.add_argument("--plan-model", default=None,
                    help="basis planned samples are planned for (default: the prior's, or --ipca)")
    ap.add_argument("--plan-design", default=None,
                    help="design of the planned samples (brdfkit plan --design; default the protocol's, render)")
    ap.add_argument("--json", default=None, help="also write the per-material records here")
    ap.add_argument("--render", type=int, default=0, metavar="PX",
                    help="also render each reconstruction in the reference scene at PX pixels and report PSNR")
    ap.add_argument("--s2", type=float, default=None, help="override the learnt prior's metric noise variance")
    ap.add_argument("--lam", type=float, default=None, help="override the learnt prior's IPCA noise variance")
    args = ap.parse_args()

    if (args.prior is None) == (args.ipca is None):
        ap.error("give --prior (the learnt prior, its basis fit and IPCA) or --ipca (IPCA alone)")

    from brdfkit.io.folders import read_exclude_list
    from brdfkit.io.merl import read_merl
    from brdfkit.methods import get_method
    from brdfkit.evaluation.metrics import brdf_log_rmse
    from brdfkit.acquisition.protocol import SamplingProtocol

    prior = get_method("prior").load(args.prior) if args.prior else None
    basis = prior.basis if prior else get_method("ipca").load(args.ipca)
    protocols = {s: SamplingProtocol(s, args.plan_model or basis, args.plan_design) if s == "planned"
                 else SamplingProtocol(s)
                 for s in dict.fromkeys(args.sampling)}
    if prior and (args.s2 is not None or args.lam is not None):
        import dataclasses
        prior.cfg = dataclasses.replace(prior.cfg, **{k: v for k, v in (("s2", args.s2), ("lam", args.lam))
                                                      if v is not None})
    psnr_of = None
    if args.render:
        from brdfkit.evaluation.metrics import psnr
        img = common.table_renderer(args.render)

        def psnr_of(pred, ref_img):
            return float(psnr(img(pred), ref_img))
    names = read_exclude_list(args.list)
    variants = {"prior": lambda s: prior.reconstruct(s),
                "basis fit": lambda s: prior.reconstruct(s, use_prior=False)} if prior else {}
    ipca = basis.baseline() if prior else basis  # the prior's basis may have more components than IPCA-8
    variants["ipca"] = lambda s: ipca.reconstruct(s, floor=0.0)  # as published, as `sparse --method ipca`
    if args.hypernet:
        from brdfkit import api
        from brdfkit.hypernet.packing import load_builtin
        hyper = load_builtin(args.hypernet, device="cpu")
        variants["hypernet"] = lambda s: api.sparse(s, hyper)[0]
    rows = [(k, s) for k in variants for s in protocols]  # one table row per method and sampling
    errs = {r: {n: [] for n in args.n} for r in rows}
    psnrs = {r: {n: [] for n in args.n} for r in rows}
    secs = {r: [] for r in rows}
    records = []
    for name in names:
        table = read_merl(os.path.join(args.data, name + ".binary"))
        ref_img = img(table) if psnr_of else None
        for n in args.n:
            for seed in args.seeds:
                for sampling, protocol in protocols.items():
                    s, info = protocol.samples(table, name, n, seed)
                    for k, f in variants.items():
                        t = time.process_time()
                        pred = f(s)
                        secs[k, sampling].append(time.process_time() - t)
                        e = float(brdf_log_rmse(pred, table))
                        errs[k, sampling][n].append(e)
                        rec = {"material": name, "n": n, "seed": seed, "method": k, **info, "log_rmse": e}
                        if psnr_of:
                            rec["psnr"] = psnr_of(pred, ref_img)
                            psnrs[k, sampling][n].append(rec["psnr"])
                        records.append(rec)

    def row_name(r):
        return r[0] if r[1] == "uniform" else f"{r[0]} ({r[1]})"

    print(f"{len(names)} materials, draws {args.seeds}; mean BRDF log RMSE")
    print(f"{'method':20s} " + " ".join(f"N={n:>5d}" for n in args.n) + "  CPU s/recon")
    for r in rows:
        print(f"{row_name(r):20s} " + " ".join(f"{np.mean(errs[r][n]):7.4f}" for n in args.n)
              + f"  {np.mean(secs[r]):.3f}")
    if psnr_of:
        print(f"mean PSNR (dB), reference scene at {args.render} px")
        for r in rows:
            print(f"{row_name(r):20s} " + " ".join(f"{np.mean(psnrs[r][n]):7.2f}" for n in args.n))
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"materials": names, "records": records}, f)


if __name__ == "__main__":
    from brdfkit.errors import BrdfkitError

    try:
        main()
    except BrdfkitError as e:  # bad input (a model, list or design): one line, exit code 2
        print(f"eval_sparse.py: error: {e}", file=sys.stderr)
        sys.exit(2)
