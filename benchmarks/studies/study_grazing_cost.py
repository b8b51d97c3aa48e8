"""Where the grazing mapping's renders went (issue 56, item 1): the projections of the old
``merl80`` basis (Nielsen's mapping, before issue 50) and of today's (the resolution share
``kappa = 0.03``, ``eps_share``) scored side by side in the six judged scenes, the render
change attributed to regions of the table and to the component count. Decides nothing by
itself; reported in ``docs/notes/compression.md``, "Where the grazing mapping's renders
went".

For each of the 20 unseen MERL test proxies and every ``--every``-th RGL proxy:

* the least-squares projection (:meth:`brdfkit.basis.model.PcaBasis.project`, what ``brdfkit
  bench``'s ``basis-K`` entries run) onto the ``K`` leading components of each basis, ``K
  = 1 .. --sweep`` (the size where the old-new gap opens), decoded by each basis;
* renders in the six judged scenes at ``--resolution`` px, scored as ``brdfkit bench
  --scenes all`` scores them (:meth:`brdfkit.bench.worker.Worker.render`,
  :func:`brdfkit.evaluation.metrics.score` per scene, their mean);
* region swaps at each ``-k``: today's decode with the old decode's values put back in one
  region of the table at a time (``grazing``: ``theta_h >= 80 deg``, rows 85 to 89;
  ``60-80``: rows 74 to 84; ``peak``: ``theta_h < 2 deg``, rows 0 to 13; ``rest``: rows 14
  to 73; and ``share``: the cells whose mapping the share changed, ``x_ref < eps``), so
  that ``swap - new`` is what that region's change cost (positive: the old values
  rendered better there);
* per region, each decode's median decoded / true ratio;
* at ``--full-resolution`` px, the ``--full-k`` case again (old, new, swaps);
* once, per component: the old and new component's cosine and each one's share of its
  energy in each region, and the overlap of the leading subspaces.

With ``--encode SIZES``, the same for ``merl80-l40``'s default ``encode`` (the residual
kind) in place of the projection: each table encoded and decoded with the old bundle's
residual and basis (``--old-rev``) and with today's, each with and without the refinement
on renders (``encode_with(..., refine=False)``: projection and fit through the
correction), scored and swapped by region at ``--resolution`` px.

    python benchmarks/studies/study_grazing_cost.py --old-rev 8c3b76b --merl proxies/merl \\
        --test-list ../shared/data/merl-test.txt --rgl proxies/rgl --every 3 --jobs 2 \\
        -o benchmarks/results/2026-12-01-grazing-cost-64.json
    python benchmarks/studies/study_grazing_cost.py --encode 21 39 --old-rev 8c3b76b --merl proxies/merl \\
        --test-list ../shared/data/merl-test.txt --rgl proxies/rgl --every 3 --jobs 1 --full-resolution 0 \\
        --resolution 32 -o benchmarks/results/2026-12-02-grazing-cost-encode-32.json
"""

from __future__ import annotations

import argparse
import concurrent.futures
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

ROWS = {"grazing": (85, 90), "60-80": (74, 85), "peak": (0, 14), "rest": (14, 74)}
"""Regions of ``theta_h`` rows ``[first, last)`` (row ``i`` at ``(i / 90)^2 90 deg``)."""
REGIONS = (*ROWS, "share")
NEW_BASIS = "brdfkit/models/merl80-basis.safetensors"
NEW_RESIDUAL = "brdfkit/models/merl80-residual.safetensors"

_STATE: dict = {}


def _old_basis(rev: str, folder: str) -> str:
    """The ``merl80`` basis file of a git revision, written to ``folder``."""
    out = os.path.join(folder, f"merl80-basis-{rev}.safetensors")
    with open(out, "wb") as f:
        subprocess.run(["git", "show", f"{rev}:{NEW_BASIS}"], stdout=f, check=True)
    return out


def _old_residual(rev: str, folder: str) -> str:
    """The ``merl80`` residual file of a git revision, written to ``folder`` with the basis
    it corrects beside it under the name its header records."""
    from brdfkit.residual.residual_file import read_header

    out = os.path.join(folder, "merl80-residual.safetensors")
    with open(out, "wb") as f:
        subprocess.run(["git", "show", f"{rev}:{NEW_RESIDUAL}"], stdout=f, check=True)
    with open(os.path.join(folder, read_header(out)["basis_file"]), "wb") as f:
        subprocess.run(["git", "show", f"{rev}:{NEW_BASIS}"], stdout=f, check=True)
    return out


def _masks(basis) -> dict:
    """``{region: bool (90, 90, 180)}``."""
    from brdfkit.basis.mapping import EPS
    from brdfkit.geometry import GRID_SHAPE, N_CELLS

    out = {}
    for name, (a, b) in ROWS.items():
        m = np.zeros(GRID_SHAPE, bool)
        m[a:b] = True
        out[name] = m
    share = np.zeros(N_CELLS, bool)
    share[basis.cells[basis.reference < EPS]] = True
    out["share"] = share.reshape(GRID_SHAPE)
    return out


def _init(old_path, new_path, resolutions, residuals=None):
    from brdfkit.basis.basis_file import load_basis
    from brdfkit.bench.config import BenchConfig
    from brdfkit.bench.worker import Worker
    from brdfkit.render.scene_suite import SUITE
    from brdfkit.runtime import set_cpu_threads, set_torch_threads

    set_torch_threads(1)
    set_cpu_threads(1)
    _STATE["bases"] = {"old": load_basis(old_path), "new": load_basis(new_path)}
    _STATE["workers"] = {r: Worker(BenchConfig(output=tempfile.gettempdir(), scenes=tuple(SUITE), resolution=r,
                                               threads=1)) for r in resolutions}
    _STATE["masks"] = _masks(_STATE["bases"]["new"])
    if residuals:
        from brdfkit.embeddings import load_decoder

        _STATE["decoders"] = {which: load_decoder("residual", path, "cpu") for which, path in residuals.items()}


def _scores(worker, table, refs) -> dict:
    """The judged scenes' scores of a table, as ``brdfkit bench --scenes all`` records them
    (each scene's, and their mean)."""
    from brdfkit.evaluation.comparison import mean_scores
    from brdfkit.evaluation.metrics import score

    imgs = worker.render(table)
    per = {s: score(imgs[s], refs[s]) for s in imgs}
    mean = mean_scores(list(per.values()))
    return {"psnr": mean["psnr"], "delta_e": mean["delta_e"],
            "scenes": {s: {"psnr": r["psnr"], "delta_e": r["delta_e"]} for s, r in per.items()}}


def _ratios(pred, ref, masks) -> dict:
    """``{region: median decoded / true ratio}`` over the cells and channels where the
    truth is positive."""
    out = {}
    ok = np.isfinite(pred) & np.isfinite(ref) & (ref > 0)
    for name, m in masks.items():
        sel = ok & m[..., None]
        out[name] = float(np.median(pred[sel] / ref[sel])) if sel.any() else None
    return out


def _material(task) -> dict:
    lab, name, path, ks, sweep, res, full_res, full_k = task
    from brdfkit.io.merl import read_merl

    t0 = time.time()
    table = read_merl(path)
    bases, workers, masks = _STATE["bases"], _STATE["workers"], _STATE["masks"]
    w = workers[res]
    refs = w.render(table)
    rec = {"lab": lab, "material": name, "sweep": {"old": {}, "new": {}}, "swaps": {}, "ratios": {}}
    decoded = {}
    for which, basis in bases.items():
        for k in range(1, sweep + 1):
            part = basis.leading(k)
            dec = part.decode(part.project(table))
            rec["sweep"][which][str(k)] = _scores(w, dec, refs)
            if k in ks or k == full_k:
                decoded[which, k] = dec
                rec["ratios"].setdefault(which, {})[str(k)] = _ratios(dec, table, masks)
    for k in ks:
        rec["swaps"][str(k)] = {}
        for region, m in masks.items():
            swap = decoded["new", k].copy()
            swap[m] = decoded["old", k][m]
            rec["swaps"][str(k)][region] = _scores(w, swap, refs)
    if full_res:
        wf = workers[full_res]
        frefs = wf.render(table)
        full = {which: _scores(wf, decoded[which, full_k], frefs) for which in bases}
        full["swaps"] = {}
        for region, m in masks.items():
            swap = decoded["new", full_k].copy()
            swap[m] = decoded["old", full_k][m]
            full["swaps"][region] = _scores(wf, swap, frefs)
        rec["full"] = full
    rec["seconds"] = time.time() - t0
    return rec


def _encoded(task) -> dict:
    """One material through ``merl80-l40``'s residual encode, old and new (``--encode``)."""
    lab, name, path, sizes, res = task
    from brdfkit.embeddings import encode_with, open_embedding
    from brdfkit.io.merl import read_merl

    t0 = time.time()
    table = read_merl(path)
    w, masks, decs = _STATE["workers"][res], _STATE["masks"], _STATE["decoders"]
    refs = w.render(table)
    rec = {"lab": lab, "material": name, "encode": {}, "unrefined": {}, "swaps": {}, "ratios": {}, "chosen": {}}
    for size in sizes:
        k = str(size)
        decoded = {}
        for which, dec in decs.items():
            for refine, into in ((False, "unrefined"), (True, "encode")):
                emb = encode_with(dec, table, source=name, size=size, refine=refine)
                tab = open_embedding(emb, dec, name).to_table()
                rec[into].setdefault(which, {})[k] = _scores(w, tab, refs)
                if refine:
                    decoded[which] = tab
                    rec["ratios"].setdefault(which, {})[k] = _ratios(tab, table, masks)
                    rec["chosen"].setdefault(which, {})[k] = emb.options
        rec["swaps"][k] = {}
        for region, m in masks.items():
            swap = decoded["new"].copy()
            swap[m] = decoded["old"][m]
            rec["swaps"][k][region] = _scores(w, swap, refs)
    rec["seconds"] = time.time() - t0
    return rec


def summarise_encode(doc) -> dict:
    """Per lab and size: old and new encode (refined and not), the gap, each scene's gap,
    the region swaps and the materials that lose most."""
    out = {}
    scenes = doc["scenes"]
    for lab in sorted({r["lab"] for r in doc["materials"].values()}):
        recs = [r for r in doc["materials"].values() if r["lab"] == lab]
        s = {"count": len(recs)}
        for k in map(str, doc["encode"]):
            row = {}
            for into in ("unrefined", "encode"):
                for which in ("old", "new"):
                    row[f"{into}_{which}"] = {m: _mean([r[into][which][k][m] for r in recs]) for m in ("psnr", "delta_e")}
                    row[f"{into}_{which}"]["scenes"] = {
                        sc: _mean([r[into][which][k]["scenes"][sc]["psnr"] for r in recs]) for sc in scenes}
            row["gap"] = row["encode_new"]["psnr"] - row["encode_old"]["psnr"]
            row["gap_unrefined"] = row["unrefined_new"]["psnr"] - row["unrefined_old"]["psnr"]
            row["swaps"] = {reg: _mean([r["swaps"][k][reg]["psnr"] - r["encode"]["new"][k]["psnr"] for r in recs])
                            for reg in REGIONS}
            row["swap_scenes"] = {
                reg: {sc: _mean([r["swaps"][k][reg]["scenes"][sc]["psnr"] - r["encode"]["new"][k]["scenes"][sc]["psnr"]
                                 for r in recs]) for sc in scenes} for reg in REGIONS}
            row["ratios"] = {which: {reg: _mean([r["ratios"][which][k][reg] for r in recs]) for reg in REGIONS}
                             for which in ("old", "new")}
            gaps = sorted((r["encode"]["new"][k]["psnr"] - r["encode"]["old"][k]["psnr"], r["material"]) for r in recs)
            row["worst"] = [{"material": n, "gap": g} for g, n in gaps[:5]]
            s[k] = row
        out[lab] = s
    return out


def report_encode(doc) -> str:
    lines = []
    for lab, s in doc["summary"].items():
        lines.append(f"\n## {lab} ({s['count']} materials), encode, {doc['resolution']} px, six scenes")
        lines.append("| numbers | unrefined old | new | gap | encode old | new | gap | dE old | dE new | "
                     + " | ".join(doc["scenes"]) + " |")
        lines.append("| --- " * (9 + len(doc["scenes"])) + "|")
        for k in map(str, doc["encode"]):
            r = s[k]
            per = " | ".join(f"{r['encode_new']['scenes'][sc] - r['encode_old']['scenes'][sc]:+.2f}" for sc in doc["scenes"])
            lines.append(f"| {k} | {r['unrefined_old']['psnr']:.2f} | {r['unrefined_new']['psnr']:.2f} | "
                         f"{r['gap_unrefined']:+.2f} | {r['encode_old']['psnr']:.2f} | {r['encode_new']['psnr']:.2f} | "
                         f"{r['gap']:+.2f} | {r['encode_old']['delta_e']:.3f} | {r['encode_new']['delta_e']:.3f} | {per} |")
        lines.append("\nswap (old values back in one region) - new, PSNR dB:")
        lines.append("| numbers | " + " | ".join(REGIONS) + " |")
        for k in map(str, doc["encode"]):
            lines.append(f"| {k} | " + " | ".join(f"{s[k]['swaps'][r]:+.3f}" for r in REGIONS) + " |")
        for k in map(str, doc["encode"]):
            lines.append(f"{k} numbers, lose most: " + ", ".join(f"{w['material']} {w['gap']:+.2f}" for w in s[k]["worst"]))
    return "\n".join(lines)


def brightness(doc, merl: str, rgl: str, new_path: str) -> str:
    """Per material of a projection record: the median of its weighted value over the
    reference, ``x / x_ref``, at the cells whose mapping the share changed (``x_ref <
    eps``, channels averaged), beside its old-new gap at the largest swept ``K`` and what
    the old values put back in those cells gained; Spearman's rank correlation of each with
    the logarithm of the ratio (``--brightness``, reads the tables again)."""
    from scipy.stats import spearmanr

    from brdfkit.basis.basis_file import load_basis
    from brdfkit.basis.mapping import EPS
    from brdfkit.geometry import N_CELLS
    from brdfkit.io.merl import read_merl

    basis = load_basis(new_path)
    share = basis.reference < EPS
    cells, ref, w = basis.cells[share], basis.reference[share].astype(np.float64), basis.cell_weight()[share]
    k = str(doc["sweep"])
    rows = []
    for r in doc["materials"].values():
        table = read_merl(os.path.join(merl if r["lab"] == "merl-test" else rgl, r["material"] + ".binary"))
        x = table.reshape(N_CELLS, 3)[cells].mean(axis=1) * w
        new = r["sweep"]["new"][k]["psnr"]
        rows.append((float(np.nanmedian(x / ref)), new - r["sweep"]["old"][k]["psnr"],
                     r["swaps"][k]["share"]["psnr"] - new, f"{r['lab']}:{r['material']}"))
    rows.sort()
    lines = [f"| material | median x / x_ref (share cells) | gap at K = {k} | share swap |", "| --- | ---: | ---: | ---: |"]
    lines += [f"| {n} | {ratio:.2f} | {gap:+.2f} | {swap:+.2f} |" for ratio, gap, swap, n in rows]
    logr = np.log(np.maximum([r[0] for r in rows], 1e-3))
    for i, what in ((1, "gap"), (2, "share swap")):
        rho, p = spearmanr(logr, [r[i] for r in rows])
        lines.append(f"Spearman({what}, log ratio) = {rho:+.2f} (p = {p:.3f}, {len(rows)} materials)")
    return "\n".join(lines)


def _components(old, new, sweep, masks) -> dict:
    """Per component: the cosine of the old and new ``k``-th components and each one's
    share of its squared norm in each region; the overlap of the leading ``k``-dimensional
    subspaces (mean squared cosine of their principal angles)."""
    from brdfkit.geometry import N_CELLS

    uo = old.leading(sweep).components.astype(np.float64)
    un = new.leading(sweep).components.astype(np.float64)
    where = {r: m.reshape(N_CELLS)[new.cells] for r, m in masks.items()}
    out = {"cells": {r: float(m.mean()) for r, m in where.items()}, "k": {}}
    qo, qn = np.linalg.qr(uo.T)[0], np.linalg.qr(un.T)[0]  # nested: a stored basis is orthonormal to 1e-3
    for k in range(sweep):
        a, b = uo[k], un[k]
        s = np.linalg.svd(qo[:, :k + 1].T @ qn[:, :k + 1], compute_uv=False)
        out["k"][str(k + 1)] = {
            "cosine": float(abs(a @ b) / np.sqrt((a @ a) * (b @ b))),
            "subspace_overlap": float(np.mean(s ** 2)),
            "energy_old": {r: float((a[m] ** 2).sum() / (a @ a)) for r, m in where.items()},
            "energy_new": {r: float((b[m] ** 2).sum() / (b @ b)) for r, m in where.items()}}
    return out


def _mean(xs):
    xs = [x for x in xs if x is not None]
    return float(np.mean(xs)) if xs else None


def summarise(doc) -> dict:
    """Per lab: the means of every row (old, new, gap; per scene; per swap; per ``K`` of
    the sweep) and the materials that lose most."""
    out = {}
    scenes = doc["scenes"]
    for lab in sorted({r["lab"] for r in doc["materials"].values()}):
        recs = [r for r in doc["materials"].values() if r["lab"] == lab]
        s = {"count": len(recs), "sweep": {}, "swaps": {}, "worst": {}}
        for k in map(str, range(1, doc["sweep"] + 1)):
            row = {}
            for which in ("old", "new"):
                row[which] = {m: _mean([r["sweep"][which][k][m] for r in recs]) for m in ("psnr", "delta_e")}
                row[which]["scenes"] = {sc: _mean([r["sweep"][which][k]["scenes"][sc]["psnr"] for r in recs])
                                        for sc in scenes}
            row["gap"] = row["new"]["psnr"] - row["old"]["psnr"]
            s["sweep"][k] = row
        for k in map(str, doc["k"]):
            s["swaps"][k] = {reg: _mean([r["swaps"][k][reg]["psnr"] - r["sweep"]["new"][k]["psnr"] for r in recs])
                             for reg in REGIONS}
            s["swaps"][k]["scenes"] = {
                reg: {sc: _mean([r["swaps"][k][reg]["scenes"][sc]["psnr"] - r["sweep"]["new"][k]["scenes"][sc]["psnr"]
                                 for r in recs]) for sc in scenes} for reg in REGIONS}
            gaps = sorted((r["sweep"]["new"][k]["psnr"] - r["sweep"]["old"][k]["psnr"], r["material"]) for r in recs)
            s["worst"][k] = [{"material": n, "gap": g} for g, n in gaps[:5]]
            s["ratios_" + k] = {which: {reg: _mean([r["ratios"][which][k][reg] for r in recs]) for reg in REGIONS}
                                for which in ("old", "new")}
        full = [r["full"] for r in recs if "full" in r]
        if full:
            s["full"] = {"count": len(full)}
            for which in ("old", "new"):
                s["full"][which] = {m: _mean([f[which][m] for f in full]) for m in ("psnr", "delta_e")}
                s["full"][which]["scenes"] = {sc: _mean([f[which]["scenes"][sc]["psnr"] for f in full])
                                              for sc in scenes}
            s["full"]["swaps"] = {reg: _mean([f["swaps"][reg]["psnr"] - f["new"]["psnr"] for f in full])
                                  for reg in REGIONS}
            s["full"]["swap_scenes"] = {
                reg: {sc: _mean([f["swaps"][reg]["scenes"][sc]["psnr"] - f["new"]["scenes"][sc]["psnr"] for f in full])
                      for sc in scenes} for reg in REGIONS}
        out[lab] = s
    return out


def report(doc) -> str:
    summ = doc["summary"]
    lines = []
    for lab, s in summ.items():
        lines.append(f"\n## {lab} ({s['count']} materials), {doc['resolution']} px, six scenes")
        lines.append("| K | numbers | old PSNR | new PSNR | gap | old dE | new dE | " +
                     " | ".join(doc["scenes"]) + " |")
        lines.append("| --- " * (7 + len(doc["scenes"])) + "|")
        for k, row in s["sweep"].items():
            per = " | ".join(f"{row['new']['scenes'][sc] - row['old']['scenes'][sc]:+.2f}" for sc in doc["scenes"])
            lines.append(f"| {k} | {3 * int(k)} | {row['old']['psnr']:.2f} | {row['new']['psnr']:.2f} | "
                         f"{row['gap']:+.2f} | {row['old']['delta_e']:.3f} | {row['new']['delta_e']:.3f} | {per} |")
        lines.append("\nswap (old values back in one region) - new, PSNR dB:")
        lines.append("| K | " + " | ".join(REGIONS) + " |")
        for k, row in s["swaps"].items():
            lines.append(f"| {k} | " + " | ".join(f"{row[r]:+.3f}" for r in REGIONS) + " |")
        for k, worst in s["worst"].items():
            lines.append(f"K={k} lose most: " + ", ".join(f"{w['material']} {w['gap']:+.2f}" for w in worst))
        if "full" in s:
            f = s["full"]
            lines.append(f"\nK={doc['full_k']} at {doc['full_resolution']} px ({f['count']}): old {f['old']['psnr']:.2f} "
                         f"new {f['new']['psnr']:.2f} (dE {f['old']['delta_e']:.3f} / {f['new']['delta_e']:.3f}); swaps: "
                         + ", ".join(f"{r} {v:+.3f}" for r, v in f["swaps"].items()))
    return "\n".join(lines)


def compare(before: str, after: str) -> str:
    """Two ``brdfkit bench`` compression records side by side: for each size both ran, the
    mean PSNR, Delta E and each scene's PSNR over the materials both scored, the change,
    and the materials that lost most (item (A) of the study: today's ``merl80-l40``
    residual against the record before issue 50)."""
    docs = [json.load(open(p, encoding="utf-8")) for p in (before, after)]

    def rows(doc):
        out = {}
        for r in doc["records"]:
            if r.get("kind") == "compression" and "error" not in r and r["method"].startswith("residual-"):
                out.setdefault(int(r["size"]), {})[r["material"]] = r
        return out

    a, b = rows(docs[0]), rows(docs[1])
    scenes = docs[1]["config"]["scenes"]
    lines = ["| numbers | materials | before PSNR | after | change | before dE | after dE | "
             + " | ".join(scenes) + " |", "| --- " * (7 + len(scenes)) + "|"]
    worst = []
    for size in sorted(set(a) & set(b)):
        common = sorted(set(a[size]) & set(b[size]))
        ra, rb = [a[size][m] for m in common], [b[size][m] for m in common]
        pa, pb = np.mean([r["psnr"] for r in ra]), np.mean([r["psnr"] for r in rb])
        da, db = np.mean([r["delta_e"] for r in ra]), np.mean([r["delta_e"] for r in rb])
        per = " | ".join(f"{np.mean([y['scenes'][sc]['psnr'] - x['scenes'][sc]['psnr'] for x, y in zip(ra, rb)]):+.2f}"
                         for sc in scenes)
        lines.append(f"| {size} | {len(common)} | {pa:.2f} | {pb:.2f} | {pb - pa:+.2f} | {da:.3f} | {db:.3f} | {per} |")
        d = sorted((y["psnr"] - x["psnr"], m) for m, x, y in zip(common, ra, rb))
        worst.append(f"{size} numbers, lost most: " + ", ".join(f"{m} {g:+.2f}" for g, m in d[:6])
                     + "; gained most: " + ", ".join(f"{m} {g:+.2f}" for g, m in d[-3:])
                     + f"; {sum(g < 0 for g, _ in d)} of {len(d)} lower")
    return "\n".join(lines + [""] + worst)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--old-rev", default="8c3b76b", help="git revision whose merl80 basis is the old one")
    ap.add_argument("--old", default=None, help="the old basis file instead of --old-rev")
    ap.add_argument("--new", default=NEW_BASIS)
    ap.add_argument("--merl", default="proxies/merl")
    ap.add_argument("--test-list", default="../shared/data/merl-test.txt")
    ap.add_argument("--rgl", default="proxies/rgl")
    ap.add_argument("--every", type=int, default=3, help="every N-th RGL proxy in name order")
    ap.add_argument("--offset", type=int, default=0, help="the first RGL proxy of --every (0 .. every - 1)")
    ap.add_argument("--first", type=int, default=None, help="the first N materials of each lab only (a test)")
    ap.add_argument("-k", type=int, nargs="+", default=[3, 7, 13], help="component counts of the swaps")
    ap.add_argument("--sweep", type=int, default=13, help="K = 1 .. this, old and new")
    ap.add_argument("--resolution", type=int, default=64)
    ap.add_argument("--full-resolution", type=int, default=128, help="0: none")
    ap.add_argument("--full-k", type=int, default=13)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--encode", type=int, nargs="+", default=None,
                    help="sizes of merl80-l40's residual encode to compare (old and new) instead of the projections")
    ap.add_argument("--new-residual", default=NEW_RESIDUAL)
    ap.add_argument("--report", action="store_true", help="only print the tables of the record -o")
    ap.add_argument("--brightness", action="store_true",
                    help="only print, per material of the projection record -o, its brightness over the reference "
                         "at the cells the share changed beside its gap and share swap")
    ap.add_argument("--compare", nargs=2, metavar=("BEFORE", "AFTER"),
                    help="only compare two brdfkit bench records' residual rows (no -o)")
    ap.add_argument("-o", "--output")
    a = ap.parse_args(sys.argv[1:] if argv is None else argv)
    if a.compare:
        print(compare(*a.compare))
        return
    if not a.output:
        ap.error("-o is required")
    if a.report:
        doc = json.load(open(a.output, encoding="utf-8"))
        print(report_encode(doc) if doc.get("encode") else report(doc))
        return
    if a.brightness:
        print(brightness(json.load(open(a.output, encoding="utf-8")), a.merl, a.rgl, a.new))
        return
    from brdfkit.basis.basis_file import load_basis
    from brdfkit.render.scene_suite import SUITE

    tmp = tempfile.mkdtemp(prefix="grazing-cost-")
    old_path = a.old or _old_basis(a.old_rev, tmp)
    test = open(a.test_list, encoding="utf-8").read().split()
    items = [("merl-test", n, os.path.join(a.merl, n + ".binary")) for n in test][:a.first]
    if a.rgl:
        names = sorted(f[:-7] for f in os.listdir(a.rgl) if f.endswith(".binary"))[a.offset::a.every]
        items += [("rgl", n, os.path.join(a.rgl, n + ".binary")) for n in names][:a.first]
    old, new = load_basis(old_path), load_basis(a.new)
    residuals = None
    if a.encode:
        residuals = {"old": _old_residual(a.old_rev, tmp), "new": a.new_residual}
    doc = {"format": "brdfkit-study-grazing-cost", "command": "python " + " ".join(sys.argv),
           "encode": a.encode, "new_residual": a.new_residual if a.encode else None,
           "old": {"rev": None if a.old else a.old_rev, "file": NEW_BASIS if not a.old else a.old,
                   "mapping": old.mapping.record()},
           "new": {"file": a.new, "mapping": new.mapping.record()},
           "k": a.k, "sweep": a.sweep, "resolution": a.resolution, "full_resolution": a.full_resolution or None,
           "full_k": a.full_k, "scenes": list(SUITE), "regions": {**{r: list(v) for r, v in ROWS.items()},
                                                                  "share": "cells with x_ref < eps"},
           "every": a.every, "offset": a.offset, "cpus": os.cpu_count(), "load_start": os.getloadavg(), "started": time.strftime("%FT%T"),
           "components": _components(old, new, a.sweep, _masks(new)), "materials": {}}
    del old, new
    res = [a.resolution] + ([a.full_resolution] if a.full_resolution else [])
    if a.encode:
        tasks = [(lab, n, p, a.encode, a.resolution) for lab, n, p in items]
        run, summ, rep = _encoded, summarise_encode, report_encode
    else:
        tasks = [(lab, n, p, a.k, a.sweep, a.resolution, a.full_resolution or None, a.full_k) for lab, n, p in items]
        run, summ, rep = _material, summarise, report
    t0 = time.time()
    with concurrent.futures.ProcessPoolExecutor(a.jobs, initializer=_init,
                                                initargs=(old_path, a.new, res, residuals)) as ex:
        futures = [ex.submit(run, t) for t in tasks]
        for i, fut in enumerate(concurrent.futures.as_completed(futures), 1):
            rec = fut.result()
            doc["materials"][f"{rec['lab']}:{rec['material']}"] = rec
            doc["elapsed_s"], doc["load_end"] = time.time() - t0, os.getloadavg()
            doc["complete"] = i == len(tasks)
            doc["summary"] = summ(doc)
            with open(a.output + ".tmp", "w", encoding="utf-8") as f:
                json.dump(doc, f, indent=1)
            os.replace(a.output + ".tmp", a.output)
            print(f"[{i}/{len(tasks)}] {rec['lab']} {rec['material']} {rec['seconds']:.0f} s", flush=True)
    print(rep(doc))


if __name__ == "__main__":
    main()
