"""Reference-scene render time and BRDF evaluation count, against the cost of the BRDF
evaluations alone; and a Mitsuba render with the ``brdfkit`` plugin, per sample per pixel.

Issue 7, item 4 (the render engineer's ``benchmarks/render_bench.py`` times the same
calls; this script adds the bound and the neural BRDF). For a dense table
(:class:`~brdfkit.render.brdf.TableBRDF`, synthetic ``stiff-white``) and a neural BRDF
(:class:`~brdfkit.model.brdf.NeuralBRDF` of an untrained default model: the hyponet costs the
same whatever its weights):

* ``render``: :func:`brdfkit.render.quadrature.render` of the reference scene at
  ``--resolution`` (256 is the scene's own; the driver uses 128 on a busy 2-core
  machine), with ``RenderStats.evaluations``, the BRDF evaluations it needed;
* the **bound**: ``eval_dirs`` on that many random direction pairs, in blocks of
  262,144: what the render would cost if the quadrature itself were free;
* ``mitsuba``: :func:`brdfkit.render.mitsuba_plugin.render_reference` at ``--spp``,
  seconds per sample per pixel, beside ``eval_dirs`` on ``resolution^2 x spp`` pairs.

Best of ``--repeat`` interleaved rounds (default 1: a render takes tens of seconds
here). Usage::

    python benchmarks/render_bound.py [--resolution 128] [--spp 4] [--threads 1] [--json out.json]
"""

from __future__ import annotations

import argparse
import sys
import tempfile

import common


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--resolution", type=int, default=128)
    p.add_argument("--spp", type=int, default=4)
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--repeat", type=int, default=1)
    p.add_argument("--skip-mitsuba", action="store_true")
    p.add_argument("--json", default=None)
    args = p.parse_args(argv)

    import numpy as np
    import torch

    common.set_threads(args.threads)
    from brdfkit.embedding import Embedding
    from brdfkit.model.brdf import NeuralBRDF
    from brdfkit.render import quadrature
    from brdfkit.render.brdf import TableBRDF
    from brdfkit.render.scene import Scene

    scene = Scene(resolution=args.resolution)
    rows, results = [], []
    with tempfile.TemporaryDirectory() as tmp:
        model, _, table = common.untrained_model(tmp)
        rng = np.random.default_rng(0)
        emb = Embedding((0.1 * rng.normal(size=40)).astype(np.float32), model.fingerprint)
        brdfs = {"table (stiff-white)": TableBRDF(table, "stiff-white", device="cpu"),
                 "neural (hyponet)": NeuralBRDF.from_embedding(model, emb)}

        def pairs(n):
            v = rng.normal(size=(2, n, 3))
            v[..., 2] = np.abs(v[..., 2])
            v /= np.linalg.norm(v, axis=-1, keepdims=True)
            return torch.tensor(v, dtype=torch.float32)

        def evals(brdf, wi, wo):
            with torch.no_grad():
                for s in range(0, wi.shape[0], 1 << 18):
                    brdf.eval_dirs(wi[s:s + (1 << 18)], wo[s:s + (1 << 18)])

        for name, brdf in brdfs.items():
            quadrature.render(brdf, Scene(resolution=16))  # warm-up: node tables, caches
            import time

            times, bound_times, n = [], [], None
            wi = wo = None
            for _ in range(args.repeat):  # render, bound, render, bound, ...
                t0 = time.perf_counter()
                stats = quadrature.RenderStats()
                quadrature.render(brdf, scene, stats=stats)
                times.append(time.perf_counter() - t0)
                n = stats.evaluations
                if wi is None:
                    wi, wo = pairs(n)
                t0 = time.perf_counter()
                evals(brdf, wi, wo)
                bound_times.append(time.perf_counter() - t0)
            t = {"render": min(times), "bound": min(bound_times)}
            r = {"brdf": name, "resolution": args.resolution, "evaluations": n, "render_s": t["render"],
                 "bound_eval_dirs_s": t["bound"], "ratio_to_bound": t["render"] / t["bound"],
                 "us_per_evaluation_render": 1e6 * t["render"] / n,
                 "us_per_evaluation_bound": 1e6 * t["bound"] / n, "load_average": common.load_average()}
            del wi, wo
            if not args.skip_mitsuba:
                from brdfkit.render.mitsuba_plugin import render_reference

                render_reference(brdf, Scene(resolution=16), spp=1)  # warm-up: JIT, plugin
                m = args.resolution ** 2 * args.spp
                mwi, mwo = pairs(m)
                tm = common.best_of({"mitsuba": lambda: render_reference(brdf, scene, spp=args.spp),
                                 "bound": lambda: evals(brdf, mwi, mwo)}, args.repeat, warmup=0)
                r.update(mitsuba_s=tm["mitsuba"], spp=args.spp,
                         mitsuba_s_per_spp=tm["mitsuba"] / args.spp,
                         mitsuba_ns_per_sample_per_pixel=1e9 * tm["mitsuba"] / m,
                         mitsuba_bound_eval_dirs_s=tm["bound"])
            results.append(r)
            rows.append([name, args.resolution, f"{n:,}", t["render"], t["bound"], f"{r['ratio_to_bound']:.2f}x",
                         r.get("mitsuba_s_per_spp", float("nan")),
                         r.get("mitsuba_ns_per_sample_per_pixel", float("nan")),
                         r.get("mitsuba_bound_eval_dirs_s", float("nan")),
                         " ".join(f"{v:.1f}" for v in r["load_average"])])
    data = {"machine": common.machine(), "results": results}
    common.report("render", f"Reference-scene render ({args.resolution} x {args.resolution}), {args.threads} thread(s)",
              ["BRDF", "px", "BRDF evaluations", "render s", "bound: eval_dirs only s", "ratio",
               f"Mitsuba s per spp ({args.spp} spp)", "Mitsuba ns / sample / pixel",
               "bound: eval_dirs, res^2 x spp pairs, s", "load 1/5/15"], rows, data, args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
