"""``brdfkit render``: render a BRDF in a scene of the suite or a Mitsuba scene."""

from __future__ import annotations

import os
import time

import click

from brdfkit.console import console
from brdfkit.cli.common import model_option


def threads_option(f):
    """``--threads N``: threads for rendering (default: the idle cores, at least 1)."""
    return click.option("--threads", type=click.IntRange(min=1, max=1024), default=None,
                        help="Threads of the render (and of torch, for a hypernetwork's embedding; default: "
                             "cores not already busy by the load average, at least 1; docs/render.md).")(f)


@click.command("render")
@click.argument("brdf", type=click.Path(dir_okay=False))
@model_option
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="Output image (.exr, linear float32 RGB).")
@click.option("--png", type=click.Path(dir_okay=False), default=None,
              help="Also write a tone-mapped sRGB PNG (exposure 1, clipped; docs/render.md).")
@click.option("--mitsuba", is_flag=True,
              help="Path-trace the scene with Mitsuba 3 instead of the quadrature.")
@click.option("--scene", "scene", default="reference", show_default=True, metavar="NAME|FILE.xml",
              help="A scene of the suite (reference, backlight, rim, small-lights, overcast, sunset; "
                   "docs/render.md), or a Mitsuba XML scene file to render instead (with --bsdf-id).")
@click.option("--bsdf-id", default=None, help="Id of the <bsdf> in --scene FILE.xml that gets the BRDF.")
@click.option("--spp", type=click.IntRange(min=1), default=None,
              help="Samples per pixel for Mitsuba (default 256, or the scene's own).")
@click.option("--resolution", type=click.IntRange(min=8, max=8192), default=None,
              help="Image size in pixels (square; default 256; for --scene, overrides the film).")
@click.option("--supersample", type=click.IntRange(min=1, max=16), default=1, show_default=True,
              help="Quadrature: average an S x S grid of points per pixel (anti-aliasing).")
@threads_option
@click.option("--quiet", is_flag=True, help="No progress bar.")
def command(brdf, model_path, output, png, mitsuba, scene, bsdf_id, spp, resolution, supersample,
            threads, quiet):
    """Render BRDF (a MERL .binary, an RGL .bsdf, or an embedding .emb with -m MODEL) to an EXR image.

    By default the reference scene (a sphere under a fixed HDR environment,
    docs/render.md) is computed by deterministic quadrature: noise-free, same bytes
    every run. --scene NAME puts the sphere under another scene of the suite.
    --mitsuba path-traces the same scene with Mitsuba 3 and the `brdfkit` BSDF plugin;
    --scene FILE.xml --bsdf-id NAME renders your own Mitsuba scene with the BRDF bound
    to the BSDF of that id. An RGL .bsdf is evaluated straight from the file,
    conditioned on the direction toward the camera, as Mitsuba 3's `measured` plugin
    evaluates it (a measured file is not reciprocal; docs/rgl-bsdf.md).
    """
    from brdfkit.atomic import refuse_overwrite_of_inputs
    from brdfkit.errors import InputError
    from brdfkit.files.brdf_file import file_type
    from brdfkit.files.render_file import render_brdf_file
    from brdfkit.files.brdf_file import EmbeddingDecoders
    from brdfkit.runtime import set_cpu_threads, set_torch_threads
    from brdfkit.render.image import write_exr, write_png

    file_type(brdf)
    scene_file = scene if scene.lower().endswith(".xml") or os.path.isfile(scene) else None
    if scene_file is None:
        from brdfkit.render.scene_suite import scene_names

        if "," in scene or scene.strip() == "all":
            raise InputError(f"--scene {scene}: render takes one scene (a name of the suite, or a Mitsuba .xml file)")
        scene_names(scene)  # an unknown name is refused here, before anything is read
    if scene_file is not None and not bsdf_id:
        raise InputError(f"{scene_file}: --scene needs --bsdf-id NAME (the <bsdf id=...> to replace)")
    if bsdf_id and scene_file is None:
        raise InputError("--bsdf-id is only used with --scene FILE.xml")
    if png is not None and os.path.abspath(png) == os.path.abspath(output):
        raise InputError(f"{png}: --png and -o name the same file")
    inputs = [brdf, model_path, scene_file]
    refuse_overwrite_of_inputs(output, inputs)
    refuse_overwrite_of_inputs(png, inputs)
    if not output.lower().endswith(".exr"):
        raise InputError(f"{output}: the output image must be an .exr file (use --png for a PNG)")
    set_cpu_threads(threads)
    t0 = time.perf_counter()
    models = EmbeddingDecoders(model_path, before_load=lambda: set_torch_threads(threads))
    img, how = render_brdf_file(brdf, model_path, resolution=resolution, mitsuba=mitsuba, spp=spp,
                                supersample=supersample, scene_file=scene_file, bsdf_id=bsdf_id,
                                progress=not quiet, scene="reference" if scene_file else scene, model=models)
    write_exr(output, img)
    if png is not None:
        write_png(png, img)
    out = console()
    out.print(f"{output}: {img.shape[1]}x{img.shape[0]}, {how}, {time.perf_counter() - t0:.1f} s"
              + (f"; {png}" if png else ""), soft_wrap=True)
