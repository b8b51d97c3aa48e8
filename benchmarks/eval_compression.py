"""Compression of full tables, judged by renders (issue 21's done-when).

Each table of ``--data`` (MERL ``.binary`` files; ``--test-list`` restricts them) is
compressed by each ``--compressors`` entry and rendered in the reference scene at ``--px``
pixels (quadrature) beside the table itself:

* ``hypernet:MODEL`` (a built-in name or a model file): ``brdfkit encode`` then
  ``brdfkit decode`` with default options (:func:`brdfkit.api.encode`: the encoder's pass
  refined on screen for the default budget), or ``hypernet-norefine:MODEL`` (the paper's
  single pass);
* ``ipca:BASIS``: the PCA basis's least-squares projection of the full table, decoded
  (the method registry's ``compress_fn``, as ``brdfkit bench`` scores it).

Per record: PSNR and Delta E 2000 of the renders, BRDF log RMSE, the compression's wall
seconds. Prints mean, worst material and the count below ``--floor`` dB per compressor;
``--json`` keeps every record. ``--jobs`` worker processes share the materials.

    python benchmarks/eval_compression.py --data PROXIES/merl \\
        --compressors hypernet:merl-rgl-l40 hypernet:merl-rgl-l7 ipca:ipca100.safetensors \\
        --jobs 2 --json compression-merl100.json
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))


def _compressor(spec):
    kind, _, path = spec.partition(":")
    if kind not in ("hypernet", "hypernet-norefine", "ipca") or not path:
        raise SystemExit(f"bad --compressors entry {spec!r}: KIND:MODEL with KIND hypernet, hypernet-norefine or ipca")
    return kind, path


def _encode(model, table, name, kind, config):
    """``brdfkit encode``'s embedding, with ``config`` (``--config``) overriding the
    refinement's :class:`~brdfkit.render.objective.ObjectiveConfig` fields."""
    from brdfkit import api
    from brdfkit.hypernet.refine_on_screen import compress_table
    from brdfkit.render.objective import ObjectiveConfig

    if kind != "hypernet" or not config:
        return api.encode(table, model, source=name, refine=kind == "hypernet")
    return compress_table(model, table, ObjectiveConfig(**config), name).embedding


def _work(args):
    names, data, specs, px, threads, config = args
    import torch

    torch.set_num_threads(threads)
    from brdfkit import api
    from brdfkit.io.merl import read_merl
    from brdfkit.methods import METHODS
    from brdfkit.evaluation.metrics import brdf_log_rmse, delta_e_2000, psnr
    from brdfkit.render.renderable import TableBRDF
    from brdfkit.render.quadrature import render_many
    from brdfkit.render.scene import Scene

    models = {}
    for kind, path in specs:
        if kind == "ipca":
            models[(kind, path)] = METHODS["ipca"].load(path, "cpu")
        else:
            models[(kind, path)] = api.load_model(path, "cpu")
    scene = Scene(resolution=px)
    out = []
    for name in names:
        table = read_merl(os.path.join(data, name + ".binary"))
        preds, secs = [], []
        for kind, path in specs:
            m = models[(kind, path)]
            t = time.perf_counter()
            if kind == "ipca":
                pred = METHODS["ipca"].compress_fn(m, table, name)
            else:
                pred = api.decode(_encode(m, table, name, kind, config), m)
            secs.append(time.perf_counter() - t)
            preds.append(pred)
        imgs = render_many([TableBRDF(table, device="cpu")] + [TableBRDF(p, device="cpu") for p in preds], scene)
        ref = imgs[0][0]
        for (kind, path), pred, (img, _), s in zip(specs, preds, imgs[1:], secs):
            out.append(dict(material=name, compressor=f"{kind}:{path}", psnr=psnr(img, ref),
                            delta_e=delta_e_2000(img, ref), log_rmse=brdf_log_rmse(pred, table), seconds=s))
        print(f"{name}: " + ", ".join(f"{r['compressor'].split(':')[0]} {r['psnr']:.2f}" for r in out[-len(specs):]),
              flush=True)
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--data", required=True, help="folder of MERL tables NAME.binary")
    ap.add_argument("--test-list", default=None, help="only these material names (one a line)")
    ap.add_argument("--compressors", nargs="+", required=True, help="hypernet:MODEL, hypernet-norefine:MODEL, ipca:BASIS")
    ap.add_argument("--px", type=int, default=128)
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--floor", type=float, default=35.0, help="count materials below this PSNR")
    ap.add_argument("--config", nargs="*", default=[], metavar="KEY=VALUE",
                    help="refinement settings (ObjectiveConfig fields, numbers) instead of the defaults")
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    from common import load_average, machine

    specs = [_compressor(s) for s in args.compressors]
    names = sorted(f[:-7] for f in os.listdir(args.data) if f.endswith(".binary"))
    if args.test_list:
        with open(args.test_list) as f:
            keep = {ln.split("#")[0].strip() for ln in f} - {""}
        names = [n for n in names if n in keep]
    t0 = time.time()
    load0 = load_average()
    jobs = max(1, min(args.jobs, len(names)))
    config = {}
    for item in args.config:
        key, sep, value = item.partition("=")
        if not sep:
            raise SystemExit(f"bad --config entry {item!r}: KEY=VALUE")
        config[key] = int(value) if value.lstrip("-").isdigit() else float(value)
    parts = [(names[i::jobs], args.data, specs, args.px, max(1, (os.cpu_count() or 1) // jobs), config)
             for i in range(jobs)]
    if jobs == 1:
        records = _work(parts[0])
    else:
        import multiprocessing as mp

        with mp.get_context("spawn").Pool(jobs) as pool:
            records = [r for part in pool.map(_work, parts) for r in part]
    summary = {}
    print(f"\n{len(names)} materials, {args.px} px, {time.time() - t0:.0f} s (load {load0} -> {load_average()})\n")
    print("| compressor | PSNR (dB) | worst (material) | below %g dB | Delta E | log RMSE | seconds |" % args.floor)
    print("| --- | ---: | --- | ---: | ---: | ---: | ---: |")
    for spec in args.compressors:
        kind, path = _compressor(spec)
        rs = [r for r in records if r["compressor"] == f"{kind}:{path}"]
        worst = min(rs, key=lambda r: r["psnr"])
        s = dict(psnr=float(np.mean([r["psnr"] for r in rs])), delta_e=float(np.mean([r["delta_e"] for r in rs])),
                 log_rmse=float(np.mean([r["log_rmse"] for r in rs])), seconds=float(np.mean([r["seconds"] for r in rs])),
                 worst=(worst["material"], worst["psnr"]), below=sum(r["psnr"] < args.floor for r in rs), count=len(rs))
        summary[spec] = s
        print(f"| {spec} | {s['psnr']:.2f} | {s['worst'][1]:.2f} ({s['worst'][0]}) | {s['below']} | "
              f"{s['delta_e']:.3f} | {s['log_rmse']:.4f} | {s['seconds']:.2f} |")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(dict(command=" ".join(sys.argv), machine=machine(), load_start=load0, load_end=load_average(),
                           seconds=time.time() - t0, materials=names, summary=summary, records=records), f, indent=1)


if __name__ == "__main__":
    main()
