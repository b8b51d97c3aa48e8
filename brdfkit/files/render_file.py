"""Render a BRDF file (``.binary`` MERL table, RGL ``.bsdf`` straight from the file as
Mitsuba 3 renders it, or ``.emb`` with its model): the work of ``brdfkit render`` and of
``brdfkit metrics`` for BRDF inputs.

Three renderers (``docs/render.md``): the deterministic quadrature of the reference
scene (:mod:`brdfkit.render.quadrature`, the default), the reference scene path-traced by
Mitsuba 3, or a user's Mitsuba XML scene with the BRDF bound to one of its BSDFs
(:mod:`brdfkit.render.mitsuba3`).
"""

from __future__ import annotations

import dataclasses
import os

from brdfkit.console import ProgressBar
from brdfkit.render.scene import reference_scene

__all__ = ["render_brdf_file", "render_brdf_files"]


def render_brdf_files(paths, *, resolution: int | None = None, progress: bool = True, model=None,
                      tables: dict | None = None, scene: str = "reference") -> list:
    """Quadrature renders of several BRDF files in one scene, in one pass
    (:func:`brdfkit.render.quadrature.render_many`: each image equals
    :func:`render_brdf_file`'s of that file, to the bit).

    Parameters
    ----------
    paths
        ``.binary`` / ``.bsdf`` / ``.emb`` files.
    resolution, progress, model, scene
        As for :func:`render_brdf_file`.
    tables
        Optional ``{path: dense table}`` of ``.binary`` files the caller has already read
        (``brdfkit metrics`` reads each once).

    Returns
    -------
    list
        float32 ``(R, R, 3)`` linear RGB image per file.
    """
    from brdfkit.render.renderable import TableBRDF
    from brdfkit.files.brdf_file import load_brdf
    from brdfkit.render.quadrature import render_many
    from brdfkit.render.scene_suite import scene_env

    tables = tables or {}
    brdfs = [TableBRDF(tables[p], name=os.path.splitext(os.path.basename(p))[0]) if p in tables
             else load_brdf(p, model=model) for p in paths]
    # One pass needs one device (a table and a model's BRDF may sit on different ones).
    groups: dict = {}
    for i, b in enumerate(brdfs):
        groups.setdefault(str(getattr(b, "device", "cpu")), []).append(i)
    images = [None] * len(brdfs)
    for idx in groups.values():
        with ProgressBar(f"quadrature {' + '.join(brdfs[i].name for i in idx)}", enabled=progress) as bar:
            done = render_many([brdfs[i] for i in idx], reference_scene(resolution), env=scene_env(scene),
                               progress=bar if progress else None)
        for i, (img, _) in zip(idx, done):
            images[i] = img
    return images


def render_brdf_file(path, model_path=None, *, resolution: int | None = None, mitsuba: bool = False,
                     spp: int | None = None, supersample: int = 1, scene_file=None, bsdf_id: str | None = None,
                     progress: bool = True, model=None, scene: str = "reference"):
    """Render a ``.binary`` / ``.bsdf`` / ``.emb`` file.

    Parameters
    ----------
    path
        The BRDF file.
    model_path, model
        The model of an ``.emb`` (a path, or a model already loaded); for ``scene_file``,
        also the model of the scene's other ``brdfkit`` BSDFs that name none.
    resolution
        Image size in pixels, square (default: the reference scene's 256); with
        ``scene_file``, overrides the film's size.
    mitsuba
        Path-trace the reference scene with Mitsuba instead of the quadrature.
    spp
        Mitsuba samples per pixel (default: the scene's).
    supersample
        Quadrature: an ``S x S`` grid of points per pixel.
    scene_file, bsdf_id
        A Mitsuba XML scene and the id of the BSDF that gets the BRDF.
    scene
        The suite scene (:mod:`brdfkit.render.scene_suite`) of the quadrature or Mitsuba
        render: its environment around the reference scene's sphere and camera.
    progress
        Show a progress bar on stderr.

    Returns
    -------
    tuple
        ``(image, how)``: float32 ``(H, W, 3)`` linear RGB, and a short description for
        messages (renderer, samples, BRDF evaluations).
    """
    from brdfkit.files.brdf_file import load_brdf
    from brdfkit.render.scene import REFERENCE

    from brdfkit.render.scene_suite import scene_env

    env = scene_env(scene)  # an unknown name is refused before the file is read
    brdf = load_brdf(path, model_path, model=model)
    name = scene
    scene = dataclasses.replace(REFERENCE, resolution=int(resolution or REFERENCE.resolution),
                                supersample=int(supersample))
    if scene_file is not None:
        from brdfkit.render.mitsuba3.scenes import load_user_scene, render_scene

        sc, n = load_user_scene(scene_file, bsdf_id, brdf, resolution=resolution, spp=spp, model_path=model_path)
        with ProgressBar(f"Mitsuba {os.path.basename(scene_file)}", enabled=progress) as bar:
            img = render_scene(sc, n, progress=bar if progress else None)
        return img, f"Mitsuba, {os.path.basename(scene_file)}, {n} spp"
    if mitsuba:
        from brdfkit.render.mitsuba3.scenes import render_reference

        n = int(spp or scene.spp)
        with ProgressBar(f"Mitsuba {brdf.name}", enabled=progress) as bar:
            img = render_reference(brdf, scene, spp=n, progress=bar if progress else None, env=env)
        return img, f"Mitsuba, scene {name}, {n} spp"
    from brdfkit.render.quadrature import RenderStats, render

    stats = RenderStats()
    with ProgressBar(f"quadrature {brdf.name}", enabled=progress) as bar:
        img, _ = render(brdf, scene, env=env, progress=bar if progress else None, stats=stats)
    return img, f"quadrature, scene {name}, {stats.evaluations:,} BRDF evaluations"
