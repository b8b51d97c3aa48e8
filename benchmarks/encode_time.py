"""Error against run time for ``brdfkit encode``: for each kind, size and step count, the
seconds an encode takes and the render error of what it decodes to.

For each material (``--materials``, or the names of ``--list`` in ``--proxies``, every
``--every``-th), each case ``MODEL:KIND-SIZE`` (``default`` names the default built-in)
and each ``--steps`` value (or the case's own, ``MODEL:KIND-SIZE@0/10/40``), the table is encoded as ``brdfkit encode -m MODEL --kind KIND
--size SIZE --steps STEPS`` encodes it (:func:`brdfkit.api.encode`, in this process),
decoded densely, and rendered at ``--px`` pixels in each of ``--scenes`` (the judged
suite, :mod:`brdfkit.render.scene_suite`) beside the table's own render: PSNR and Delta E
2000 as ``brdfkit bench`` scores them (their mean over the scenes, and each scene's).

Seconds are the encode's alone, in a process that has encoded before (its caches filled:
the model, the objective scenes' pairs): wall and CPU (every thread). What a whole
``brdfkit encode`` process adds to them (start, imports, the model's load, reading the
table, the first use of the scenes) is in ``benchmarks/encode_decode.py``'s record.

``--set MODULE.NAME=VALUE`` sets a module constant before anything runs (a study: the
fit's cell count, ``brdfkit.residual.encoding.FIT_CELLS=4096``); the record says what was
set.

    python benchmarks/encode_time.py --proxies proxies/merl --list ../shared/data/merl-test.txt \\
        --cases merl80-l40:residual-9,merl80-l40:residual-39 --steps 0 2 8 --px 64 --json out.json
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import common  # noqa: E402


def _set_constants(settings) -> dict:
    """Apply ``MODULE.NAME=VALUE`` settings (VALUE read as JSON, else as text)."""
    done = {}
    for item in settings:
        target, _, value = item.partition("=")
        module, _, name = target.rpartition(".")
        mod = importlib.import_module(module)
        if not hasattr(mod, name):
            raise SystemExit(f"--set {item}: {module} has no {name}")
        try:
            parsed = json.loads(value)
        except json.JSONDecodeError:
            parsed = value
        setattr(mod, name, parsed)
        done[target] = parsed
    return done


def _materials(args) -> list:
    if args.materials:
        names = args.materials.split(",")
    else:
        with open(args.list, encoding="utf-8") as f:
            names = sorted(f.read().split())[::args.every]
    paths = [os.path.join(args.proxies, f"{n}.binary") for n in names]
    missing = [p for p in paths if not os.path.exists(p)]
    if missing:
        raise SystemExit(f"missing tables: {', '.join(missing[:3])}")
    return list(zip(names, paths))


def _renders(table, scene, envs) -> dict:
    from brdfkit.render.quadrature import render
    from brdfkit.render.renderable import TableBRDF

    brdf = TableBRDF(table, device="cpu")
    return {s: render(brdf, scene, env=env)[0] for s, env in envs.items()}


def _scores(table, refs, scene, envs) -> dict:
    from brdfkit.evaluation.comparison import mean_scores
    from brdfkit.evaluation.metrics import score

    imgs = _renders(table, scene, envs)
    per = {s: score(imgs[s], refs[s]) for s in imgs}
    out = mean_scores(list(per.values()))
    return {"psnr": out["psnr"], "delta_e": out["delta_e"],
            "scenes": {s: {"psnr": r["psnr"], "delta_e": r["delta_e"]} for s, r in per.items()}}


def _decoders(cases, steps) -> list:
    """``[(label, decoder, size, step counts)]``: a case ``MODEL:KIND-SIZE``, or
    ``MODEL:KIND-SIZE@S1/S2/...`` with its own step counts (a latent's Adam steps)."""
    from brdfkit.embeddings import choose_decoder
    from brdfkit.models.builtin import default_bundle

    out = []
    for spec in cases:
        spec, _, own = spec.partition("@")
        model, kind_size = spec.split(":")
        model = default_bundle().name if model == "default" else model
        kind, size = kind_size.rsplit("-", 1)
        counts = [int(s) for s in own.split("/")] if own else list(steps)
        out.append((f"{model}:{kind}-{size}", choose_decoder(kind, model, size=int(size)), int(size), counts))
    return out


def _summary(records) -> list:
    rows = []
    for case in dict.fromkeys(r["case"] for r in records):
        for s in dict.fromkeys(r["steps"] for r in records if r["case"] == case):
            rs = [r for r in records if r["case"] == case and r["steps"] == s]
            scenes = rs[0]["scenes"]
            rows.append({"case": case, "steps": s, "materials": len(rs),
                         "encode_wall_s": float(np.mean([r["encode_wall_s"] for r in rs])),
                         "encode_cpu_s": float(np.mean([r["encode_cpu_s"] for r in rs])),
                         "psnr": float(np.mean([r["psnr"] for r in rs])),
                         "delta_e": float(np.mean([r["delta_e"] for r in rs])),
                         "scenes": {sc: float(np.mean([r["scenes"][sc]["psnr"] for r in rs])) for sc in scenes}})
    return rows


def main(argv=None):
    ap = common.record_options(argparse.ArgumentParser(description=__doc__.split("\n\n")[0]))
    ap.add_argument("--proxies", default=os.path.join("proxies", "merl"), help="folder of MERL tables NAME.binary")
    ap.add_argument("--list", default=os.path.join("..", "shared", "data", "merl-test.txt"))
    ap.add_argument("--materials", default="", help="names joined by commas (instead of --list)")
    ap.add_argument("--every", type=int, default=1, help="every K-th name of --list, sorted")
    ap.add_argument("--cases", default="merl80-l40:residual-9,merl80-l40:residual-39,default:residual-9,"
                                       "default:residual-39,default:basis-9,default:basis-39")
    ap.add_argument("--steps", type=int, nargs="+", default=[0, 2, 8])
    ap.add_argument("--px", type=int, default=64)
    ap.add_argument("--scenes", default="all")
    ap.add_argument("--set", action="append", default=[], help="MODULE.NAME=VALUE, a module constant (a study)")
    a = ap.parse_args(argv)
    load0, t0 = common.load_average(), time.time()
    settings = _set_constants(a.set)

    from brdfkit.api import encode
    from brdfkit.embeddings import open_embedding
    from brdfkit.io.merl import read_merl
    from brdfkit.render.scene import Scene
    from brdfkit.render.scene_suite import scene_env, scene_names

    mats = _materials(a)
    scene = Scene(resolution=a.px)
    envs = {s: scene_env(s) for s in scene_names(a.scenes)}
    decoders = _decoders(a.cases.split(","), a.steps)
    records, warm = [], set()
    for name, path in mats:
        table = read_merl(path)
        refs = _renders(table, scene, envs)
        for label, dec, size, counts in decoders:
            if label not in warm:  # a warm-up: the caches a process fills on a case's first encode
                encode(table, dec, size=size, steps=max(counts), source=name)
                warm.add(label)
            for steps in counts:
                w, c = time.perf_counter(), time.process_time()
                emb = encode(table, dec, size=size, steps=steps, source=name)
                wall, cpu = time.perf_counter() - w, time.process_time() - c
                decoded = open_embedding(emb, dec, name).to_table()
                rec = {"material": name, "case": label, "steps": steps, "encode_wall_s": wall, "encode_cpu_s": cpu,
                       "ran": (emb.refinement or {}).get("steps", 0), **_scores(decoded, refs, scene, envs)}
                records.append(rec)
                print(f"{name} {label} steps {steps}: {rec['psnr']:.2f} dB, {cpu:.2f} s CPU", file=sys.stderr)
    summary = _summary(records)
    cols = ["case", "steps", "materials", "encode wall s", "encode CPU s", "PSNR dB", "Delta E"]
    rows = [[r["case"], r["steps"], r["materials"], r["encode_wall_s"], r["encode_cpu_s"], r["psnr"], r["delta_e"]]
            for r in summary]
    config = {k: v for k, v in vars(a).items() if k != "json"}
    record = common.write_record({"config": {**config, "set": settings}, "materials": [n for n, _ in mats],
                                  "summary": summary, "records": records}, None, load0, t0)
    common.report("encode_time", "Encode: error against run time", cols, rows, record, a.json)


if __name__ == "__main__":
    main()
