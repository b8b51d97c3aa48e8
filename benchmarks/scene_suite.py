"""The scene suite in pictures (``docs/render.md``): three materials rendered in every
scene, with the brightest pixel of a white Lambertian sphere.

Each row is a scene of :mod:`brdfkit.render.scene_suite` (the judged suite, then the first
objective scenes with ``--objective N``); the columns a white Lambertian sphere
(albedo 1), a glossy GGX dielectric and the stiff mirror of :mod:`brdfkit.materials.synthetic`,
rendered by the quadrature at ``--px`` pixels and shown as displayed (exposure 1,
clipped, sRGB).

    python benchmarks/scene_suite.py --px 96 --objective 2 -o docs/images/scene-suite.png
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys

sys.path.insert(0, os.path.dirname(__file__))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--px", type=int, default=96, help="render size, pixels")
    ap.add_argument("--objective", type=int, default=2, help="objective scenes to show after the suite")
    ap.add_argument("-o", "--output", required=True, help="the PNG")
    args = ap.parse_args(argv)

    from brdfkit.figures.canvas import pyplot, save_png, show_render
    from brdfkit.materials import synthetic
    from brdfkit.render.quadrature import render
    from brdfkit.render.renderable import TableBRDF
    from brdfkit.render.scene import REFERENCE
    from brdfkit.render.scene_suite import OBJECTIVE_SCENES, SUITE, scene_env
    from brdfkit.testing.examples import lambertian_table

    scene = dataclasses.replace(REFERENCE, resolution=args.px)
    brdfs = {"white Lambertian": TableBRDF(lambertian_table((1.0, 1.0, 1.0))),
             "glossy dielectric": TableBRDF(synthetic.table(synthetic.library(3, seed=1, stiff=False)[0])),
             "mirror": TableBRDF(synthetic.table(synthetic.STIFF[0]))}
    names = list(SUITE) + list(OBJECTIVE_SCENES)[:args.objective]
    plt = pyplot()
    fig, axes = plt.subplots(len(names), len(brdfs), figsize=(1.45 * len(brdfs) + 1.6, 1.45 * len(names)))
    for i, name in enumerate(names):
        env = scene_env(name)
        for j, (label, brdf) in enumerate(brdfs.items()):
            img, _ = render(brdf, scene, env=env)
            show_render(axes[i, j], img, label if i == 0 else None, fontsize=8)
            if j == 0:
                role = "judge" if name in SUITE else "objective"
                axes[i, j].text(-0.08, 0.5, f"{name}\n({role})\nwhite max {img.max():.2f}", fontsize=7,
                                ha="right", va="center", transform=axes[i, j].transAxes)
            print(f"{name:13s} {label:18s} max {img.max():8.2f}", flush=True)
    fig.subplots_adjust(left=0.3, right=0.99, top=0.95, bottom=0.01, wspace=0.05, hspace=0.08)
    save_png(fig, args.output)
    print(f"wrote {args.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
