#!/usr/bin/env python3
"""Render times: the quadrature reference scene and Mitsuba with the ``brdfkit`` plugin.

Measures, for one BRDF (a MERL ``.binary``, or by default the synthetic ``stiff-white``
table):

* ``quadrature``: wall time of the reference-scene render (:func:`brdfkit.render.quadrature.render`)
  at ``--resolution``, the number of BRDF evaluations it made, per pixel and per second;
* ``mitsuba``: wall time of the path-traced reference scene with the plugin
  (:func:`brdfkit.render.mitsuba_plugin.render_reference`) at ``--spp`` samples per pixel,
  and that time per sample per pixel.

Each is run ``--repeat`` times after one untimed warm-up at 16 x 16 pixels (imports, node
tables, Mitsuba's kernel compilation); the minimum and the median wall time are reported, the process CPU
time, and the machine's load average (the figures depend on what else runs). Prints JSON.

``--accuracy`` instead measures the quadrature's own error: PSNR and Delta E 2000 of the
default quadrature against one with about ten times the nodes (32 x 32 renders of four
synthetic tables), and the finer one against brute-force integration (a 800 x 1600
lat-long grid of directions, closed-form GGX) at four sphere normals, where the default
quadrature's error is reported too.

Examples (the figures in docs/render.md)::

    python benchmarks/render_bench.py --threads 2 --resolution 256 --spp 16
    python benchmarks/render_bench.py --accuracy
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
    ap.add_argument("--accuracy", action="store_true", help="measure the quadrature's error instead")
    args = ap.parse_args(argv)
    if args.accuracy:
        print(json.dumps(accuracy(args.threads), indent=1))
        return 0

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

    def timed(fn, warm):
        warm()
        times, cpu, loads = [], [], []
        for _ in range(args.repeat):
            loads.append(os.getloadavg()[0])
            t0, c0 = time.perf_counter(), time.process_time()
            fn()
            times.append(time.perf_counter() - t0)
            cpu.append(time.process_time() - c0)
        return {"min_s": min(times), "median_s": statistics.median(times), "cpu_s": min(cpu),
                "load_avg_1min": loads}

    _, mask = scene.pixel_normals()
    small = Scene(resolution=16)
    stats = quadrature.RenderStats()
    q = timed(lambda: quadrature.render(brdf, scene, stats=stats), lambda: quadrature.render(brdf, small))
    n = stats.evaluations
    q.update(evaluations=n, object_pixels=int(mask.any(2).sum()),
             evaluations_per_pixel=n / max(1, int(mask.any(2).sum())),
             us_per_evaluation=1e6 * q["min_s"] / max(1, n))
    out["quadrature"] = q
    if not args.skip_mitsuba:
        from brdfkit.render.mitsuba_plugin import render_reference

        m = timed(lambda: render_reference(brdf, scene, spp=args.spp),
                  lambda: render_reference(brdf, small, spp=args.spp))
        m.update(spp=args.spp,
                 ns_per_sample_per_pixel=1e9 * m["min_s"] / (args.spp * args.resolution ** 2))
        out["mitsuba"] = m
    print(json.dumps(out, indent=1))
    return 0


FINE = dict(cosine_grid=32, half_rings=48, half_phi=40, half_phi_min=16, light_density=3.0)


class _Analytic:
    """A synthetic material in closed form (no table)."""

    def __init__(self, material):
        import torch

        self.m, self.device, self.name = material, torch.device("cpu"), material.name

    def eval_dirs(self, wi, wo):
        import torch

        from brdfkit.synthetic import evaluate

        return torch.from_numpy(evaluate(self.m, wi.double().numpy(), wo.double().numpy())).float()


def _brute_force(material, normal, env, n=800):
    """Radiance at a sphere normal by a midpoint rule over an ``n x 2n`` lat-long grid."""
    import numpy as np
    import torch

    from brdfkit.render.envmap import uv_to_direction
    from brdfkit.render.quadrature import _frames
    from brdfkit.synthetic import evaluate

    t, b = (a[0].numpy() for a in _frames(torch.tensor(normal[None], dtype=torch.float64)))
    wo = np.array([t[2], b[2], normal[2]])
    u = (np.arange(2 * n) + 0.5) / (2 * n)
    total = np.zeros(3)
    for vs in np.array_split((np.arange(n) + 0.5) / n, 16):
        d = uv_to_direction(u[None, :], vs[:, None]).reshape(-1, 3)
        dw = np.repeat(2 * np.pi ** 2 * np.sin(np.pi * vs) / (n * 2 * n), 2 * n)
        wi = np.stack([d @ t, d @ b, d @ normal], -1)
        f = evaluate(material, wi, np.broadcast_to(wo, wi.shape))
        radiance = env.radiance(torch.from_numpy(d)).double().numpy()
        total += (radiance * f * np.clip(wi[:, 2:3], 0, None) * dw[:, None]).sum(0)
    return total


def accuracy(threads: int) -> dict:
    import dataclasses

    import numpy as np
    import torch

    from brdfkit import metrics, synthetic
    from brdfkit.render import quadrature
    from brdfkit.render.brdf import TableBRDF
    from brdfkit.render.envmap import reference_envmap
    from brdfkit.render.scene import REFERENCE, Scene

    torch.set_num_threads(threads)
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
