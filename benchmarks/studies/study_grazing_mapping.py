"""Decided: the built-ins' bases map with a resolution share at grazing cells
(``LogMapping(0.03)``, ``-O eps_share=0.03``): the grazing rows follow the material in 18 to
19 of the 20 unseen MERL test materials (12 to 13 with Nielsen's mapping), renders of the
projections within -0.2 to +0.35 dB of Nielsen's; the shape that leaves every cell with
``x_ref >= eps`` alone (``e = clip(x_ref max(kappa, x_ref / eps), ., eps)``) over one that
changes 40% of the cells (``e = min(eps, kappa x_ref)``, ``--power 0``), which cost up to
2 dB on some materials; and the decode's lower bound, half a percent of the reference
(``--share-floor``). Reported in ``docs/notes/compression.md``, "Grazing rows".

Bases of 30 components fitted on the 80 MERL training proxies with each mapping (all with
the shipped ``w_floor = 0.005``), then, for the 20 unseen MERL test proxies and every
``--every``-th RGL proxy: the least-squares projection onto the ``K`` leading components
and (MERL) a ridge fit of all 30 to 400 uniform samples, scored by

* the six judged scenes' render PSNR at the render-aligned error's 32 px
  (:mod:`brdfkit.render.screen`);
* the median decoded / true ratio over the cells with ``theta_h >= 80 deg`` (the grazing
  rows) and the share of the positive cells decoded below 1% of their value.

A variant is ``SHARE:POWER``: ``0:1`` Nielsen's mapping; ``0.03:1`` the shipped shape;
``K:2`` a resolution falling as ``(x_ref / eps)^2``; ``K:0`` ``e = min(eps, K x_ref)``.

    python benchmarks/studies/study_grazing_mapping.py --train proxies/merl --test-list ../shared/data/merl-test.txt \\
        --rgl proxies/rgl --every 3 --variants 0:1 0.03:1 0.01:2 -o grazing-mapping.json
"""

from __future__ import annotations

import argparse
import json
import os
import sys

import numpy as np


def _mapping(spec: str, share_floor: float):
    """The :class:`~brdfkit.basis.mapping.LogMapping` of a variant ``SHARE:POWER``."""
    import brdfkit.basis.mapping as m

    share, power = (float(x) for x in spec.split(":"))
    if share == 0:
        return m.NIELSEN
    if power == 1 and share_floor == m.SHARE_FLOOR:
        return m.LogMapping(share)

    class Variant(m.LogMapping):
        def resolution(self, reference):
            reference = np.asarray(reference, np.float64)
            rel = np.full_like(reference, share) if power == 0 else np.maximum((reference / m.EPS) ** power, share)
            e = np.clip(reference * rel, m.E_MIN, m.EPS)
            return e, (reference + e) / (reference + m.EPS)

        def lower_bound(self, reference, weight, floor=m.FLOOR):
            return (np.minimum(share_floor * np.asarray(reference, np.float64), m.CAP)
                    + m.E_MIN * np.minimum(weight / 0.005, 1.0))

    return Variant(share)


def _grazing(pred, ref):
    """``(median ratio at theta_h >= 80 deg, share of positive cells below 1%)``."""
    from brdfkit.evaluation.metrics import grazing_ratio

    allok = np.isfinite(pred) & np.isfinite(ref) & (ref > 0)
    return grazing_ratio(pred, ref), float((pred[allok] < 0.01 * ref[allok]).mean())


def _score(table, bases, ks, screens, ridge):
    from brdfkit.acquisition.sampling import draw_samples
    from brdfkit.render.screen import screen_psnr

    refs = {s: sc.render_table(table) for s, sc in screens.items()}
    out = {}
    for spec, basis in bases.items():
        for k in [*ks, "ridge400"] if ridge else ks:
            if k == "ridge400":
                dec = basis.reconstruct(draw_samples(table, 400, seed=0))
            else:
                part = basis.leading(k)
                dec = part.decode(part.project(table))
            per = {s: float(screen_psnr(sc.render_table(dec), refs[s])) for s, sc in screens.items()}
            graz, below = _grazing(dec, table)
            out[f"{spec}/{k}"] = {"psnr": float(np.mean(list(per.values()))), "scenes": per, "graz": graz,
                                  "below": below}
    return out


def _table(doc):
    rows = ["| set | numbers | variant | suite PSNR (32 px) | grazing ratio in [0.5, 2] | its range | below 1% |",
            "| --- | --- | --- | ---: | ---: | --- | ---: |"]
    for st, mats in doc["sets"].items():
        for k in [*map(str, doc["k"]), "ridge400"]:
            for spec in doc["variants"]:
                rs = [r[f"{spec}/{k}"] for r in mats.values() if f"{spec}/{k}" in r]
                if rs:
                    g = [r["graz"] for r in rs]
                    rows.append(f"| {st} ({len(rs)}) | {k} | {spec} | {np.mean([r['psnr'] for r in rs]):.2f} | "
                                f"{sum(0.5 <= x <= 2 for x in g)} | {min(g):.2f} to {max(g):.2f} | "
                                f"{100 * np.mean([r['below'] for r in rs]):.4f}% |")
    return "\n".join(rows)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--train", required=True)
    ap.add_argument("--test-list", required=True)
    ap.add_argument("--rgl", default=None)
    ap.add_argument("--every", type=int, default=3)
    ap.add_argument("--variants", nargs="+", default=["0:1", "0.03:1"])
    ap.add_argument("--share-floor", type=float, default=None)
    ap.add_argument("-k", type=int, nargs="+", default=[7, 13])
    ap.add_argument("-o", "--output", required=True)
    a = ap.parse_args(sys.argv[1:] if argv is None else argv)
    from brdfkit.basis import fit_basis
    from brdfkit.basis.mapping import SHARE_FLOOR
    from brdfkit.io.merl import read_merl
    from brdfkit.render.scene_suite import SUITE, scene_env
    from brdfkit.render.screen import screen

    floor = SHARE_FLOOR if a.share_floor is None else a.share_floor
    test = open(a.test_list, encoding="utf-8").read().split()
    train = sorted(f[:-7] for f in os.listdir(a.train) if f.endswith(".binary") and f[:-7] not in test)
    bases = {spec: fit_basis([os.path.join(a.train, n + ".binary") for n in train], 30, names=train, w_floor=0.005,
                             mapping=_mapping(spec, floor)) for spec in a.variants}
    screens = {s: screen(None, 32, env=scene_env(s)) for s in SUITE}
    items = [("merl-test", n, os.path.join(a.train, n + ".binary")) for n in test]
    if a.rgl:
        names = sorted(f[:-7] for f in os.listdir(a.rgl) if f.endswith(".binary"))[::a.every]
        items += [("rgl", n, os.path.join(a.rgl, n + ".binary")) for n in names]
    doc = {"train_count": len(train), "variants": a.variants, "k": a.k, "share_floor": floor, "resolution": 32,
           "scenes": list(SUITE), "sets": {}}
    for st, name, path in items:
        doc["sets"].setdefault(st, {})[name] = _score(read_merl(path), bases, a.k, screens, st == "merl-test")
        print(f"{st} {name}", file=sys.stderr, flush=True)
        with open(a.output + ".tmp", "w", encoding="utf-8") as f:
            json.dump(doc, f, indent=1)
        os.replace(a.output + ".tmp", a.output)
    print(_table(doc))


if __name__ == "__main__":
    main()
