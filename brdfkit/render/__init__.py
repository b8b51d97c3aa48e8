"""Rendering: the reference scene (deterministic quadrature) and a Mitsuba 3 plugin.

Modules, one concept each:

* :mod:`.scene`: the reference scene's constants (sphere, orthographic camera, resolution,
  samples, quadrature settings);
* :mod:`.envmap`: the procedural HDR environment map;
* :mod:`.brdf`: BRDFs a renderer can evaluate (dense tables, neural BRDFs) and
  :func:`~.brdf.load_brdf`;
* :mod:`.quadrature`: the noise-free reference renderer (torch, no path tracing);
* :mod:`.mitsuba_plugin`: the ``brdfkit`` BSDF for Mitsuba 3 and path-traced renders;
* :mod:`.image`: EXR and PNG files.

Nothing here is imported by ``import brdfkit``; torch and Mitsuba load only when used.
"""

from __future__ import annotations

__all__ = ["render", "TableBRDF", "load_brdf"]


def render(brdf, scene=None, env=None, progress=None):
    """The reference-scene image of ``brdf`` by the quadrature renderer.

    Parameters
    ----------
    brdf
        Object with ``eval_dirs`` (:class:`~brdfkit.render.brdf.TableBRDF`,
        :class:`~brdfkit.model.brdf.NeuralBRDF`).
    scene, env, progress
        As for :func:`brdfkit.render.quadrature.render` (default: the reference scene).

    Returns
    -------
    numpy.ndarray
        float32 ``(R, R, 3)`` linear-sRGB radiance, background black
        (:func:`brdfkit.render.quadrature.render` also returns the object mask).
    """
    from .quadrature import render as _render
    from .scene import REFERENCE

    return _render(brdf, scene or REFERENCE, env=env, progress=progress)[0]


def __getattr__(name):
    if name in ("TableBRDF", "load_brdf"):
        from . import brdf

        return getattr(brdf, name)
    raise AttributeError(f"module 'brdfkit.render' has no attribute {name!r}")
