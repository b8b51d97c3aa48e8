"""Decided: which lever lifts the basis residual at half the numbers (issue 45); reported in
``docs/notes/compression.md``, "Levers of the residual (study, 2026-11-28)".

Study: residuals trained by ``brdfkit fit --method residual`` with one lever changed each,
on a reduced budget, scored on materials none of them saw, in scenes none of them was
chosen by, against full-precision PCA fitted on the same tables.

The split: the 80 MERL training materials less the 16 of ``benchmarks/validation.txt``
train (64 tables); the 16 score. The 20 test materials are never read. The basis the
residuals correct is fitted on the 64 too (``prepare``), with the options of the shipped
bases, so nothing a row is scored on was seen by any of its parts.

Scoring, per material and size ``K`` (``3 K`` numbers): the projection ``c0`` decoded by the
basis alone, by basis plus correction, and coefficients fitted through the correction
(``brdfkit.residual.encoding.fit_through``) decoded with it; then the candidate an encoder
would keep (the best on the objective scenes, :data:`brdfkit.render.objective.OBJECTIVE`);
full-precision PCA of ``K`` and ``2 K`` components (``3 K`` and ``6 K`` numbers) by their
projections. No refinement on renders for any row (it adds about the same to each).
Images: the screens (:func:`brdfkit.render.screen.screen`) of the objective scenes, which
choose the lever, and of the six judged scenes, reported beside them, at ``--resolution``
px, PSNR after the metrics' display encoding against the table's own.

    python benchmarks/studies/study_residual_levers.py prepare --proxies proxies/merl -o runs/levers
    brdfkit fit --method residual proxies/merl --exclude-list runs/levers/exclude.txt \\
        -O basis=runs/levers/basis64.safetensors -O sizes=9 --steps 4000 -o runs/levers/base.safetensors
    python benchmarks/studies/study_residual_levers.py score runs/levers/base.safetensors ... \\
        --proxies proxies/merl --basis runs/levers/basis64.safetensors -k 3 -o runs/levers/score-k3.json
    python benchmarks/studies/study_residual_levers.py choose runs/levers/score-k3*.json \\
        --groups base base,cos-s1,cos-s2     # a choice per material among members
"""

from __future__ import annotations

import argparse
import json
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))

from common import load_average  # noqa: E402
from study_data import TEST_LIST, validation_materials  # noqa: E402

BASIS_OPTIONS = ["--components", "30", "-O", "half=true", "-O", "phi_stride=2", "-O", "int8=true",
                 "-O", "w_floor=0.005"]
"""The shipped bases' options (``brdfkit/models/manifest.json``)."""


def _train_names(proxies):
    held = set(TEST_LIST.read_text().split()) | set(validation_materials())
    merl = sorted(f[:-7] for f in os.listdir(proxies) if f.endswith(".binary"))
    return [n for n in merl if n not in held]


def prepare(a):
    """The exclude list (test + validation), the basis of the 64 and full PCA of each size."""
    from brdfkit.basis import fit_basis, save_basis
    from brdfkit.cli import main as brdfkit_main

    os.makedirs(a.output, exist_ok=True)
    names = _train_names(a.proxies)
    with open(os.path.join(a.output, "exclude.txt"), "w", encoding="utf-8") as f:
        f.write("\n".join(sorted(set(TEST_LIST.read_text().split()) | set(validation_materials()))) + "\n")
    basis = os.path.join(a.output, "basis64.safetensors")
    if not os.path.exists(basis):
        try:
            brdfkit_main(["fit", "--method", "basis", a.proxies, "--exclude-list",
                          os.path.join(a.output, "exclude.txt"), *BASIS_OPTIONS, "-o", basis])
        except SystemExit as e:
            if e.code:
                raise
    paths = [os.path.join(a.proxies, n + ".binary") for n in names]
    for k in a.full:
        out = os.path.join(a.output, f"full-{k}.safetensors")
        if not os.path.exists(out):
            save_basis(out, fit_basis(paths, k, names=names))
    print(f"{len(names)} training tables; basis {basis}; full PCA {a.full}")


def _screens(resolution):
    from brdfkit.render.objective import OBJECTIVE
    from brdfkit.render.scene_suite import SUITE, scene_env
    from brdfkit.render.screen import screen

    return {s: screen(None, resolution, env=scene_env(s)) for s in (*OBJECTIVE, *SUITE)}


def _candidates(residuals, part, table, k):
    """``{row: table}`` of every residual's candidates at ``K = k``."""
    from brdfkit.residual.encoding import fit_through
    from brdfkit.runtime import torch_threads

    c0 = part.project(table)
    rows = {"basis": part.decode(c0)}
    mapped = part.mapped_table(table)
    for name, res in residuals.items():
        rows[f"{name}: c0"] = res.decode(c0, 1.0)
        with torch_threads(1):
            c1 = fit_through(res, mapped, c0)
        rows[f"{name}: fitted"] = res.decode(c1, 1.0)
    return rows


def score(a):
    import torch

    from brdfkit.basis import load_basis
    from brdfkit.io.merl import read_merl
    from brdfkit.render.objective import OBJECTIVE
    from brdfkit.render.screen import screen_psnr
    from brdfkit.residual.residual_file import load_residual

    basis = load_basis(a.basis)
    part = basis.leading(a.k)
    residuals = {os.path.basename(p).rsplit(".", 1)[0]: load_residual(p) for p in a.residuals}
    full = {f"PCA-{k} ({3 * k})": load_basis(os.path.join(a.full_dir, f"full-{k}.safetensors")) for k in a.full}
    screens = _screens(a.resolution)
    records = []
    for name in validation_materials():
        table = read_merl(os.path.join(a.proxies, name + ".binary"))
        rows = _candidates(residuals, part, table, a.k)
        for label, pca in full.items():
            rows[label] = pca.decode(pca.project(table))
        with torch.no_grad():
            refs = {s: sc.render_table(table) for s, sc in screens.items()}
            psnr = {row: {s: screen_psnr(sc.render_table(t), refs[s]) for s, sc in screens.items()}
                    for row, t in rows.items()}
        for res in residuals:  # what an encoder keeps: its best candidate on the objective scenes
            cands = ["basis", f"{res}: c0", f"{res}: fitted"]
            best = max(cands, key=lambda r: np.mean([psnr[r][s] for s in OBJECTIVE]))
            psnr[f"{res}: chosen"] = psnr[best]
        records.append({"material": name, "psnr": psnr})
        print(name, {r: round(float(np.mean([v[s] for s in OBJECTIVE])), 2) for r, v in psnr.items()}, flush=True)
    doc = {"k": a.k, "resolution": a.resolution, "materials": validation_materials(), "records": records,
           "residuals": {n: r.meta.get("options") for n, r in residuals.items()}, "load_average": load_average()}
    with open(a.output, "w", encoding="utf-8") as f:
        json.dump(doc, f, indent=1)
    table_of(doc)


def table_of(doc):
    """Markdown: each row's mean over the materials, objective scenes and judged scenes."""
    from brdfkit.render.objective import OBJECTIVE
    from brdfkit.render.scene_suite import SUITE

    recs = doc["records"]
    print(f"\nK = {doc['k']} ({3 * doc['k']} numbers), {len(recs)} validation materials, {doc['resolution']} px\n")
    print("| row | objective scenes | judged scenes | " + " | ".join(SUITE) + " |")
    print("| --- | ---: | ---: | " + " | ".join("---:" for _ in SUITE) + " |")
    for row in recs[0]["psnr"]:
        per = {s: float(np.mean([r["psnr"][row][s] for r in recs])) for s in (*OBJECTIVE, *SUITE)}
        print(f"| {row} | {np.mean([per[s] for s in OBJECTIVE]):.2f} | {np.mean([per[s] for s in SUITE]):.2f} | "
              + " | ".join(f"{per[s]:.2f}" for s in SUITE) + " |")


def choose(a):
    """A choice per material among several residuals (*members*): the candidate (basis alone,
    each member's projection or fitted coefficients) with the best objective-scene PSNR,
    its judged scenes reported, against full PCA."""
    from brdfkit.render.objective import OBJECTIVE
    from brdfkit.render.scene_suite import SUITE

    recs = {}
    for path in a.records:
        with open(path, encoding="utf-8") as f:
            for r in json.load(f)["records"]:
                recs.setdefault(r["material"], {}).update(r["psnr"])
    rows = {}
    for group in a.groups:
        members = group.split(",")
        picked = []
        for ps in recs.values():
            cands = ["basis"] + [f"{m}: {c}" for m in members for c in ("c0", "fitted")]
            picked.append(ps[max(cands, key=lambda c: np.mean([ps[c][s] for s in OBJECTIVE]))])
        rows[f"chosen among {len(members)}: {group}"] = picked
    for label in sorted({k for ps in recs.values() for k in ps if k.startswith("PCA")}):
        rows[label] = [ps[label] for ps in recs.values()]
    print(f"\n{len(recs)} materials\n")
    print("| row | objective scenes | judged scenes | " + " | ".join(SUITE) + " |")
    print("| --- | ---: | ---: | " + " | ".join("---:" for _ in SUITE) + " |")
    for label, picked in rows.items():
        per = {s: float(np.mean([p[s] for p in picked])) for s in (*OBJECTIVE, *SUITE)}
        print(f"| {label} | {np.mean([per[s] for s in OBJECTIVE]):.2f} | {np.mean([per[s] for s in SUITE]):.2f} | "
              + " | ".join(f"{per[s]:.2f}" for s in SUITE) + " |")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    p = sub.add_parser("prepare")
    p.add_argument("--proxies", required=True)
    p.add_argument("--full", type=int, nargs="*", default=[3, 6, 7, 13])
    p.add_argument("-o", "--output", required=True)
    s = sub.add_parser("score")
    s.add_argument("residuals", nargs="+")
    s.add_argument("--proxies", required=True)
    s.add_argument("--basis", required=True)
    s.add_argument("--full-dir", default=None, help="where prepare wrote full-K.safetensors (default: beside --basis)")
    s.add_argument("--full", type=int, nargs="*", default=None, help="full PCA sizes K (default: k and 2k)")
    s.add_argument("-k", type=int, default=3)
    s.add_argument("--resolution", type=int, default=64)
    s.add_argument("-o", "--output", required=True)
    t = sub.add_parser("table")
    t.add_argument("record")
    c = sub.add_parser("choose")
    c.add_argument("records", nargs="+", help="score records of the same materials")
    c.add_argument("--groups", nargs="+", required=True, help="comma-separated residual names chosen among")
    a = ap.parse_args(argv)
    if a.cmd == "choose":
        return choose(a)
    if a.cmd == "prepare":
        return prepare(a)
    if a.cmd == "table":
        with open(a.record, encoding="utf-8") as f:
            return table_of(json.load(f))
    a.full_dir = a.full_dir or os.path.dirname(os.path.abspath(a.basis))
    a.full = a.full or [a.k, 2 * a.k]
    return score(a)


if __name__ == "__main__":
    main()
