"""Decided: the basis file's compact storage (float16, every other ``phi_d`` cell restored from
its neighbours): float16 changes nothing at four digits, and halving ``phi_d`` costs about
2 % in log RMSE and 0.01 dB, the price of fitting the built-ins into their size budget.
Reported in ``docs/notes/models.md``, "How the shipped models were made" (the basis's
compact storage).

What the compact storage of a PCA basis costs (``brdfkit.basis.storage``).

Fits the 8-component basis to the MERL training proxies less the fixed validation split,
stores it as shipped (float16, every other ``phi_d`` cell) and as float32, reads both
back, and prints the mean BRDF log RMSE on the validation materials of the IPCA fit from
N = 40 / 400 / 4000 samples (draws 0, 1, 2) and of the full-table projection, with
the file sizes.

    python benchmarks/studies/basis_storage.py --proxies PROXIES
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile

import numpy as np

from brdfkit.geometry import N_CELLS
from brdfkit.basis import fit_basis, load_basis, save_basis
from brdfkit.acquisition.sampling import draw_samples

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))  # benchmarks/common.py
import common  # noqa: E402
from study_data import load_library, validation_materials  # noqa: E402


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--proxies", required=True)
    ap.add_argument("--n", type=int, nargs="+", default=[40, 400, 4000])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--render", type=int, default=0, metavar="PX",
                    help="also the mean PSNR of the IPCA fits in the reference scene at PX pixels")
    args = ap.parse_args()
    if args.render:
        from brdfkit.evaluation.metrics import psnr
        img = common.table_renderer(args.render)
    lib = load_library(args.proxies)
    val = validation_materials()
    train = [n for n in lib.names if n not in val and not n.startswith("rgl:")]
    basis = fit_basis([lib.table(n) for n in train], 8, names=train)
    with tempfile.TemporaryDirectory() as tmp:
        variants = {}
        for label, kw in (("float32, all cells", {}), ("float16, all cells", {"half": True}),
                          ("float16, half phi_d", {"half": True, "phi_stride": 2})):
            path = os.path.join(tmp, "b.safetensors")
            save_basis(path, basis, **kw)
            variants[label] = (load_basis(path), os.path.getsize(path))
        print(f"{'storage':22s} {'MB':>6s} " + " ".join(f"N={n:>5d}" for n in args.n) + "  projection")
        for label, (model, size) in variants.items():
            errs = {n: [] for n in args.n}
            psnrs = {n: [] for n in args.n}
            proj = []
            for name in val:
                table = lib.table(name)
                ref_img = img(table) if args.render else None
                for n in args.n:
                    for seed in args.seeds:
                        pred = model.reconstruct(draw_samples(table, n, seed=seed))
                        errs[n].append(lib.log_rmse(name, pred.reshape(N_CELLS, 3)[lib.cells]))
                        if args.render:
                            psnrs[n].append(float(psnr(img(pred), ref_img)))
                proj.append(lib.log_rmse(name, model.decode(model.project(table)).reshape(N_CELLS, 3)[lib.cells]))
            print(f"{label:22s} {size / 1e6:6.2f} " + " ".join(f"{np.mean(errs[n]):7.4f}" for n in args.n)
                  + f"  {np.mean(proj):.4f}" + ("  PSNR " + " ".join(f"{np.mean(psnrs[n]):.2f}" for n in args.n)
                                                 if args.render else ""), flush=True)


if __name__ == "__main__":
    main()
