"""Decided: brdfkit's ``.bsdf`` files agree with Mitsuba 3's ``measured`` plugin to float32
precision, and the round trip MERL -> ``.bsdf`` -> MERL at the default settings keeps
63.8 dB mean in the reference scene (40 asked); the error-against-size sweep made 48 incident
elevations (on the 64 x 64 grid) the default. Reported in ``docs/notes/rgl-bsdf.md``,
"Checked by Mitsuba 3" and "What the round trip loses".

What the RGL .bsdf round trip loses (issue 30): MERL table -> .bsdf -> MERL table,
rendered in the reference scene against the source; and Mitsuba 3's own ``measured``
BSDF rendering the written file against brdfkit's render of the source.

Four jobs (any combination in one run):

* ``--roundtrip``: every table of ``--data`` (folders of MERL ``.binary`` proxies, or
  ``--names`` among them) written at the default settings, read back at the MERL grid,
  both rendered by the quadrature (``--px``, default 256) in one pass; PSNR, Delta E,
  the file's size, write and read seconds per material.
  ``--scenes NAME,...`` renders in those scenes of the suite instead
  (:mod:`brdfkit.render.scene_suite`; ``psnr`` is then their mean).
* ``--sizes N,...``: the error against file size on the ``--names`` materials: one
  ``.bsdf`` per sample-space resolution ``N`` (and per ``--theta-i-sizes``), all read
  back and rendered with the source in one pass.
* ``--agree NAME ...``: Mitsuba's ``measured`` ``eval`` against brdfkit's reader of the
  written file at ``--pairs`` random direction pairs.
* ``--mitsuba NAME ...``: the written file path-traced by Mitsuba's ``measured`` plugin
  (``scalar_rgb``, in a child process; ``--mitsuba-px``, ``--spp``) against the
  quadrature render of the source (supersampled 4 x 4: Mitsuba box-filters each pixel).

``--json PATH`` writes the record (command, machine, load average at start and end,
every row). Example (the figures of docs/rgl-bsdf.md)::

    python benchmarks/studies/rgl_roundtrip.py --data proxies/merl proxies/rgl --roundtrip \\
        --json benchmarks/results/2026-11-26-rgl-roundtrip.json

(``proxies/merl``, ``proxies/rgl``: the reference proxies, made by
``python ../shared/tools/nbrdf_to_merl.py merl proxies/merl`` and ``... rgl proxies/rgl``.)

Benchmarks import nothing from ``tests/``; one torch thread (``--threads``).
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))  # benchmarks/common.py
from common import load_average, record_options, set_threads, write_record  # noqa: E402


def _tables(folders, names):
    found = {}
    for folder in folders:
        for n in sorted(os.listdir(folder)):
            if n.endswith(".binary"):
                found.setdefault(n[:-7], os.path.join(folder, n))
    if names:
        missing = [n for n in names if n not in found]
        if missing:
            sys.exit(f"rgl_roundtrip.py: error: not in --data: {', '.join(missing)}")
        return {n: found[n] for n in names}
    return found


def _write_read(table, path, settings):
    from brdfkit.io.rgl_bsdf import read_bsdf_table, write_bsdf

    t0 = time.perf_counter()
    write_bsdf(path, table, settings)
    t1 = time.perf_counter()
    back = read_bsdf_table(path)
    return back, {"bytes": os.path.getsize(path), "write_s": round(t1 - t0, 3),
                  "read_s": round(time.perf_counter() - t1, 3)}


def _scores(images, ref):
    from brdfkit.evaluation.metrics import delta_e_2000, psnr

    return [{"psnr": round(psnr(img, ref), 3), "delta_e": round(delta_e_2000(img, ref), 4)} for img in images]


def roundtrip(tables, px, folder, scenes=None):
    """One row per material at the default settings; with ``scenes`` (suite scene names,
    :mod:`brdfkit.render.scene_suite`) the PSNR in each, and their mean as ``psnr``."""
    from brdfkit.io.merl import read_merl
    from brdfkit.io.rgl.fit import FitSettings
    from brdfkit.render.quadrature import render_many
    from brdfkit.render.renderable import TableBRDF
    from brdfkit.render.scene import REFERENCE

    scene = dataclasses.replace(REFERENCE, resolution=px)
    envs = {None: None}
    if scenes:
        from brdfkit.render.scene_suite import scene_env

        envs = {name: scene_env(name) for name in scenes}
    rows = []
    for i, (name, src) in enumerate(tables.items(), 1):
        table = read_merl(src)
        back, info = _write_read(table, os.path.join(folder, "x.bsdf"), FitSettings())
        pair = [TableBRDF(table, device="cpu"), TableBRDF(back, device="cpu")]
        per = {}
        for scene_name, env in envs.items():
            (ref, _), (img, _) = render_many(pair, scene, env=env)
            per[scene_name] = _scores([img], ref)[0]
        row = {"material": name, **info}
        if scenes:
            row.update(psnr=round(sum(v["psnr"] for v in per.values()) / len(per), 3), scenes=per)
        else:
            row.update(per[None])
        rows.append(row)
        print(f"[{i}/{len(tables)}] {name}: {row}", flush=True)
    return rows


def sizes(tables, px, resolutions, theta_counts, folder):
    """Error against file size: per material, one file per setting, one render pass."""
    from brdfkit.io.merl import read_merl
    from brdfkit.io.rgl.fit import FitSettings
    from brdfkit.render.quadrature import render_many
    from brdfkit.render.renderable import TableBRDF
    from brdfkit.render.scene import REFERENCE

    settings = [FitSettings(resolution=n) for n in resolutions]
    settings += [FitSettings(theta_i=t) for t in theta_counts]
    scene = dataclasses.replace(REFERENCE, resolution=px)
    rows = []
    for name, src in tables.items():
        table = read_merl(src)
        backs, infos = [], []
        for k, s in enumerate(settings):
            back, info = _write_read(table, os.path.join(folder, f"s{k}.bsdf"), s)
            backs.append(back)
            infos.append(info)
        images = render_many([TableBRDF(t, device="cpu") for t in [table, *backs]], scene)
        for s, info, score in zip(settings, infos, _scores([im for im, _ in images[1:]], images[0][0])):
            rows.append({"material": name, "resolution": s.resolution, "theta_i": s.theta_i, **score, **info})
            print(rows[-1], flush=True)
    return rows


def mitsuba(tables, px, spp, folder):
    """Mitsuba's ``measured`` render of each written file against the source's quadrature."""
    from brdfkit.io.merl import read_merl
    from brdfkit.io.rgl_bsdf import write_bsdf
    from brdfkit.render.quadrature import render
    from brdfkit.render.renderable import TableBRDF
    from brdfkit.render.scene import REFERENCE
    from brdfkit.testing.mitsuba_measured import measured_render

    rows = []
    for name, src in tables.items():
        table = read_merl(src)
        path = os.path.join(folder, f"{name}.bsdf")
        write_bsdf(path, table)
        t0 = time.perf_counter()
        img = measured_render(path, resolution=px, spp=spp, seed=0, timeout=3600)
        seconds = time.perf_counter() - t0
        ref, _ = render(TableBRDF(table, device="cpu"), dataclasses.replace(REFERENCE, resolution=px, supersample=4))
        rows.append({"material": name, "px": px, "spp": spp, "mitsuba_s": round(seconds, 1), **_scores([img], ref)[0],
                     "mean_mitsuba": [round(float(v), 5) for v in img.reshape(-1, 3).mean(0)],
                     "mean_quadrature": [round(float(v), 5) for v in ref.reshape(-1, 3).mean(0)]})
        print(rows[-1], flush=True)
    return rows


def agree(tables, pairs, folder, seed=30):
    """Mitsuba's ``measured`` ``eval`` against brdfkit's reader on each written file, at
    ``pairs`` random direction pairs (uniform over the hemisphere)."""
    import numpy as np

    from brdfkit.io.merl import read_merl
    from brdfkit.io.rgl_bsdf import read_bsdf, write_bsdf
    from brdfkit.testing.mitsuba_measured import measured_eval

    rng = np.random.default_rng(seed)

    def dirs():
        z, phi = rng.random(pairs), rng.random(pairs) * 2 * np.pi
        return np.stack([np.sqrt(1 - z * z) * np.cos(phi), np.sqrt(1 - z * z) * np.sin(phi), z], -1)

    wi, wo = dirs(), dirs()
    paths = []
    for name, src in tables.items():
        paths.append(os.path.join(folder, f"{name}.bsdf"))
        write_bsdf(paths[-1], read_merl(src))
    rows = []
    for name, path, theirs in zip(tables, paths, measured_eval(paths, wi, wo)):
        ours = read_bsdf(path).eval(wi, wo)
        diff, scale = np.abs(ours - theirs), np.abs(theirs).max()
        rel = diff / np.maximum(np.abs(theirs), 1e-300)
        rows.append({"material": name, "pairs": pairs, "values": int(theirs.size),
                     "max_rel": float(rel.max()), "over_1e-3_rel": int((rel > 1e-3).sum()),
                     "over_1e-3_rel_plus_1e-6_max": int((diff > 1e-3 * np.abs(theirs) + 1e-6 * scale).sum()),
                     "max_rel_of_values_above_1e-4_max": float(rel[np.abs(theirs) > 1e-4 * scale].max())})
        print(rows[-1], flush=True)
    return rows


def _summary(rows):
    import numpy as np

    p = np.array([r["psnr"] for r in rows])
    return {"n": len(rows), "psnr_mean": round(float(p.mean()), 3), "psnr_min": round(float(p.min()), 3),
            "psnr_median": round(float(np.median(p)), 3), "below_40": int((p < 40).sum()),
            "worst": min(rows, key=lambda r: r["psnr"])["material"],
            "bytes": int(np.median([r["bytes"] for r in rows])),
            "write_s_max": max(r["write_s"] for r in rows), "read_s_max": max(r["read_s"] for r in rows)}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", nargs="+", required=True, help="folders of MERL .binary proxies")
    ap.add_argument("--names", nargs="*", default=None, help="these materials only")
    ap.add_argument("--roundtrip", action="store_true", help="every material at the default settings")
    ap.add_argument("--px", type=int, default=256, help="render size of --roundtrip and --sizes")
    ap.add_argument("--scenes", default=None, metavar="NAME,...",
                    help="--roundtrip in these scenes of the suite (brdfkit.render.scene_suite), not the reference")
    ap.add_argument("--sizes", default=None, metavar="N,...", help="sample-space resolutions for error vs size")
    ap.add_argument("--theta-i-sizes", default="", metavar="T,...", help="incident elevation counts, too")
    ap.add_argument("--mitsuba", nargs="*", default=None, metavar="NAME", help="Mitsuba render check of these")
    ap.add_argument("--agree", nargs="*", default=None, metavar="NAME", help="Mitsuba eval against the reader")
    ap.add_argument("--pairs", type=int, default=10_000)
    ap.add_argument("--mitsuba-px", type=int, default=64)
    ap.add_argument("--spp", type=int, default=4096)
    args = record_options(ap).parse_args(argv)
    set_threads(args.threads)
    load0, t0 = load_average(), time.time()
    record = {"command": " ".join(["benchmarks/studies/rgl_roundtrip.py", *sys.argv[1:]])}
    with tempfile.TemporaryDirectory(prefix="rgl-roundtrip-") as folder:
        if args.roundtrip:
            scenes = [x for x in args.scenes.split(",") if x] if args.scenes else None
            rows = roundtrip(_tables(args.data, args.names), args.px, folder, scenes)
            record["roundtrip"] = {"px": args.px, "scenes": scenes or ["reference"], "rows": rows,
                                   "summary": _summary(rows)}
            print("roundtrip", record["roundtrip"]["summary"])
        if args.sizes:
            res = [int(x) for x in args.sizes.split(",") if x]
            thetas = [int(x) for x in args.theta_i_sizes.split(",") if x]
            record["sizes"] = {"px": args.px, "rows": sizes(_tables(args.data, args.names), args.px, res, thetas,
                                                            folder)}
        if args.agree is not None:
            record["agree"] = {"rows": agree(_tables(args.data, args.agree), args.pairs, folder)}
        if args.mitsuba is not None:
            record["mitsuba"] = {"rows": mitsuba(_tables(args.data, args.mitsuba), args.mitsuba_px, args.spp,
                                                 folder)}
    write_record(record, args.json, load0, t0)


if __name__ == "__main__":
    main()
