"""Decided: the refinement's default settings stay (80 steps, trust 0.01, ``studio-0..3``): at
9, 21 and 39 numbers they add 0.5 to 1 dB to the projection in the mean and take from one
scene, and no setting tried adds 1 dB in every scene. Reported in
``docs/notes/compression.md``, "What the refinement adds at each size (training materials,
32 px)".

How much the refinement on renders adds to a basis embedding at each size, for given
settings, judged quickly: the projection and each setting's refined coefficients, rendered
in the six judged scenes at the render-aligned error's 32 px (:mod:`brdfkit.render.screen`;
none of them is an objective scene the refinement descends).

Choose settings on training materials only (the materials of the basis, or others outside
every reported set):

    python benchmarks/studies/study_refine_sizes.py BASIS.safetensors proxies/merl --names-from train.txt \\
        --every 10 -k 3 7 13 --set default='{}' --set scenes8='{"scenes": "studio-0,...,studio-7"}' -o refine.json

A setting is JSON: ``steps``, ``lr``, ``trust``, ``scenes`` (comma-separated objective scenes).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np


def judged(table, screens):
    import torch

    from brdfkit.render.screen import screen_psnr

    with torch.no_grad():
        return {s: sc.render_table(table) for s, sc in screens.items()}, screen_psnr


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("basis")
    ap.add_argument("folder")
    ap.add_argument("--names-from", default=None, help="file of material names (default: every table)")
    ap.add_argument("--every", type=int, default=1)
    ap.add_argument("-k", type=int, nargs="+", default=[3, 7, 13])
    ap.add_argument("--set", action="append", default=[], help="NAME=JSON settings (repeatable)")
    ap.add_argument("-o", "--output", required=True)
    a = ap.parse_args(sys.argv[1:] if argv is None else argv)
    import torch

    torch.set_num_threads(1)
    from brdfkit.basis import load_basis
    from brdfkit.basis.refine_on_screen import DEFAULT_LR, DEFAULT_TRUST, refine_coefficients
    from brdfkit.io.merl import read_merl
    from brdfkit.render.objective import OBJECTIVE, ObjectiveConfig
    from brdfkit.render.scene_suite import SUITE, scene_env
    from brdfkit.render.screen import screen, screen_psnr

    basis = load_basis(a.basis)
    names = sorted(f[:-7] for f in os.listdir(a.folder) if f.endswith(".binary"))
    if a.names_from:
        with open(a.names_from, encoding="utf-8") as f:
            keep = {w for line in f for w in [line.split("#")[0].strip()] if w}
        names = [n for n in names if n in keep]
    names = names[::a.every]
    settings = {}
    for spec in a.set:
        name, text = spec.split("=", 1)
        settings[name] = json.loads(text)
    screens = {s: screen(None, 32, env=scene_env(s)) for s in SUITE}
    out = {"basis": os.path.basename(a.basis), "k": a.k, "settings": settings, "records": []}
    for n in names:
        table = read_merl(os.path.join(a.folder, n + ".binary"))
        with torch.no_grad():
            refs = {s: sc.render_table(table) for s, sc in screens.items()}

        def score(c, part):
            dec = part.decode(c)
            with torch.no_grad():
                return {s: float(screen_psnr(sc.render_table(dec), refs[s])) for s, sc in screens.items()}

        rec = {"material": n}
        for k in a.k:
            part = basis.leading(k)
            c0 = part.project(table)
            rec[str(k)] = {"projection": score(c0, part)}
            for name, st in settings.items():
                cfg = ObjectiveConfig(steps=st.get("steps", 80), lr=st.get("lr", DEFAULT_LR),
                                      scenes=tuple(st["scenes"].split(",")) if "scenes" in st else OBJECTIVE)
                t = time.perf_counter()
                c, info = refine_coefficients(part, table, c0, cfg, trust=st.get("trust", DEFAULT_TRUST))
                rec[str(k)][name] = dict(score(c, part), seconds=time.perf_counter() - t, best_step=info["best_step"])
        out["records"].append(rec)
        print(n, {k: {s: round(float(np.mean([v for key, v in r.items() if key in SUITE])), 2)
                      for s, r in rec[str(k)].items()} for k in a.k}, file=sys.stderr, flush=True)
        with open(a.output, "w", encoding="utf-8") as f:
            json.dump(out, f, indent=1)
    rows = ["projection"] + list(settings)
    print("| numbers | setting | suite PSNR (32 px) | gain | " + " | ".join(SUITE) + " | worst scene gain |")
    print("| ---: | --- | ---: | ---: | " + " | ".join("---:" for _ in SUITE) + " | ---: |")
    for k in a.k:
        base = {s: np.mean([r[str(k)]["projection"][s] for r in out["records"]]) for s in SUITE}
        for row in rows:
            per = {s: np.mean([r[str(k)][row][s] for r in out["records"]]) for s in SUITE}
            gain = {s: per[s] - base[s] for s in SUITE}
            print(f"| {3 * k} | {row} | {np.mean(list(per.values())):.2f} | {np.mean(list(gain.values())):+.2f} | "
                  + " | ".join(f"{per[s]:.2f}" for s in SUITE) + f" | {min(gain.values()):+.2f} |")


if __name__ == "__main__":
    main()
