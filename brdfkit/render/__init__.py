"""Rendering: the reference scene (deterministic quadrature), the display encoding, the
render-aligned error, and Mitsuba 3.

Modules, one concept each:

* :mod:`.scene`: the reference scene's constants (sphere, orthographic camera, resolution,
  samples, quadrature settings);
* :mod:`.envmap`: the procedural HDR environment map;
* :mod:`.renderable`: BRDFs a renderer evaluates (dense tables, stacks of them; a neural
  BRDF is :class:`brdfkit.hypernet.neural_brdf.NeuralBRDF`);
* :mod:`.measured`: an RGL ``.bsdf`` file evaluated straight from the file, conditioned
  on the view as Mitsuba 3's ``measured`` BSDF is;
* :mod:`.nodes`, :mod:`.shares`, :mod:`.pairs`: the quadrature's node sets, the share
  terms and environment radiance a pair's weight is made of, and its (pixel, node) pairs
  with their MERL grid coordinates;
* :mod:`.lookup`: a table prepared for a render's trilinear lookups;
* :mod:`.quadrature`: the noise-free reference renderer (NumPy, no path tracing);
* :mod:`.screen`: the render-aligned error, a small render of a table or, differentiably
  in torch, of a hyponet;
* :mod:`.display`: the display encoding every image metric, PNG and error uses;
* :mod:`.image`: EXR and PNG files;
* :mod:`.scene_suite`, :mod:`.objective`: the judged scenes, and what a refinement on
  renders may descend (and the one loop every refinement runs);
* :mod:`.mitsuba3`: the ``brdfkit`` BSDF for Mitsuba 3 and path-traced renders.

May import: the ground floor, :mod:`brdfkit.geometry` and :mod:`brdfkit.io`; a renderer
evaluates any object with ``eval_pairs`` or ``eval_dirs``, and a hyponet through its
model's own methods, so nothing here imports the hypernetwork, the basis or any layer
above. BRDF *files* are rendered by :mod:`brdfkit.files.render_file`, which registers the
file loader the Mitsuba plugin opens a scene's files with. Nothing here is imported by
``import brdfkit``; a render imports no torch (only a hyponet's render on a screen, and
Mitsuba's, load it).
"""

from __future__ import annotations

from brdfkit import lazy_attributes

__all__ = ["render", "TableBRDF"]


def render(brdf, scene=None, env=None, progress=None):
    """The reference-scene image of ``brdf`` by the quadrature renderer.

    Parameters
    ----------
    brdf
        A renderable BRDF (:class:`~brdfkit.render.renderable.TableBRDF`,
        :class:`~brdfkit.hypernet.neural_brdf.NeuralBRDF`, ...).
    scene, env, progress
        As for :func:`brdfkit.render.quadrature.render` (default: the reference scene).

    Returns
    -------
    numpy.ndarray
        float32 ``(R, R, 3)`` linear-sRGB radiance, background black
        (:func:`brdfkit.render.quadrature.render` also returns the object mask).

    Examples
    --------
    >>> import numpy as np
    >>> from brdfkit.render.renderable import TableBRDF
    >>> from brdfkit.render.scene import REFERENCE
    >>> import dataclasses
    >>> small = dataclasses.replace(REFERENCE, resolution=8)
    >>> img = render(TableBRDF(np.full((90, 90, 180, 3), 1 / np.pi)), scene=small)
    >>> img.shape, bool(img.max() > 0)
    ((8, 8, 3), True)
    """
    from brdfkit.render.quadrature import render as _render
    from brdfkit.render.scene import REFERENCE

    return _render(brdf, scene or REFERENCE, env=env, progress=progress)[0]


__getattr__, _dir = lazy_attributes(__name__, {"TableBRDF": "brdfkit.render.renderable"})


def __dir__():
    return __all__
