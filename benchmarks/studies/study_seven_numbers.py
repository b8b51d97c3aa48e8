"""Decided: no design of 7 numbers over the basis replaces the 7-D latent (``merl-rgl-l7``)
yet: the best, three components a channel with the third tied across the channels, renders
1 dB under three free ones (9 numbers) as projections, and the shipped residual at 9
numbers renders 2.1 dB under the 7-D latent on materials both were trained on. Reported in
``docs/notes/compression.md``, "A 7-number embedding".

Projections of tables onto a basis's leading components with some coefficients tied across
the colour channels (one value for all three), in the six judged scenes at 32 px:
``K2-6`` (two components, 6 numbers), ``K3tied-7`` (three, the third tied: 7), ``K5c1-7``
(five, the first free and four tied: 7), ``K3-9`` (three free: 9). The least squares is
solved exactly for the tied unknowns.

    python benchmarks/studies/study_seven_numbers.py merl-rgl-basis.safetensors runs/all --every 5 -o seven.json
"""

from __future__ import annotations

import argparse
import json
import os
import sys

import numpy as np

DESIGNS = {"K2-6": (2, 2), "K3tied-7": (3, 2), "K5c1-7": (5, 1), "K3-9": (3, 3)}
"""``{name: (components, free a channel)}``: the rest of the components are tied."""


def tied_projection(part, y, free: int) -> np.ndarray:
    """Coefficients ``(K, 3)`` minimising ``|y - U^T c|^2`` over the cells where ``y (P, 3)``
    (mapped, less the mean) is finite, the leading ``free`` components per channel and the
    rest one value for all three."""
    u = part.components.astype(np.float64)
    ok = np.isfinite(y).all(1)
    u, y = u[:, ok], y[ok]
    k = u.shape[0]
    g, r = u @ u.T, u @ y
    n = 3 * free + (k - free)

    def idx(j, ch):
        return ch * free + j if j < free else 3 * free + (j - free)

    a, b = np.zeros((n, n)), np.zeros(n)
    for ch in range(3):
        for j in range(k):
            b[idx(j, ch)] += r[j, ch]
            for m in range(k):
                a[idx(j, ch), idx(m, ch)] += g[j, m]
    x = np.linalg.solve(a, b)
    return np.array([[x[idx(j, ch)] for ch in range(3)] for j in range(k)])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("basis")
    ap.add_argument("folder")
    ap.add_argument("--every", type=int, default=5)
    ap.add_argument("-o", "--output", required=True)
    a = ap.parse_args(sys.argv[1:] if argv is None else argv)
    from brdfkit.basis import load_basis
    from brdfkit.io.merl import read_merl
    from brdfkit.render.scene_suite import SUITE, scene_env
    from brdfkit.render.screen import screen, screen_psnr

    basis = load_basis(a.basis)
    screens = {s: screen(None, 32, env=scene_env(s)) for s in SUITE}
    names = sorted(f[:-7] for f in os.listdir(a.folder) if f.endswith(".binary"))[::a.every]
    out = {}
    for name in names:
        table = read_merl(os.path.join(a.folder, name + ".binary"))
        refs = {s: sc.render_table(table) for s, sc in screens.items()}
        out[name] = {}
        for label, (k, free) in DESIGNS.items():
            part = basis.leading(k)
            c = tied_projection(part, part.mapped_table(table) - part.mean[:, None], free)
            dec = part.decode(c)
            out[name][label] = float(np.mean([screen_psnr(sc.render_table(dec), refs[s]) for s, sc in screens.items()]))
        print(name, " ".join(f"{k} {v:.2f}" for k, v in out[name].items()), file=sys.stderr, flush=True)
    doc = {"basis": os.path.basename(a.basis), "materials": out, "resolution": 32,
           "mean": {k: float(np.mean([m[k] for m in out.values()])) for k in DESIGNS}}
    with open(a.output, "w", encoding="utf-8") as f:
        json.dump(doc, f, indent=1)
    print(" ".join(f"{k} {v:.2f}" for k, v in doc["mean"].items()))


if __name__ == "__main__":
    main()
