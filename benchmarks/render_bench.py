#!/usr/bin/env python3
"""Render times: the quadrature reference scene and Mitsuba with the ``brdfkit`` plugin.

Measures, for one BRDF (a MERL ``.binary``, or by default the synthetic ``stiff-white``
table):

* ``quadrature``: wall time of the reference-scene render (:func:`brdfkit.render.quadrature.render`)
  at ``--resolution``, the number of BRDF evaluations it made, per pixel and per second;
* ``mitsuba``: wall time of the path-traced reference scene with the plugin
  (:func:`brdfkit.render.mitsuba_plugin.render_reference`) at ``--spp`` samples per pixel,
  and that time per sample per pixel.

Each is run ``--repeat`` times after one untimed warm-up (imports, node tables, Mitsuba's
kernel compilation); the minimum and the median are reported, with the machine's load
average (the figures depend on what else runs). Prints JSON.

Example (the figures in docs/render.md)::

    python benchmarks/render_bench.py --threads 2 --resolution 256 --spp 16
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys
import time


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--brdf", default=None, help="MERL .binary (default: synthetic stiff-white)")
    ap.add_argument("--resolution", type=int, default=256)
    ap.add_argument("--spp", type=int, default=16, help="Mitsuba samples per pixel")
    ap.add_argument("--threads", type=int, default=2, help="torch threads")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--skip-mitsuba", action="store_true")
    args = ap.parse_args(argv)

    import torch

    torch.set_num_threads(args.threads)
    from brdfkit.render import quadrature
    from brdfkit.render.brdf import TableBRDF, load_brdf
    from brdfkit.render.scene import Scene

    if args.brdf:
        brdf = load_brdf(args.brdf, device="cpu")
    else:
        from brdfkit import synthetic

        brdf = TableBRDF(synthetic.table(synthetic.STIFF[2]), "stiff-white", device="cpu")
    scene = Scene(resolution=args.resolution)
    out = {"brdf": brdf.name, "resolution": args.resolution, "torch_threads": args.threads,
           "cpu_count": os.cpu_count(), "platform": platform.platform(),
           "python": sys.version.split()[0], "torch": torch.__version__}

    def timed(fn):
        fn()  # warm-up
        times, loads = [], []
        for _ in range(args.repeat):
            loads.append(os.getloadavg()[0])
            t0 = time.perf_counter()
            fn()
            times.append(time.perf_counter() - t0)
        return {"min_s": min(times), "median_s": statistics.median(times), "load_avg_1min": loads}

    _, mask = scene.pixel_normals()
    q = timed(lambda: quadrature.render(brdf, scene))
    n = quadrature.render_pixels.last_evaluations
    q.update(evaluations=n, object_pixels=int(mask.any(2).sum()),
             evaluations_per_pixel=n / max(1, int(mask.any(2).sum())),
             us_per_evaluation=1e6 * q["min_s"] / max(1, n))
    out["quadrature"] = q
    if not args.skip_mitsuba:
        from brdfkit.render.mitsuba_plugin import render_reference

        m = timed(lambda: render_reference(brdf, scene, spp=args.spp))
        m.update(spp=args.spp,
                 ns_per_sample_per_pixel=1e9 * m["min_s"] / (args.spp * args.resolution ** 2))
        out["mitsuba"] = m
    print(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
