"""Decided: test-time refinement (the latent, then the hyponet's weights) became the default of
``--method hypernet`` (``--no-refine``: the paper's one pass), but the learnt prior stays
``brdfkit sparse``'s default at every N, since the refined hypernetwork renders worse; no
change to the hypernetwork's training (Lever 5) beat the paper's recipe. Reported in
``docs/notes/generalisation.md``, "Lever 4: test-time refinement of the paper's
hypernetwork" and "Lever 5: the hypernetwork's regularisation, size, pooling and training
data".

Does test-time refinement make the paper's hypernetwork generalise? (issue 12)

Scores, on the 16 validation materials (``benchmarks/validation.txt``; the 20 test
materials are never loaded), BRDF log RMSE and optionally the reference-scene render
PSNR of

* ``encode``: the hypernetwork's one-pass reconstruction (the paper's method);
* refinement variants (:func:`brdfkit.hypernet.refine_on_samples.refine`), ``NAME:target[:key=value...]``
  with the keys of :class:`~brdfkit.hypernet.refine_on_samples.RefineConfig`;
* ``ipca`` and ``prior``: the learnt prior's basis fitted with IPCA's ridge, and the learnt
  prior as shipped (``--prior``, trained without the validation materials too),

from ``draw_samples(table, N, seed)`` samples, with the CPU seconds of each.

    brdfkit fit PROXIES/merl --exclude-list merl-test.txt $(sed 's/^/--exclude /' benchmarks/validation.txt) \
        --steps 2500 --seed 0 -o val64-l40.safetensors
    python benchmarks/studies/study_refine.py --proxies PROXIES --model val64-l40.safetensors \
        --prior val64-prior.safetensors --n 40 400 4000 --seeds 0 1 2 --json refine.json
"""

from __future__ import annotations

import argparse
import os
import pathlib
import sys
import time

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent.parent))  # benchmarks/common.py

DEFAULT_VARIANTS = ["latent:latent", "weights:weights"]


def parse_variant(spec):
    from brdfkit.hypernet.refine_on_samples import RefineConfig

    name, target, *kv = spec.split(":")
    given = {}
    for item in kv:
        k, v = item.split("=")
        given[k] = int(v) if k in ("max_steps", "check_every", "patience", "min_samples") else float(v)
    return name, RefineConfig(target=target, **given)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--proxies", required=True)
    ap.add_argument("--model", required=True, help="hypernetwork trained without benchmarks/validation.txt")
    ap.add_argument("--prior", default=None, help="learnt prior trained without them (adds ipca and prior)")
    ap.add_argument("--n", type=int, nargs="+", default=[40, 400, 4000])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0])
    ap.add_argument("--variants", nargs="*", default=DEFAULT_VARIANTS, help="NAME:target[:key=value...]")
    ap.add_argument("--px", type=int, default=0, help="also render at this size (0: log RMSE only)")
    ap.add_argument("--json", default=None)
    args = ap.parse_args()

    import torch

    from brdfkit.api import load_model
    from brdfkit.io.merl import read_merl
    from brdfkit.methods import get_method
    from brdfkit.evaluation.metrics import brdf_log_rmse, psnr
    from brdfkit.hypernet.neural_brdf import NeuralBRDF
    from brdfkit.hypernet.encoding import encode_samples
    from brdfkit.hypernet.refine_on_samples import refine
    from brdfkit.acquisition.sampling import draw_samples
    import common
    from study_data import record_progress, validation_materials

    torch.set_num_threads(1)
    model = load_model(args.model, device="cpu")
    prior = get_method("prior").load(args.prior, "cpu") if args.prior else None
    variants = [parse_variant(v) for v in args.variants]
    img = common.table_renderer(args.px) if args.px else None

    recs, t0 = [], time.time()
    for i, name in enumerate(validation_materials()):
        table = read_merl(os.path.join(args.proxies, "merl", name + ".binary"))
        ref_img = img(table) if args.px else None
        for n in args.n:
            for seed in args.seeds:
                s = draw_samples(table, n, seed=seed)
                runs = []
                c = time.process_time()
                emb = encode_samples(model, s, name)
                pred = NeuralBRDF.from_embedding(model, emb, name).to_table()
                runs.append(("encode", pred, time.process_time() - c, {}))
                for vname, cfg in variants:
                    c = time.process_time()
                    r = refine(model, s, emb, config=cfg, seed=seed, name=name)
                    pred = r.brdf.to_table()
                    runs.append((vname, pred, time.process_time() - c, r.steps))
                if prior is not None:
                    c = time.process_time()
                    pred = prior.basis.reconstruct(s)
                    runs.append(("ipca", pred, time.process_time() - c, {}))
                    c = time.process_time()
                    pred = prior.reconstruct(s)
                    runs.append(("prior", pred, time.process_time() - c, {}))
                for vname, pred, cpu, steps in runs:
                    recs.append({"material": name, "n": n, "seed": seed, "variant": vname,
                                 "log_rmse": float(brdf_log_rmse(pred, table)), "cpu_s": cpu, "steps": steps,
                                 "psnr": float(psnr(img(pred), ref_img)) if args.px else float("nan")})
        record_progress(recs, i + 1, 16, name, t0, args.json)
    summarise(recs, args.n)


def summarise(recs, ns):
    names = list(dict.fromkeys(r["variant"] for r in recs))
    print("| variant | " + " | ".join(f"log RMSE N = {n}" for n in ns) + " | "
          + " | ".join(f"PSNR N = {n}" for n in ns) + " | CPU s (mean) |")
    print("| --- |" + " ---: |" * (2 * len(ns) + 1))
    for v in names:
        rs = [r for r in recs if r["variant"] == v]
        lr = [np.mean([r["log_rmse"] for r in rs if r["n"] == n]) for n in ns]
        ps = [np.mean([r["psnr"] for r in rs if r["n"] == n]) for n in ns]
        cpu = np.mean([r["cpu_s"] for r in rs])
        print(f"| {v} | " + " | ".join(f"{x:.4f}" for x in lr) + " | "
              + " | ".join(f"{x:.2f}" for x in ps) + f" | {cpu:.2f} |")


if __name__ == "__main__":
    main()
