"""Rate against distortion: PSNR and Delta E 2000 against numbers per material, from the
compression ``bench.json`` of ``brdfkit bench``, in the six judged scenes.

Each bench is one set of materials (``NAME=FOLDER``: the folder holding its ``bench.json``);
every row is taken over the materials that every row scored.
Rows are grouped by what ran, read from the record's label: the basis plus its
hypernetwork residual (``residual-N (R)``, the default ``encode`` at the sizes a built-in
offers it at), the basis embedding (``basis-N (B)``, a basis embedding of ``N`` numbers), full-precision PCA of equal size
(``basis-K (3K numbers)``, the projection onto ``K`` components; ``pca-K`` in earlier
runs), the hypernetwork's latent (``hypernet-N``; ``latent-N`` in earlier runs). For each set and size it prints the suite mean and
every scene's mean, the default's margin over the PCA of equal size in the mean and in its
worst scene, Delta E beside PCA's, and the darkest ratio of a decoded table to the data
where the data are at least 1 /sr (``brdfkit.evaluation.metrics.darkest_ratio``; below
1e-3 is a black corner); ``--plot`` draws PSNR and Delta E against numbers per material.

    python benchmarks/rate_distortion.py unseen=runs/bench-unseen rgl=runs/bench-rgl --plot rd.png
"""

from __future__ import annotations

import argparse
import json
import os
import re
import sys

import numpy as np

_KIND = re.compile(r"^(residual|basis|hypernet|latent|pca)-(\d+)")


def rows_of(folder: str) -> tuple[dict, list]:
    """``{(kind, numbers): [records]}`` of a bench's compression records, and its scenes."""
    with open(os.path.join(folder, "bench.json"), encoding="utf-8") as f:
        doc = json.load(f)
    out, scenes = {}, doc["config"]["scenes"]
    for r in doc["records"]:
        if r["kind"] != "compression" or "error" in r:
            continue
        m = _KIND.match(r["method"])
        if m is None:
            continue
        kind, n = m.group(1), int(m.group(2))
        if kind == "latent":
            kind = "hypernet"  # the label of earlier runs
        if kind in ("basis", "pca") and " numbers" in r["method"]:  # a projection onto K components
            kind = "pca (model's basis)" if "numbers," in r["method"] else "pca"
            # a method's own basis, whole, is not the full-precision PCA
        numbers = 3 * n if kind.startswith("pca") else n
        out.setdefault((kind, numbers), []).append(r)
    # Every row over the same materials: those every row scored (a failed record drops its material).
    common = set.intersection(*({r["material"] for r in recs} for recs in out.values())) if out else set()
    return {key: [r for r in recs if r["material"] in common] for key, recs in out.items()}, scenes


def summary(recs: list, scenes: list) -> dict:
    """Means over materials: PSNR, Delta E, each scene's PSNR, the darkest ratio's minimum."""
    dark = [r.get("darkest_ratio") for r in recs if r.get("darkest_ratio") is not None]
    return {"n": len(recs), "psnr": float(np.mean([r["psnr"] for r in recs])),
            "delta_e": float(np.mean([r["delta_e"] for r in recs])),
            "scenes": {s: float(np.mean([r["scenes"][s]["psnr"] for r in recs])) for s in scenes}
            if len(scenes) > 1 else {scenes[0]: float(np.mean([r["psnr"] for r in recs]))},
            "darkest": min(dark) if dark else None}


def table(sets: dict) -> list[str]:
    lines = []
    for name, (rows, scenes) in sets.items():
        lines += [f"### {name}", "", "| numbers | row | n | suite PSNR | Delta E | " + " | ".join(scenes)
                  + " | darkest ratio |", "| ---: | --- | ---: | ---: | ---: | " + " | ".join("---:" for _ in scenes)
                  + " | ---: |"]
        for numbers in sorted({n for _, n in rows}):
            for kind in ("residual", "basis", "pca", "pca (model's basis)", "hypernet"):
                if (kind, numbers) not in rows:
                    continue
                s = summary(rows[(kind, numbers)], scenes)
                dark = "-" if s["darkest"] is None else f"{s['darkest']:.2g}"
                lines.append(f"| {numbers} | {kind} | {s['n']} | {s['psnr']:.2f} | {s['delta_e']:.3f} | "
                             + " | ".join(f"{s['scenes'][sc]:.2f}" for sc in scenes) + f" | {dark} |")
        lines += [""] + margins(rows, scenes) + [""]
    return lines


def margins(rows: dict, scenes: list) -> list[str]:
    """The residual's and the basis embedding's margins over the PCA of equal size on the
    materials both scored (mean, worst scene, Delta E), and the residual's over PCA of
    about twice its numbers (9 against 18, 21 against 39: half the numbers)."""
    out = []
    pairs = [(k, n, n) for k in ("residual", "basis") for n in sorted({n for kk, n in rows if kk == k})]
    pairs += [("residual", n, m) for n, m in ((9, 18), (21, 39)) if ("residual", n) in rows]
    for kind, numbers, against in pairs:
        if ("pca", against) not in rows:
            continue
        both = {r["material"] for r in rows[(kind, numbers)]} & {r["material"] for r in rows[("pca", against)]}
        a = summary([r for r in rows[(kind, numbers)] if r["material"] in both], scenes)
        b = summary([r for r in rows[("pca", against)] if r["material"] in both], scenes)
        worst = min(scenes, key=lambda sc: a["scenes"][sc] - b["scenes"][sc])
        out.append(f"* {kind} at {numbers} numbers ({len(both)} materials with both): {a['psnr'] - b['psnr']:+.2f} dB "
                   f"over PCA-{against // 3} ({against} numbers) in the mean, "
                   f"{a['scenes'][worst] - b['scenes'][worst]:+.2f} in its worst scene ({worst}); Delta E "
                   f"{a['delta_e']:.3f} against {b['delta_e']:.3f}")
    return out


def plot(sets: dict, path: str) -> None:
    from brdfkit.figures.canvas import pyplot, save_png

    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(10, 4), dpi=100)
    for name, (rows, scenes) in sets.items():
        for kind, style in (("residual", "-D"), ("basis", "-o"), ("pca", "--s"), ("hypernet", ":^")):
            pts = sorted((n, summary(r, scenes)) for (k, n), r in rows.items() if k == kind)
            if pts:
                x = [n for n, _ in pts]
                axes[0].plot(x, [s["psnr"] for _, s in pts], style, label=f"{name}: {kind}")
                axes[1].plot(x, [s["delta_e"] for _, s in pts], style, label=f"{name}: {kind}")
    for ax, what in zip(axes, ("PSNR (dB), mean of the six scenes", "Delta E 2000")):
        ax.set_xlabel("numbers per material")
        ax.set_ylabel(what)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7)
    fig.tight_layout()
    save_png(fig, path)


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("sets", nargs="+", help="NAME=FOLDER of a compression bench")
    ap.add_argument("--plot", default=None)
    a = ap.parse_args(sys.argv[1:] if argv is None else argv)
    sets = {}
    for spec in a.sets:
        name, folder = spec.split("=", 1)
        sets[name] = rows_of(folder)
    print("\n".join(table(sets)))
    if a.plot:
        plot(sets, a.plot)


if __name__ == "__main__":
    main()
