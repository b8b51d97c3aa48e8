"""What every PNG sheet shares: the pyplot import (Agg backend), bare axes, a render shown
as displayed (resampled smoothly to its tile), its silhouette antialiased, the PNG written
atomically."""

from __future__ import annotations

import os

__all__ = ["SMOOTH", "SILHOUETTE_SAMPLES", "pyplot", "bare_axes", "show_render", "show_image", "save_png",
           "antialias_silhouette"]

SILHOUETTE_SAMPLES = 4
"""Points a side of each silhouette pixel of a sheet's render (:func:`antialias_silhouette`)."""

SMOOTH = "lanczos"
"""How a sheet resamples an image to its tile's pixels (matplotlib's ``interpolation``, on
the displayed colours): Lanczos, so that a render enlarged by a factor that is not whole
(a 128 px render in a tile of about 237 px) has smooth edges, not rows and columns of
pixels drawn twice. Deterministic: the same image gives the same PNG. A drawing that puts
one render pixel on one PNG pixel (the interpolation strip) passes ``"nearest"``."""


def pyplot():
    """``matplotlib.pyplot`` on the Agg backend: a sheet is a file, never a window, and
    needs no display."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def bare_axes(ax) -> None:
    """No ticks and no frame: the axes shows an image or text only."""
    ax.set_xticks([])
    ax.set_yticks([])
    for spine in ax.spines.values():
        spine.set_visible(False)


def show_image(ax, image, interpolation: str = SMOOTH, **kwargs):
    """``ax.imshow(image, **kwargs)`` resampled by ``interpolation`` (default
    :data:`SMOOTH`) on the displayed colours (``interpolation_stage="rgba"``: a colour
    map's colours are blended, never a value outside the data's range); returns the
    image artist."""
    return ax.imshow(image, interpolation=interpolation, interpolation_stage="rgba", **kwargs)


def show_render(ax, image, title: str | None = None, fontsize: float = 10, interpolation: str = SMOOTH) -> None:
    """Draw a linear RGB render ``(H, W, 3)`` as displayed
    (:func:`brdfkit.render.display.display_encode`: exposure 1, clipped, sRGB), resampled
    to the axes by ``interpolation`` (:func:`show_image`), on bare axes, with ``title``
    above it."""
    from brdfkit.render.display import display_encode

    show_image(ax, display_encode(image), interpolation)
    if title is not None:
        ax.set_title(title, fontsize=fontsize)
    bare_axes(ax)


def save_png(fig, output: str | os.PathLike) -> None:
    """Write ``fig`` to the PNG ``output`` atomically (:func:`brdfkit.atomic.atomic_path`)
    at the figure's own dpi, then close it."""
    from brdfkit.atomic import atomic_path

    with atomic_path(os.fspath(output)) as tmp:
        fig.savefig(tmp, format="png", dpi=fig.dpi)
    pyplot().close(fig)


def antialias_silhouette(brdfs, images, scene=None, env=None, supersample: int = SILHOUETTE_SAMPLES) -> list:
    """Reference-scene renders with their silhouette antialiased: each pixel that the
    sphere's outline crosses (some of its ``supersample x supersample`` points on the
    sphere, some off it) becomes the mean of those points, the ones on the sphere shaded
    by the quadrature (:func:`brdfkit.render.quadrature.render_pixels`) and the others
    black: what ``brdfkit render --supersample`` gives at those pixels. Every other pixel
    is left as rendered (one point at its centre), so the sphere's inside, and every score
    taken from the renders themselves, are unchanged; the rim costs about ``4 pi R`` pixels
    of ``supersample^2`` points each, a fraction of the render.

    Parameters
    ----------
    brdfs
        The BRDFs (``eval_dirs``) of ``images``, in order.
    images
        float32 ``(R, R, 3)`` renders of the reference scene (``scene``), one a BRDF.
    scene
        :class:`brdfkit.render.scene.Scene` of the renders (default: the reference scene at
        the images' size).
    env
        Their environment (default the reference one; a suite scene's,
        :func:`brdfkit.render.scene_suite.scene_env`).
    supersample
        Points a side of a silhouette pixel.

    Returns
    -------
    list
        float32 ``(R, R, 3)`` images, new arrays.
    """
    import dataclasses

    import numpy as np

    from brdfkit.render.envmap import reference_envmap
    from brdfkit.render.quadrature import render_pixels
    from brdfkit.render.scene import reference_scene

    images = [np.asarray(img, np.float32) for img in images]
    if not images:
        return []
    base = scene or reference_scene(images[0].shape[0])
    fine = dataclasses.replace(base, supersample=int(supersample))
    normals, inside = fine.pixel_normals()
    edge = inside.any(2) & ~inside.all(2)
    points = normals[edge][inside[edge]]
    env = env if env is not None else reference_envmap()
    out = []
    for brdf, img in zip(brdfs, images):
        samples = np.zeros(inside[edge].shape + (3,), np.float32)
        samples[inside[edge]] = render_pixels(brdf, points, env, q=fine.quadrature)
        img = img.copy()
        img[edge] = samples.mean(1)
        out.append(img)
    return out
