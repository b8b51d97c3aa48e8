#!/usr/bin/env python3
"""Fit and reconstruction times (and BRDF-space errors) of the sparse baselines.

Measures, on MERL tables (real files or the NBRDF proxies of ``../shared``):

* ``ipca``: the time to fit the PCA basis on the training tables (read included), and
  per sample set the time of the ridge fit plus the dense decode;
* ``nbrdf``: per sample set the time of fitting the network to the samples and of the
  dense decode (``to_table``);

at N = 40, 400 and 4000 samples (``brdfkit.acquisition.sampling.draw_samples``, seeds 0, 1, ...), with
``brdfkit.evaluation.metrics.brdf_log_rmse`` against the full table. Prints a Markdown table (the
one in ``docs/baselines.md``) and, with ``--json``, writes every measurement.

Example (the figures in docs/baselines.md)::

    python benchmarks/baselines_time.py --data proxies/merl \\
        --test-list ../shared/data/merl-test.txt --materials 5 --basis basis.safetensors

(``proxies/merl``: the reference proxies, made by
``python ../shared/tools/nbrdf_to_merl.py merl proxies/merl``; ``docs/data.md``.)
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time

import numpy as np


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", required=True, help="folder of MERL .binary tables")
    ap.add_argument("--test-list", required=True, help="names held out from the basis (one a line)")
    ap.add_argument("--materials", type=int, default=5, help="how many test materials to time (first ones)")
    ap.add_argument("--n", type=int, nargs="+", default=[40, 400, 4000], help="sample counts")
    ap.add_argument("--seeds", type=int, default=1, help="sample sets per material and N")
    ap.add_argument("--basis", default=None, help="PCA basis file: read if it exists, else fitted "
                                                  "(timed) and written there")
    ap.add_argument("--components", type=int, default=8)
    ap.add_argument("--nbrdf-steps", type=int, default=None, help="NBRDF step budget (default: the module's)")
    ap.add_argument("--json", default=None, help="write all measurements here")
    args = ap.parse_args(argv)

    import torch

    from brdfkit.basis import fit_basis, load_basis, save_basis
    from brdfkit.methods.nbrdf import DEFAULT_STEPS, fit_nbrdf
    from brdfkit.io.merl import read_merl
    from brdfkit.evaluation.metrics import brdf_log_rmse
    from brdfkit.acquisition.sampling import draw_samples

    test = [ln.strip() for ln in open(args.test_list) if ln.strip() and not ln.startswith("#")]
    files = sorted(f for f in os.listdir(args.data) if f.endswith(".binary"))
    train = [os.path.join(args.data, f) for f in files if f[:-7] not in test]
    chosen = [t for t in test if t + ".binary" in files][:args.materials]
    out = {"machine": platform.processor() or platform.machine(), "cpus": os.cpu_count(),
           "torch_threads": torch.get_num_threads(), "load_average_start": os.getloadavg(),
           "train_materials": len(train), "rows": []}

    if args.basis and os.path.exists(args.basis):
        basis = load_basis(args.basis)
        out["ipca_fit_s"] = None
    else:
        t = time.perf_counter()
        basis = fit_basis(train, args.components)
        out["ipca_fit_s"] = time.perf_counter() - t
        if args.basis:
            save_basis(args.basis, basis)
    steps = args.nbrdf_steps or DEFAULT_STEPS

    for name in chosen:
        table = read_merl(os.path.join(args.data, name + ".binary"))
        for n in args.n:
            for seed in range(args.seeds):
                samples = draw_samples(table, n, seed=seed)
                t, c = time.perf_counter(), time.process_time()
                rec = basis.reconstruct(samples)
                t_ipca, c_ipca = time.perf_counter() - t, time.process_time() - c
                e_ipca = brdf_log_rmse(rec, table)
                c = time.process_time()
                model = fit_nbrdf(samples, steps=steps, seed=seed)
                c_fit = time.process_time() - c
                t = time.perf_counter()
                rec = model.to_table()
                t_dec = time.perf_counter() - t
                row = {"material": name, "n": n, "seed": seed, "ipca_s": t_ipca, "ipca_cpu_s": c_ipca,
                       "ipca_err": e_ipca, "nbrdf_fit_s": model.seconds, "nbrdf_fit_cpu_s": c_fit,
                       "nbrdf_steps": model.steps, "nbrdf_decode_s": t_dec,
                       "nbrdf_err": brdf_log_rmse(rec, table)}
                out["rows"].append(row)
                print(json.dumps(row), file=sys.stderr, flush=True)
    out["load_average_end"] = os.getloadavg()

    print(f"torch threads {out['torch_threads']}, {out['cpus']} CPUs, load average "
          f"{out['load_average_start'][0]:.1f} -> {out['load_average_end'][0]:.1f}")
    if out["ipca_fit_s"] is not None:
        print(f"ipca basis fit on {len(train)} tables ({args.components} components): "
              f"{out['ipca_fit_s']:.1f} s")
    print("\n| N | ipca fit + decode: wall (CPU) s | ipca log-RMSE | nbrdf fit: wall (CPU) s | "
          "nbrdf steps | nbrdf decode s | nbrdf log-RMSE |")
    print("| ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    for n in args.n:
        rows = [r for r in out["rows"] if r["n"] == n]
        if not rows:
            continue
        med = lambda k: float(np.median([r[k] for r in rows]))  # noqa: E731
        print(f"| {n} | {med('ipca_s'):.2f} ({med('ipca_cpu_s'):.2f}) | {med('ipca_err'):.4f} | "
              f"{med('nbrdf_fit_s'):.1f} ({med('nbrdf_fit_cpu_s'):.1f}) | {med('nbrdf_steps'):.0f} | "
              f"{med('nbrdf_decode_s'):.2f} | {med('nbrdf_err'):.4f} |")
    print(f"\n(medians over {len(chosen)} materials x {args.seeds} sample set(s): {', '.join(chosen)})")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
