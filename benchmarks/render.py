#!/usr/bin/env python3
"""Render times of the reference scene, against the cost of the BRDF evaluations alone:
the quadrature renderer and Mitsuba with the ``brdfkit`` plugin; or the quadrature's error.

Issue 7, item 4, and docs/render.md. For each BRDF: a dense table
(:class:`~brdfkit.render.renderable.TableBRDF`, synthetic ``stiff-white``) and a neural BRDF
(:class:`~brdfkit.hypernet.neural_brdf.NeuralBRDF` of an untrained default model: the hyponet costs the
same whatever its weights), or the one file given with ``--brdf``:

* ``render``: :func:`brdfkit.render.quadrature.render` of the reference scene at
  ``--resolution`` (256 is the scene's own; the driver uses 64 on a busy 2-core
  machine), as a fresh process renders (``quadrature.clear_cache()`` first): minimum and
  median wall time, process CPU time, the BRDF evaluations it made
  (``RenderStats.evaluations``), per object pixel and per second; and the render again
  with the pairs of the one before kept (``render_pairs_kept_s``: a second render in one
  process, e.g. the bench's);
* the **bound**: ``eval_dirs`` on that many random direction pairs, in blocks of
  262,144: what the render would cost if the quadrature itself were free;
* ``mitsuba``: :func:`brdfkit.render.mitsuba3.scenes.render_reference` at ``--spp``
  samples per pixel, seconds per spp and per sample per pixel, beside ``eval_dirs`` on
  ``resolution^2 x spp`` pairs (``--skip-mitsuba`` leaves it out).

Each after one untimed warm-up at 16 x 16 pixels (imports, node tables, Mitsuba's kernel
compilation); ``--repeat`` interleaved rounds (render, bound, render, bound, ...) with the
machine's load average (the figures depend on what else runs). Prints a table and the
JSON (``--json`` writes it too).

``--accuracy`` instead measures the quadrature's own error: PSNR and Delta E 2000 of the
default quadrature against one with about ten times the nodes (32 x 32 renders of four
synthetic tables), and the finer one against brute-force integration (a 800 x 1600
lat-long grid of directions, closed-form GGX) at four sphere normals, where the default
quadrature's error is reported too.

Examples (the figures in docs/render.md and docs/notes/performance.md)::

    python benchmarks/render.py --threads 2 --resolution 256 --spp 16 --repeat 2
    python benchmarks/render.py --resolution 256 --spp 4
    python benchmarks/render.py --accuracy
"""

from __future__ import annotations

import json
import statistics
import sys
import tempfile
import time

import common


def main(argv=None) -> int:
    ap = common.timing_parser(__doc__, repeat=1)
    ap.add_argument("--brdf", default=None,
                    help="a BRDF file (MERL .binary) instead of the synthetic table and the neural BRDF")
    ap.add_argument("--resolution", type=int, default=128)
    ap.add_argument("--spp", type=int, default=4, help="Mitsuba samples per pixel")
    ap.add_argument("--skip-mitsuba", action="store_true")
    ap.add_argument("--accuracy", action="store_true", help="measure the quadrature's error instead")
    args = ap.parse_args(argv)
    if args.accuracy:
        out = accuracy(args.threads)
        print(json.dumps(out, indent=1))
        if args.json:
            with open(args.json, "w") as f:
                f.write(json.dumps({"benchmark": "render_accuracy", **out}, indent=1, sort_keys=True) + "\n")
        return 0

    import numpy as np

    common.set_threads(args.threads)
    from brdfkit.runtime import set_cpu_threads

    set_cpu_threads(args.threads)  # the renderer's blocks of pixels (NumPy); torch's for the hyponet
    from brdfkit.io.embedding import Embedding
    from brdfkit.hypernet.neural_brdf import NeuralBRDF
    from brdfkit.render.renderable import TableBRDF
    from brdfkit.files.brdf_file import load_brdf
    from brdfkit.render.scene import Scene

    scene = Scene(resolution=args.resolution)
    _, mask = scene.pixel_normals()
    object_pixels = int(mask.any(2).sum())
    rows, results = [], []
    with tempfile.TemporaryDirectory() as tmp:
        if args.brdf:
            brdfs = {args.brdf: load_brdf(args.brdf, device="cpu")}
        else:
            model, _, table = common.untrained_model(tmp)
            emb = Embedding((0.1 * np.random.default_rng(0).normal(size=40)).astype(np.float32), model.digest)
            brdfs = {"table (stiff-white)": TableBRDF(table, "stiff-white", device="cpu"),
                     "neural (hyponet)": NeuralBRDF.from_embedding(model, emb)}
        for name, brdf in brdfs.items():
            r = measure(brdf, scene, args)
            r.update(brdf=name, object_pixels=object_pixels,
                     evaluations_per_pixel=r["evaluations"] / max(1, object_pixels))
            results.append(r)
            rows.append([name, args.resolution, f"{r['evaluations']:,}", r["render_s"], r["render_cpu_s"],
                         r["render_pairs_kept_s"], r["bound_eval_dirs_s"], f"{r['ratio_to_bound']:.2f}x",
                         r.get("mitsuba_s_per_spp", float("nan")),
                         r.get("mitsuba_ns_per_sample_per_pixel", float("nan")),
                         r.get("mitsuba_bound_eval_dirs_s", float("nan")),
                         " ".join(f"{v:.1f}" for v in r["load_average"])])
    data = {"machine": common.machine(), "resolution": args.resolution, "torch_threads": args.threads,
            "results": results}
    common.report("render", f"Reference-scene render ({args.resolution} x {args.resolution}), "
                            f"{args.threads} thread(s), best of {args.repeat}",
                  ["BRDF", "px", "BRDF evaluations", "render s", "render CPU s", "render again, pairs kept, s",
                   "bound: eval_dirs only s",
                   "ratio", f"Mitsuba s per spp ({args.spp} spp)", "Mitsuba ns / sample / pixel",
                   "bound: eval_dirs, res^2 x spp pairs, s", "load 1/5/15"], rows, data, args.json)
    return 0


def _pairs(rng, n):
    """``n`` random direction pairs above the horizon, float32 ``(2, n, 3)`` (NumPy: what
    the renderer hands a BRDF)."""
    import numpy as np

    v = rng.normal(size=(2, n, 3))
    v[..., 2] = np.abs(v[..., 2])
    v /= np.linalg.norm(v, axis=-1, keepdims=True)
    return v.astype(np.float32)


def _evals(brdf, wi, wo):
    """``eval_dirs`` over all pairs in blocks of 262,144: the bound."""
    for s in range(0, wi.shape[0], 1 << 18):
        brdf.eval_dirs(wi[s:s + (1 << 18)], wo[s:s + (1 << 18)])


def _interleaved(fn, bound, repeat):
    """``repeat`` rounds of ``fn`` then ``bound``: wall and CPU times of ``fn``, wall time
    of ``bound``, the 1-minute load average before each round."""
    wall, cpu, bound_wall, loads = [], [], [], []
    for _ in range(repeat):
        loads.append(common.load_average()[:1])
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
        t0 = time.perf_counter()
        bound()
        bound_wall.append(time.perf_counter() - t0)
    return {"min_s": min(wall), "median_s": statistics.median(wall), "cpu_s": min(cpu),
            "bound_s": min(bound_wall), "load_avg_1min": [x[0] for x in loads if x]}


def measure(brdf, scene, args) -> dict:
    """The quadrature render of ``scene`` and its bound, then Mitsuba and its bound."""
    import numpy as np

    from brdfkit.render import quadrature
    from brdfkit.render.scene import Scene

    rng = np.random.default_rng(0)
    quadrature.render(brdf, Scene(resolution=16))  # warm-up: node tables, caches
    stats, pairs = quadrature.RenderStats(), []

    def bound():  # as many pairs as the first render evaluated
        if not pairs:
            pairs.extend(_pairs(rng, stats.evaluations))
        _evals(brdf, *pairs)

    def cold():  # as a fresh process renders: no pairs kept from a render before
        quadrature.clear_cache()
        quadrature.render(brdf, scene, stats=stats)

    q = _interleaved(cold, bound, args.repeat)
    warm = _interleaved(lambda: quadrature.render(brdf, scene), lambda: None, args.repeat)
    quadrature.clear_cache()
    n = stats.evaluations
    del pairs
    r = {"resolution": args.resolution, "evaluations": n, "render_s": q["min_s"], "render_median_s": q["median_s"],
         "render_cpu_s": q["cpu_s"], "render_load_avg_1min": q["load_avg_1min"],
         "bound_eval_dirs_s": q["bound_s"], "ratio_to_bound": q["min_s"] / q["bound_s"],
         "render_pairs_kept_s": warm["min_s"], "render_pairs_kept_cpu_s": warm["cpu_s"],
         "ratio_pairs_kept_to_bound": warm["min_s"] / q["bound_s"],
         "us_per_evaluation_render": 1e6 * q["min_s"] / max(1, n),
         "us_per_evaluation_bound": 1e6 * q["bound_s"] / max(1, n),
         "evaluations_per_s": n / q["min_s"]}
    if not args.skip_mitsuba:
        from brdfkit.render.mitsuba3.scenes import render_reference

        render_reference(brdf, Scene(resolution=16), spp=args.spp)  # warm-up: JIT, plugin
        m = args.resolution ** 2 * args.spp
        mwi, mwo = _pairs(rng, m)
        t = _interleaved(lambda: render_reference(brdf, scene, spp=args.spp), lambda: _evals(brdf, mwi, mwo),
                         args.repeat)
        r.update(spp=args.spp, mitsuba_s=t["min_s"], mitsuba_median_s=t["median_s"], mitsuba_cpu_s=t["cpu_s"],
                 mitsuba_load_avg_1min=t["load_avg_1min"], mitsuba_s_per_spp=t["min_s"] / args.spp,
                 mitsuba_ns_per_sample_per_pixel=1e9 * t["min_s"] / m, mitsuba_bound_eval_dirs_s=t["bound_s"])
    r["load_average"] = common.load_average()
    return r


FINE = dict(cosine_grid=32, half_rings=48, half_phi=40, half_phi_min=16, light_density=3.0)


class _Analytic:
    """A synthetic material in closed form (no table)."""

    def __init__(self, material):
        self.m, self.device, self.name = material, "cpu", material.name

    def eval_dirs(self, wi, wo):
        import numpy as np

        from brdfkit.materials.synthetic import evaluate

        return evaluate(self.m, np.asarray(wi, np.float64), np.asarray(wo, np.float64)).astype(np.float32)


def _brute_force(material, normal, env, n=800):
    """Radiance at a sphere normal by a midpoint rule over an ``n x 2n`` lat-long grid."""
    import numpy as np

    from brdfkit.render.envmap import uv_to_direction
    from brdfkit.render.nodes import frames
    from brdfkit.materials.synthetic import evaluate

    t, b = (a[0] for a in frames(np.asarray(normal, np.float64)[None]))
    wo = np.array([t[2], b[2], normal[2]])
    u = (np.arange(2 * n) + 0.5) / (2 * n)
    total = np.zeros(3)
    for vs in np.array_split((np.arange(n) + 0.5) / n, 16):
        d = uv_to_direction(u[None, :], vs[:, None]).reshape(-1, 3)
        dw = np.repeat(2 * np.pi ** 2 * np.sin(np.pi * vs) / (n * 2 * n), 2 * n)
        wi = np.stack([d @ t, d @ b, d @ normal], -1)
        f = evaluate(material, wi, np.broadcast_to(wo, wi.shape))
        radiance = env.radiance(d)
        total += (radiance * f * np.clip(wi[:, 2:3], 0, None) * dw[:, None]).sum(0)
    return total


def accuracy(threads: int) -> dict:
    import dataclasses

    import numpy as np

    from brdfkit.evaluation import metrics
    from brdfkit.materials import synthetic
    from brdfkit.render import quadrature
    from brdfkit.render.renderable import TableBRDF
    from brdfkit.render.envmap import reference_envmap
    from brdfkit.render.scene import REFERENCE, Scene

    common.set_threads(threads)
    mats = [synthetic.STIFF[2], synthetic.STIFF[0], synthetic.STIFF[3],
            synthetic.Material("copper-0.05", "conductor", 0.05, ior=synthetic.METALS["copper"][0],
                               k=synthetic.METALS["copper"][1])]
    fine_q = dataclasses.replace(REFERENCE.quadrature, **FINE)
    out = {"default_vs_fine": {}, "fine_vs_brute_force": {}, "fine_quadrature": FINE}
    for m in mats:
        brdf = TableBRDF(synthetic.table(m), m.name, device="cpu")
        sa, sb = quadrature.RenderStats(), quadrature.RenderStats()
        a, _ = quadrature.render(brdf, Scene(resolution=32), stats=sa)
        b, _ = quadrature.render(brdf, Scene(resolution=32, quadrature=fine_q), stats=sb)
        out["default_vs_fine"][m.name] = {
            "psnr": metrics.psnr(a, b), "delta_e": metrics.delta_e_2000(a, b),
            "evaluations": [sa.evaluations, sb.evaluations]}
    env = reference_envmap()
    normals = np.array([[0.0, 0.0, 1.0], [0.5, 0.5, 0.7071], [-0.693, -0.047, 0.719], [-0.153, -0.96, 0.233]])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    for m in (synthetic.STIFF[2], synthetic.Material("glossy-0.1", "dielectric", 0.1, albedo=(0.3, 0.3, 0.3))):
        fine = quadrature.render_pixels(_Analytic(m), normals, env, q=fine_q)
        default = quadrature.render_pixels(_Analytic(m), normals, env)
        brute = np.stack([_brute_force(m, n, env) for n in normals])
        out["fine_vs_brute_force"][m.name] = {
            "max_relative_error": float(np.max(np.abs(fine - brute) / np.maximum(brute, 1e-3))),
            "default_relative_error_per_normal": (np.abs(default - brute) / np.maximum(brute, 1e-3)).max(1).tolist(),
            "brute_force": brute.tolist()}
    return out


if __name__ == "__main__":
    sys.exit(main())
