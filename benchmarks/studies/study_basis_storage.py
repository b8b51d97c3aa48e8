"""Decided: int8 and float16 storage cost nothing (at most 0.01 dB); the mapping's grazing
floor is what does not travel (+0.56 dB on unseen MERL, -2.96 dB on RGL at 39 numbers), and
every other ``phi_d`` cell costs the backlit rim without it, so the storage since keeps the
odd ``phi_d`` cells near the horizon (``brdfkit.basis.storage``). Reported in
``docs/notes/compression.md``, "Where a shipped basis loses (2026-11-27, 128 px, the six
judged scenes)".

What each part of a shipped basis's storage costs, measured apart, in the scene suite.

A shipped basis differs from a full-precision PCA (``brdfkit fit --method ipca``, float32
components of a float64 decomposition, Nielsen's mapping) in four ways: the mapping's
grazing floor (``w_floor``), every other ``phi_d`` cell only (``phi_stride = 2``), float16
reference and mean, int8 components. This study fits one basis with the floor and one
without on the same training tables, stores each way apart and all together, and scores
the least-squares projection (the start of every basis embedding) of held-out tables onto
the ``K`` leading components, rendered in the six judged scenes against the tables' own
renders.

    python benchmarks/studies/study_basis_storage.py --train proxies/merl --test-list ../shared/data/merl-test.txt \\
        --sets merl-test=proxies/merl rgl=proxies/rgl -k 3 7 13 --resolution 64 -o storage.json
    python benchmarks/studies/study_basis_storage.py table storage.json

``--sets NAME=FOLDER``: the materials scored; ``merl-test`` takes only the names of
``--test-list`` from its folder (the training set is the folder less them), any other
name every table of its folder. Make the proxy tables with
``python ../shared/tools/nbrdf_to_merl.py merl proxies/merl`` (and ``rgl``).
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import os
import sys
import tempfile
import time

import numpy as np

VARIANTS = {  # name: (w_floor, storage of save_basis)
    "full": (0.0, {}),
    "floor": (0.1, {}),
    "half-phi": (0.0, {"phi_stride": 2}),
    "float16": (0.0, {"half": True}),
    "int8": (0.0, {"half": True, "int8": True}),
    "shipped": (0.1, {"half": True, "int8": True, "phi_stride": 2}),
}
"""Each storage apart on the full-precision basis, and the shipped one (all together)."""

FLOORS = {f"floor-{f:g}": (f, {}) for f in (0.0, 0.005, 0.01, 0.02, 0.05, 0.1)}
"""``--variants floors``: the mapping's grazing floor alone, full precision."""


def _names(folder):
    return sorted(f[:-7] for f in os.listdir(folder) if f.endswith(".binary"))


def _read_list(path):
    with open(path, encoding="utf-8") as f:
        return [w for line in f for w in [line.split("#")[0].strip()] if w]


def fit_variants(train_paths, names, k, folder, variants=None):
    """Fit a basis for each floor of ``variants`` (default :data:`VARIANTS`), store each
    variant in ``folder`` (``VARIANT.safetensors``) and return ``{variant: path}``."""
    from brdfkit.basis import fit_basis, save_basis

    variants = variants or VARIANTS
    fitted = {}
    for floor in sorted({f for f, _ in variants.values()}):
        t = time.perf_counter()
        fitted[floor] = fit_basis(train_paths, k, names=names, w_floor=floor)
        print(f"fitted w_floor={floor}: {time.perf_counter() - t:.0f} s", file=sys.stderr)
    out = {}
    for name, (floor, storage) in variants.items():
        out[name] = os.path.join(folder, f"{name}.safetensors")
        save_basis(out[name], fitted[floor], **storage)
    return out


_BASES = {}


def _init(paths, device):
    """Pool initializer: every variant loaded once per process."""
    from brdfkit.basis import load_basis

    _BASES.update({v: load_basis(p) for v, p in paths.items()})
    _BASES["_device"] = device


def _task(args):
    path, ks, scenes, resolution = args
    from brdfkit.io.merl import read_merl

    t = time.perf_counter()
    bases = {v: b for v, b in _BASES.items() if v != "_device"}
    scores = score_material(read_merl(path), bases, ks, scenes, resolution, _BASES["_device"])
    return os.path.splitext(os.path.basename(path))[0], scores, time.perf_counter() - t


def score_material(table, bases, ks, scenes, resolution, device):
    """``{variant: {K: {"psnr", "delta_e", "scenes": {scene: {...}}}}}`` of one table's
    projections, rendered in ``scenes``."""
    from brdfkit.evaluation.comparison import mean_scores
    from brdfkit.evaluation.metrics import brdf_log_rmse, score
    from brdfkit.render.scene import reference_scene
    from brdfkit.render.quadrature import render_many
    from brdfkit.render.renderable import TableBRDF
    from brdfkit.render.scene_suite import scene_env

    keys = [(v, k) for v in bases for k in ks]
    tables = [table] + [bases[v].leading(k).decode(bases[v].leading(k).project(table)) for v, k in keys]
    brdfs = [TableBRDF(t, device=device) for t in tables]
    per = {key: {} for key in keys}
    for s in scenes:
        imgs = [img for img, _ in render_many(brdfs, reference_scene(resolution), env=scene_env(s))]
        for key, img in zip(keys, imgs[1:]):
            per[key][s] = {m: v for m, v in score(img, imgs[0]).items() if m != "brdf_log_rmse"}
    out = {}
    for (v, k), t in zip(keys, tables[1:]):
        mean = mean_scores(list(per[(v, k)].values()))
        out.setdefault(v, {})[str(k)] = {"psnr": mean["psnr"], "delta_e": mean["delta_e"],
                                         "log_rmse": brdf_log_rmse(t, table), "scenes": per[(v, k)]}
    return out


def print_table(path):
    with open(path, encoding="utf-8") as f:
        doc = json.load(f)
    scenes = doc["scenes"]
    print("| set | K (numbers) | storage | suite PSNR | Delta E | log RMSE | " + " | ".join(scenes) + " |")
    print("| --- | ---: | --- | ---: | ---: | ---: | " + " | ".join("---:" for _ in scenes) + " |")
    for name, recs in doc["sets"].items():
        for k in doc["k"]:
            for v in doc["variants"]:
                rows = [r["scores"][v][str(k)] for r in recs]
                per = [np.mean([r["scenes"][s]["psnr"] for r in rows]) for s in scenes]
                print(f"| {name} ({len(rows)}) | {k} ({3 * k}) | {v} | {np.mean([r['psnr'] for r in rows]):.2f} | "
                      f"{np.mean([r['delta_e'] for r in rows]):.3f} | {np.mean([r['log_rmse'] for r in rows]):.3f} | "
                      + " | ".join(f"{p:.2f}" for p in per) + " |")


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["table"]:
        return print_table(argv[1])
    ap = argparse.ArgumentParser()
    ap.add_argument("--train", required=True, help="folder of the training tables (less --test-list)")
    ap.add_argument("--test-list", required=True)
    ap.add_argument("--sets", nargs="+", required=True, help="NAME=FOLDER of scored materials")
    ap.add_argument("-k", type=int, nargs="+", default=[3, 7, 13])
    ap.add_argument("--resolution", type=int, default=64)
    ap.add_argument("--scenes", default="all")
    ap.add_argument("--every", type=int, default=1, help="every n-th material of each set")
    ap.add_argument("--device", default=None)
    ap.add_argument("--jobs", type=int, default=1, help="worker processes (each loads every variant)")
    ap.add_argument("--variants", choices=("storage", "floors"), default="storage",
                    help="storage: each storage apart (VARIANTS); floors: the grazing floor alone (FLOORS)")
    ap.add_argument("--keep", default=None, help="folder to keep the variants' basis files in")
    ap.add_argument("-o", "--output", required=True)
    a = ap.parse_args(argv)
    from brdfkit.render.scene_suite import scene_names
    from brdfkit.runtime import resolve_device

    device = str(resolve_device(a.device))
    test = set(_read_list(a.test_list))
    train = [n for n in _names(a.train) if n not in test]
    scenes = scene_names(a.scenes)
    variants = FLOORS if a.variants == "floors" else VARIANTS
    doc = {"train": os.path.basename(os.path.normpath(a.train)), "train_count": len(train), "k": a.k,
           "resolution": a.resolution, "scenes": scenes, "variants": {v: {"w_floor": f, **s} for v, (f, s) in
                                                                     variants.items()},
           "device": device, "sets": {}}
    with tempfile.TemporaryDirectory() as tmp:
        if a.keep:
            os.makedirs(a.keep, exist_ok=True)
        paths = fit_variants([os.path.join(a.train, n + ".binary") for n in train], train, max(a.k), a.keep or tmp,
                             variants)
        ctx = multiprocessing.get_context("spawn")
        with ctx.Pool(a.jobs, initializer=_init, initargs=(paths, device)) as pool:
            for spec in a.sets:
                name, folder = spec.split("=", 1)
                names = [n for n in _names(folder) if (n in test) == (name == "merl-test")][::a.every]
                tasks = [(os.path.join(folder, n + ".binary"), a.k, scenes, a.resolution) for n in names]
                recs = []
                for n, scores, sec in pool.imap(_task, tasks):
                    recs.append({"material": n, "scores": scores})
                    print(f"{name} {len(recs)}/{len(names)} {n}: {sec:.1f} s", file=sys.stderr)
                doc["sets"][name] = recs
                with open(a.output, "w", encoding="utf-8") as f:
                    json.dump(doc, f, indent=1)
    print_table(a.output)


if __name__ == "__main__":
    main()
