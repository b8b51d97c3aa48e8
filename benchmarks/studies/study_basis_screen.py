"""Decided: a basis embedding (today's default ``encode``) refines the projection's
coefficients for at most 80 steps on the objective scenes ``studio-0..3`` with a trust term
weighted 0.01, which keeps the backlit scene that a refinement on renders alone gives up
(2 to 2.8 dB). Reported in ``docs/notes/compression.md``, "Basis embeddings: today's default
`encode` (issue 29)", "How it was chosen: levers measured on training materials".

Issue 29: PCA coefficients refined on the objective scenes, judged in the suite.

For each material: the least-squares projection onto a basis's ``K`` leading components
(the PCA-K of ``brdfkit bench``), then :func:`brdfkit.basis.refine_on_screen.refine_coefficients`
with ``--steps`` steps; both decoded and scored in the six judged scenes (64 px), none of
which the refinement descends (it uses ``studio-0..3``). References come from the bench's
render cache.

    python benchmarks/studies/study_basis_screen.py BASIS FOLDER -k 13 --steps 40 --lr 0.02 -o OUT.json
    python benchmarks/studies/study_basis_screen.py table benchmarks/results/2026-11-26-basis-refine-study.json

The second form prints the table of a record that gathers several runs (``docs/notes/compression.md``).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np


def print_table(path):
    """Per run of a gathered record and per row (projection, refined N): the suite's mean
    PSNR and Delta E, each scene's mean PSNR, the materials below their projection."""
    with open(path, encoding="utf-8") as fh:
        doc = json.load(fh)
    scenes = None
    for name, run in doc["runs"].items():
        recs = run["records"]
        scenes = scenes or list(recs[0]["projection"]["scenes"])
        if name == next(iter(doc["runs"])):
            print("| run | row | suite PSNR | Delta E | " + " | ".join(scenes) + " | worse than projection |")
            print("| --- | --- | ---: | ---: | " + " | ".join("---:" for _ in scenes) + " | ---: |")
        for key in [k for k in recs[0] if k != "material"]:
            base = np.array([r["projection"]["psnr"] for r in recs])
            ps = np.array([r[key]["psnr"] for r in recs])
            per = [np.mean([r[key]["scenes"][s]["psnr"] for r in recs]) for s in scenes]
            print(f"| {name} ({len(recs)}) | {key} | {ps.mean():.2f} | {np.mean([r[key]['delta_e'] for r in recs]):.3f} | "
                  + " | ".join(f"{v:.2f}" for v in per) + f" | {int((ps < base - 0.05).sum())} |")


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["table"]:
        return print_table(argv[1])
    ap = argparse.ArgumentParser()
    ap.add_argument("basis")
    ap.add_argument("folder")
    ap.add_argument("-k", type=int, default=13)
    ap.add_argument("--steps", type=int, nargs="*", default=[40], help="refinement budgets (none: the projection only)")
    ap.add_argument("--lr", type=float, default=0.02)
    ap.add_argument("--trust", type=float, default=0.0)
    ap.add_argument("--scenes", default="studio-0,studio-1,studio-2,studio-3")
    ap.add_argument("--skip", default="", help="file of names to leave out")
    ap.add_argument("--limit", type=int, default=0)
    ap.add_argument("--every", type=int, default=1, help="every n-th material")
    ap.add_argument("--cache", default=os.path.join("runs", "bench-cache"),
                    help="folder of the reference renders, shareable between runs (default runs/bench-cache)")
    ap.add_argument("--resolution", type=int, default=64)
    ap.add_argument("-o", "--output", required=True)
    a = ap.parse_args(argv)

    import torch

    torch.set_num_threads(1)
    from brdfkit.bench.config import BenchConfig
    from brdfkit.bench.worker import Worker
    from brdfkit.render.objective import ObjectiveConfig
    from brdfkit.io.merl import read_merl
    from brdfkit.basis import load_basis
    from brdfkit.basis.refine_on_screen import refine_coefficients
    from brdfkit.render.scene_suite import scene_names

    cfg = BenchConfig(output=os.path.dirname(os.path.abspath(a.output)), data=None,
                      scenes=tuple(scene_names("all")), resolution=a.resolution, cache=a.cache)
    w = Worker(cfg)
    basis = load_basis(a.basis).leading(a.k)
    scenes = tuple(a.scenes.split(","))
    skip = set()
    if a.skip:
        with open(a.skip, encoding="utf-8") as fh:
            skip = set(fh.read().split())
    names = sorted(f for f in os.listdir(a.folder) if f.endswith(".binary") and f[:-7] not in skip)[::a.every]
    if a.limit:
        names = names[:a.limit]
    out = []
    for f in names:
        path = os.path.join(a.folder, f)
        table = read_merl(path)
        refs = w.reference(f[:-7], path, table)
        c0 = basis.project(table)
        rec = {"material": f[:-7], "projection": _brief(w.score(basis.decode(c0), table, refs))}
        for steps in a.steps:
            t0 = time.perf_counter()
            c, info = refine_coefficients(basis, table, c0, ObjectiveConfig(steps=steps, lr=a.lr, scenes=scenes),
                                          trust=a.trust)  # --trust defaults to 0 here, not DEFAULT_TRUST
            info["seconds"] = time.perf_counter() - t0
            rec[f"refined{steps}"] = dict(_brief(w.score(basis.decode(c), table, refs)), **info)
        out.append(rec)
        print(f, {k: (round(v["psnr"], 2), round(v.get("seconds", 0), 1)) for k, v in rec.items() if k != "material"},
              flush=True)
        with open(a.output, "w") as fh:
            json.dump({"args": vars(a), "records": out}, fh, indent=1)
    for k in [k for k in out[0] if k != "material"]:
        ps = [r[k]["psnr"] for r in out]
        per = {s: round(float(np.mean([r[k]["scenes"][s]["psnr"] for r in out])), 2) for s in out[0][k]["scenes"]}
        print(k, round(float(np.mean(ps)), 2), round(float(np.mean([r[k]["delta_e"] for r in out])), 3), per)


def _brief(score):
    return {"psnr": score["psnr"], "delta_e": score["delta_e"], "log_rmse": score["log_rmse"],
            "scenes": {s: {"psnr": v["psnr"], "delta_e": v["delta_e"]} for s, v in score["scenes"].items()}}


if __name__ == "__main__":
    sys.exit(main())
