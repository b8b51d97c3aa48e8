"""Decided: the shipped bases dropped the grazing floor of 0.1: every floor costs the RGL
materials in proportion (2.96 dB at 0.1, 39 numbers) for 0.1 to 0.4 dB on MERL; a later run
(``--floors 0 0.005``) found the shipped floor of 0.005, which touches only the cells at the
horizon, within -0.04 to +0.06 dB of none on unseen MERL and 0 to -0.14 dB on RGL. Reported
in ``docs/notes/compression.md``, "The floor alone, every value (32 px, the judged scenes)"
and "Every size, against full-precision PCA".

The mapping's grazing floor (``w_floor``), judged quickly: projections on bases fitted
with each floor, rendered in the six judged scenes at the render-aligned error's small
resolution (32 px, :mod:`brdfkit.render.screen`: the same quadrature, a quarter of the
pixels of a 64 px render), and the grazing darkness of a ridge fit to 400 samples (what
the floor was adopted for, ``docs/notes/generalisation.md``, Lever 7).

    python benchmarks/studies/study_basis_floor.py --train proxies/merl --test-list ../shared/data/merl-test.txt \\
        --sets merl-test=proxies/merl rgl=proxies/rgl --floors 0 0.02 0.1 -k 7 13 -o floor.json

Full renders (128 px) of the floor against full precision: ``study_basis_storage.py``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np


def _names(folder):
    return sorted(f[:-7] for f in os.listdir(folder) if f.endswith(".binary"))


def score(table, bases, ks, screens, samples):
    """``{floor: {K: {"psnr", "scenes", "dark"}}}`` of one table."""
    import torch

    from brdfkit.evaluation.metrics import dark_at_grazing
    from brdfkit.render.screen import screen_psnr

    with torch.no_grad():
        refs = {s: sc.render_table(table) for s, sc in screens.items()}
        out = {}
        for f, basis in bases.items():
            for k in ks:
                part = basis.leading(k)
                dec = part.decode(part.project(table))
                per = {s: float(screen_psnr(sc.render_table(dec), refs[s])) for s, sc in screens.items()}
                fit = part.reconstruct(samples)
                out.setdefault(f, {})[str(k)] = {"psnr": float(np.mean(list(per.values()))), "scenes": per,
                                                 "dark": dark_at_grazing(fit, table)}
    return out


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--train", required=True)
    ap.add_argument("--test-list", required=True)
    ap.add_argument("--sets", nargs="+", required=True)
    ap.add_argument("--floors", type=float, nargs="+", default=[0.0, 0.02, 0.1])
    ap.add_argument("-k", type=int, nargs="+", default=[7, 13])
    ap.add_argument("--every", type=int, default=1)
    ap.add_argument("-o", "--output", required=True)
    a = ap.parse_args(sys.argv[1:] if argv is None else argv)
    import torch

    torch.set_num_threads(1)
    from brdfkit.acquisition.sampling import draw_samples
    from brdfkit.basis import fit_basis
    from brdfkit.io.merl import read_merl
    from brdfkit.render.scene_suite import SUITE, scene_env
    from brdfkit.render.screen import screen

    with open(a.test_list, encoding="utf-8") as f:
        test = {w for line in f for w in [line.split("#")[0].strip()] if w}
    train = [n for n in _names(a.train) if n not in test]
    paths = [os.path.join(a.train, n + ".binary") for n in train]
    bases = {}
    for f in a.floors:
        t = time.perf_counter()
        bases[f"{f:g}"] = fit_basis(paths, max(a.k), names=train, w_floor=f)
        print(f"fitted w_floor={f:g}: {time.perf_counter() - t:.0f} s", file=sys.stderr)
    screens = {s: screen(None, 32, env=scene_env(s)) for s in SUITE}
    doc = {"train_count": len(train), "floors": [f"{f:g}" for f in a.floors], "k": a.k, "resolution": 32,
           "scenes": list(SUITE), "samples": 400, "sets": {}}
    for spec in a.sets:
        name, folder = spec.split("=", 1)
        names = [n for n in _names(folder) if (n in test) == (name == "merl-test")][::a.every]
        recs = []
        for n in names:
            table = read_merl(os.path.join(folder, n + ".binary"))
            recs.append({"material": n, "scores": score(table, bases, a.k, screens,
                                                        draw_samples(table, 400, seed=0))})
            print(f"{name} {len(recs)}/{len(names)} {n}", file=sys.stderr, flush=True)
        doc["sets"][name] = recs
        with open(a.output, "w", encoding="utf-8") as f:
            json.dump(doc, f, indent=1)
    print("| set | K | w_floor | suite PSNR (32 px) | " + " | ".join(doc["scenes"]) + " | dark at grazing (400 samples) |")
    print("| --- | ---: | ---: | ---: | " + " | ".join("---:" for _ in doc["scenes"]) + " | ---: |")
    for name, recs in doc["sets"].items():
        for k in a.k:
            for f in doc["floors"]:
                rows = [r["scores"][f][str(k)] for r in recs]
                print(f"| {name} ({len(rows)}) | {k} | {f} | {np.mean([r['psnr'] for r in rows]):.2f} | "
                      + " | ".join(f"{np.mean([r['scenes'][s] for r in rows]):.2f}" for s in doc["scenes"])
                      + f" | {np.mean([r['dark'] for r in rows]):.3f} |")


if __name__ == "__main__":
    main()
