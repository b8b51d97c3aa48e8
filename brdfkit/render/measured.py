"""An RGL ``.bsdf`` file rendered as Mitsuba 3 renders it: straight from the file.

Mitsuba 3's ``measured`` BSDF (``src/bsdfs/measured.cpp``) evaluates a file with its
adaptive parameterization conditioned on ``si.wi``, the direction toward the camera,
and returns ``f cos(theta)`` of the direction toward the light. A measured file is not
reciprocal (``docs/rgl-bsdf.md``: RGL's files are up to 0.21 from reciprocal in log
RMS), so a renderer must condition on the same direction to show the same material; a
MERL table, which holds one value per reciprocal pair, cannot (the best reciprocal table
of a real file renders 25 to 51 dB from the file itself, 42 in the mean).

:class:`MeasuredBRDF` is the renderable BRDF (:mod:`brdfkit.render.renderable`) of a
file: ``eval_dirs(wi, wo)`` with ``wi`` toward the light and ``wo`` toward the camera (the
convention of every brdfkit renderer) is :meth:`brdfkit.io.rgl_bsdf.RglBsdf.eval` at
``(wo, wi)`` divided by ``cos(theta_i)``, which the renderers multiply back. Negative
values of the file (RGL's RGB files hold them where a measured spectrum lies outside
the sRGB gamut) pass through, as in Mitsuba.

May import: the ground floor, :mod:`brdfkit.io`; numpy.
"""

from __future__ import annotations

import numpy as np

__all__ = ["MeasuredBRDF"]


class MeasuredBRDF:
    """A measured ``.bsdf`` material as a renderable BRDF, conditioned on the view.

    Parameters
    ----------
    bsdf
        :class:`brdfkit.io.rgl_bsdf.RglBsdf`.
    name
        Shown in progress messages and metric tables.

    Attributes
    ----------
    device
        Always the CPU: the file is evaluated in NumPy (float64), about 1.4 us a pair on
        one core (a 256-pixel render, 11.8 million pairs, takes 15 to 20 s more than a
        table's).
    """

    def __init__(self, bsdf, name: str = "measured"):
        self.bsdf = bsdf
        self.name = name
        self.device = "cpu"

    def eval_dirs(self, wi, wo):
        """BRDF ``(N, 3)`` float32 at local direction pairs (NumPy ``(N, 3)``): ``wi``
        toward the light, ``wo`` toward the camera (Mitsuba's ``si.wi``); 0 where either
        is at or below the horizon, or where the file's warp has an empty row."""
        light = np.asarray(wi, np.float64).reshape(-1, 3)
        view = np.asarray(wo, np.float64).reshape(-1, 3)
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            f = self.bsdf.eval(view, light) / light[:, 2:3]
        keep = (light[:, 2:3] > 0) & (view[:, 2:3] > 0) & np.isfinite(f)
        return np.where(keep, f, 0.0).astype(np.float32)
