"""Compression error against encode time: `brdfkit encode`'s refinement steps (issues 21, 28).

For each material (MERL tables of ``--proxies``, every ``--every``-th by name) and each
model, the table is compressed by :func:`brdfkit.hypernet.refine_on_screen.compress_table`
with at most each ``--steps`` value of refinement steps (0: the paper's encoder pass),
decoded densely and rendered at ``--px`` pixels (quadrature) beside the table itself, in
each of ``--scenes`` (the suite, :mod:`brdfkit.render.scene_suite`): PSNR and Delta E 2000
of the renders (their mean over the scenes, and each scene's), the BRDF log RMSE, the
steps run and why they stopped, and the encode's wall-clock seconds (the encoder pass
included, reading the file not). Writes a JSON of every record and a plot of mean PSNR
against mean encode time.

    python benchmarks/encode_budget.py --proxies PROXIES --models merl-rgl-l40 merl-rgl-l7 \\
        --steps 0 20 40 80 120 --every 10 --scenes all --json encode-steps.json --plot docs/images/encode-budget.png
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--proxies", required=True, help="folder of MERL tables NAME.binary")
    ap.add_argument("--models", nargs="+", default=["merl-rgl-l40", "merl-rgl-l7"])
    ap.add_argument("--steps", type=int, nargs="+", default=[0, 20, 40, 80, 120])
    ap.add_argument("--scenes", default="reference", help="all, or suite scene names joined by commas")
    ap.add_argument("--every", type=int, default=10, help="every K-th material by name")
    ap.add_argument("--px", type=int, default=128)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--json", required=True)
    ap.add_argument("--plot", default=None)
    args = ap.parse_args()

    import torch

    torch.set_num_threads(args.threads)
    from common import load_average, machine

    from brdfkit.api import load_model
    from brdfkit.hypernet.refine_on_screen import compress_table
    from brdfkit.render.objective import ObjectiveConfig
    from brdfkit.io.merl import read_merl
    from brdfkit.evaluation.metrics import brdf_log_rmse, delta_e_2000, psnr
    from brdfkit.hypernet.neural_brdf import NeuralBRDF
    from brdfkit.hypernet.encoding import encode_table
    from brdfkit.render.renderable import TableBRDF
    from brdfkit.render.quadrature import render
    from brdfkit.render.scene import Scene
    from brdfkit.render.scene_suite import scene_env, scene_names

    scenes = scene_names(args.scenes)
    names = sorted(f[:-7] for f in os.listdir(args.proxies) if f.endswith(".binary"))[::args.every]
    models = {m: load_model(m, "cpu") for m in args.models}
    scene = Scene(resolution=args.px)
    records = []
    t_all = time.time()
    for name in names:
        table = read_merl(os.path.join(args.proxies, name + ".binary"))
        refs = {s: render(TableBRDF(table, device="cpu"), scene, env=scene_env(s))[0] for s in scenes}
        for mname, model in models.items():
            for steps in args.steps:
                t = time.perf_counter()
                if steps == 0:
                    emb, held, ran, stopped = encode_table(model, table, name), None, 0, "encoder"
                else:
                    r = compress_table(model, table, ObjectiveConfig(steps=steps), name)
                    emb, held, ran, stopped = r.embedding, r.heldout, r.steps, r.stopped
                seconds = time.perf_counter() - t
                pred = NeuralBRDF.from_embedding(model, emb).to_table()
                brdf = NeuralBRDF.from_embedding(model, emb)
                per = {}
                for s in scenes:
                    img = render(brdf, scene, env=scene_env(s))[0]
                    per[s] = {"psnr": psnr(img, refs[s]), "delta_e": delta_e_2000(img, refs[s])}
                rec = dict(material=name, model=mname, steps=steps, steps_run=ran, stopped=stopped, encode_s=seconds,
                           psnr=float(np.mean([v["psnr"] for v in per.values()])),
                           delta_e=float(np.mean([v["delta_e"] for v in per.values()])), scenes=per,
                           log_rmse=brdf_log_rmse(pred, table),
                           heldout_psnr=None if held is None else [-10 * np.log10(h) for h in held])
                records.append(rec)
                print(f"{name:28s} {mname:14s} steps {steps:4d} ({ran} run, {stopped}): {rec['psnr']:6.2f} dB, "
                      f"dE {rec['delta_e']:.3f}, {seconds:5.2f} s", flush=True)
    summary = {}
    for mname in models:
        for steps in args.steps:
            rs = [r for r in records if r["model"] == mname and r["steps"] == steps]
            summary[f"{mname}@{steps}"] = {k: float(np.mean([r[k] for r in rs]))
                                           for k in ("psnr", "delta_e", "log_rmse", "encode_s", "steps_run")}
    print(f"\nscenes: {', '.join(scenes)}\n| model | most steps | steps run | encode (s) | PSNR (dB) | Delta E | "
          f"log RMSE |\n| --- | ---: | ---: | ---: | ---: | ---: | ---: |")
    for key, s in summary.items():
        m, b = key.split("@")
        print(f"| {m} | {b} | {s['steps_run']:.0f} | {s['encode_s']:.2f} | {s['psnr']:.2f} | {s['delta_e']:.3f} | "
              f"{s['log_rmse']:.4f} |")
    out = dict(command=" ".join(sys.argv), machine=machine(), load_end=load_average(), scenes=scenes,
               materials=names, records=records, summary=summary, seconds=time.time() - t_all)
    with open(args.json, "w") as f:
        json.dump(out, f, indent=1)
    if args.plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(5.5, 3.6), dpi=120)
        for mname in models:
            pts = [summary[f"{mname}@{b}"] for b in args.steps]
            ax.plot([p["encode_s"] for p in pts], [p["psnr"] for p in pts], "o-", label=mname)
        ax.set_xlabel("encode time per table (s, 2-core CPU)")
        ax.set_ylabel(f"mean render PSNR (dB, {args.px} px, {len(scenes)} scene(s))")
        ax.set_title(f"compression of {len(names)} MERL proxies: error against encode time", fontsize=9)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(args.plot)


if __name__ == "__main__":
    main()
