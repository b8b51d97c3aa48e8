"""The compressions in the scene suite against PCA of equal size (issues 28 and 29).

Reads the compression ``bench.json`` of ``benchmarks/results.py`` (``RUNS/bench-compression``:
the in-sample models on all 151 tables; ``RUNS/bench-unseen``: ``merl80-l40`` on the
20 test materials) and prints, per compressor: the suite's mean PSNR and Delta E 2000,
the mean of each scene, the worst scene, the reference scene (in-sample for today's
models: they were tuned on it), the materials below 35 dB in some scene; then issue 29's
done-when comparisons (40-D against PCA-13 + 1 dB and IPCA-8 + 2 dB with Delta E at most
both; 7-D against PCA-2 + 1 dB; unseen 40-D against PCA-13, no material below 35 dB in any
scene), each judged in every scene that no objective descended (all six: today's encode
refines on the objective scenes; the models' tuning saw the reference environment, so the
reference row is flagged).

    python benchmarks/compression_suite.py RUNS/bench-compression RUNS/bench-unseen

Each argument may name several benches joined by commas (``RUNS/bench-compression,RUNS/bench-compression-basis``):
their records are merged, a later bench's replacing an earlier one's for the same
compressor and material. ``basis-39`` rows (issue 29's basis embeddings, today's default
``encode`` of the 40-D built-ins) are checked as the 40-D rows are.
"""

from __future__ import annotations

import json
import os
import sys

import numpy as np

FLOOR_DB = 35.0


def _records(folders: str) -> tuple[list, dict]:
    """The compression records of one or more benches (``A,B``: a later bench's record of
    the same compressor and material replaces an earlier one's) and the last config."""
    found, cfg = {}, None
    for folder in folders.split(","):
        with open(os.path.join(folder, "bench.json"), encoding="utf-8") as f:
            doc = json.load(f)
        for r in doc["records"]:
            if r["kind"] == "compression" and "error" not in r:
                found[(r["method"], r["material"])] = r
        cfg = doc["config"]
    return list(found.values()), cfg


def _label(method: str) -> str:
    """``40-D (merl-rgl-l40)``, ``basis-39 (merl-rgl-l40)``, ``PCA-13``, ``IPCA-8``, ``PCA-2``
    from a record's method."""
    words = method.split()
    if words[0] == "hypernet":
        return f"{words[1]} {words[2]}"
    k = int(words[1])
    return f"IPCA-{k}" if k == 8 else f"PCA-{k}"


def summary(recs: list, scenes: list) -> dict:
    """Per compressor: suite mean PSNR / Delta E, each scene's mean, worst scene, the
    materials below :data:`FLOOR_DB` in some scene."""
    out = {}
    for method in dict.fromkeys(r["method"] for r in recs):
        rs = [r for r in recs if r["method"] == method]
        per = {s: (float(np.mean([r["scenes"][s]["psnr"] for r in rs])),
                   float(np.mean([r["scenes"][s]["delta_e"] for r in rs]))) for s in scenes}
        low = sorted({r["material"] for r in rs if min(r["scenes"][s]["psnr"] for s in scenes) < FLOOR_DB})
        out[_label(method)] = {"psnr": float(np.mean([r["psnr"] for r in rs])),
                               "delta_e": float(np.mean([r["delta_e"] for r in rs])), "scenes": per,
                               "worst": min(per, key=lambda s: per[s][0]), "below": low, "n": len(rs)}
    return out


def table(summ: dict, scenes: list, title: str) -> list[str]:
    lines = [f"#### {title}", "", "| compressor | materials | suite PSNR | suite Delta E | "
             + " | ".join(f"{s}" for s in scenes) + " | worst scene | below 35 dB in a scene |",
             "| --- | ---: | ---: | ---: | " + " | ".join("---:" for _ in scenes) + " | --- | ---: |"]
    for label, s in summ.items():
        lines.append(f"| {label} | {s['n']} | {s['psnr']:.2f} | {s['delta_e']:.3f} | "
                     + " | ".join(f"{s['scenes'][sc][0]:.2f}" for sc in scenes)
                     + f" | {s['worst']} | {len(s['below'])} |")
    return lines + [""]


def _margin(summ, a, b, need, scenes) -> str:
    """``a`` against ``b`` + ``need`` dB: in the suite mean and in each scene."""
    if a not in summ or b not in summ:
        return f"{a} against {b}: not measured"
    d = summ[a]["psnr"] - summ[b]["psnr"]
    per = {s: summ[a]["scenes"][s][0] - summ[b]["scenes"][s][0] for s in scenes}
    bad = [s for s, v in per.items() if v < need]
    de = summ[a]["delta_e"] <= summ[b]["delta_e"]
    return (f"{a} against {b} + {need:g} dB: suite {d:+.2f} dB ({'met' if d >= need else 'missed'}); scenes below "
            f"the margin: {', '.join(f'{s} {per[s]:+.2f}' for s in bad) or 'none'}; Delta E "
            f"{summ[a]['delta_e']:.3f} against {summ[b]['delta_e']:.3f} ({'at most' if de else 'above'})")


def main(argv=None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if len(args) != 2:
        print("usage: compression_suite.py RUNS/bench-compression RUNS/bench-unseen", file=sys.stderr)
        return 2
    lines = []
    for folder, title, checks in (
            (args[0], "In the training set (151 materials)",
             [(e, "PCA-13", 1.0) for e in ("basis-39 (merl-rgl-l40)", "40-D (merl-rgl-l40)")]
             + [(e, "IPCA-8", 2.0) for e in ("basis-39 (merl-rgl-l40)", "40-D (merl-rgl-l40)")]
             + [("7-D (merl-rgl-l7)", "PCA-2", 1.0)]),
            (args[1], "Unseen (the 20 test materials; models and bases fitted on the other 80)",
             [(e, "PCA-13", 0.0) for e in ("basis-39 (merl80-l40)", "40-D (merl80-l40)")])):
        recs, cfg = _records(folder)
        scenes = list(cfg.get("scenes") or ["reference"])
        summ = summary(recs, scenes)
        lines += table(summ, scenes, f"{title}: PSNR (dB) at {cfg['resolution']} px")
        lines += [f"* {_margin(summ, a, b, need, scenes)}" for a, b, need in checks if a in summ]
        for label, s in summ.items():
            if s["below"]:
                lines.append(f"* {label}: below {FLOOR_DB:g} dB in some scene: {', '.join(s['below'])}")
        lines.append("")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
