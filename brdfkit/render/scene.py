"""The reference scene: one sphere, one camera, one environment, fixed settings.

Every render that a metric compares is made in this scene, by either renderer
(:mod:`brdfkit.render.quadrature`, :mod:`brdfkit.render.mitsuba3`):

* a unit sphere at the origin, the material under test on its whole surface;
* an **orthographic** camera on the ``+z`` axis looking down ``-z``, ``y`` up, seeing the
  square ``[-VIEW_HALF_WIDTH, VIEW_HALF_WIDTH]^2`` of the ``xy`` plane, so each pixel's
  normal is known in closed form and every pixel sees the object with the same view
  direction ``wo = (0, 0, 1)``. Image row 0 is the top (``+y``), column 0 the left
  (``-x``);
* lit only by the distant environment :func:`brdfkit.render.envmap.reference_envmap`
  (direct lighting: a convex object cannot see itself, so one bounce is exact);
* background pixels (centre outside the sphere) are **black** (emitters hidden), and the
  image metrics are taken over the **whole image**, background included (identical zeros
  in both images, so the object is what differs);
* ``RESOLUTION x RESOLUTION`` pixels, one sample at each pixel centre for the
  quadrature renderer (``supersample = s`` averages an ``s x s`` grid per pixel, which
  is what Mitsuba's box filter converges to), ``SPP`` box-filtered samples per pixel
  for Mitsuba.

The quadrature settings (node counts per technique) are the ``QUADRATURE`` constants,
described in :mod:`brdfkit.render.quadrature` and ``docs/render.md``.
"""

from __future__ import annotations

import dataclasses
import math

__all__ = ["Scene", "REFERENCE", "RESOLUTION", "VIEW_HALF_WIDTH", "SPP", "Quadrature", "QUADRATURE", "reference_scene"]

RESOLUTION = 256
VIEW_HALF_WIDTH = 1.1
SPP = 256
ENV_SIZE = (256, 128)


@dataclasses.dataclass(frozen=True)
class Quadrature:
    """Node counts of the deterministic quadrature (see :mod:`.quadrature`).

    Attributes
    ----------
    cosine_grid
        ``n``: an ``n x n`` stratified grid mapped to cosine-distributed local directions.
    half_rings, half_power
        Half-vector rings at ``theta_h = pi/2 (u / K)^p``, ``u = k + 1/2``, ``K = half_rings``,
        ``p = half_power``; only the rings below ``half_extent`` are used.
    half_phi, half_phi_min
        Azimuths per ring: ``max(half_phi_min, round(half_phi sqrt(sin(theta_h))))``.
    half_extent
        ``theta_h`` (radians) at which the half-vector nodes' share is cut smoothly to 0.
    share_power
        Exponent ``k`` of the density ratio in the half-vector share
        ``1 / (1 + (d_C / d_B)^k)`` (1: the balance heuristic).
    light_density
        Scale of the light nodes per axis in each of the environment's bright rectangles
        (``EnvMap.bright`` gives the counts at 1).
    light_handover
        ``(theta_a, theta_b)`` radians: inside a light rectangle the half-vector nodes
        keep their share for ``theta_h < theta_a`` and hand it to the light nodes by
        ``theta_b``.
    """

    cosine_grid: int = 10
    half_rings: int = 20
    half_power: float = 3.0
    half_phi: int = 12
    half_phi_min: int = 5
    half_extent: float = math.pi / 2
    light_density: float = 0.75
    share_power: float = 1.0
    light_handover: tuple = (0.004, 0.04)


QUADRATURE = Quadrature()


@dataclasses.dataclass(frozen=True)
class Scene:
    """Reference-scene settings that a caller may change (resolution, samples)."""

    resolution: int = RESOLUTION
    view_half_width: float = VIEW_HALF_WIDTH
    spp: int = SPP
    quadrature: Quadrature = QUADRATURE
    supersample: int = 1

    def pixel_normals(self):
        """Sphere normals at the pixel sample points and their mask (NumPy).

        Each pixel has ``supersample^2`` sample points on a regular grid (one, at the
        pixel centre, by default); the quadrature renderer averages them.

        Returns
        -------
        tuple
            ``(normals (R, R, S, 3) float64, mask (R, R, S) bool)``, ``S = supersample^2``;
            normals of points off the sphere are ``(0, 0, 1)``.
        """
        import numpy as np

        r, s = self.resolution, self.supersample
        sub = (np.arange(s) + 0.5) / s
        c = ((np.arange(r)[:, None] + sub[None, :]) / r * 2 - 1)  # (R, s)
        x = c[None, None, :, None, :] * self.view_half_width  # (1, 1, R, 1, s): columns
        y = -c[:, :, None, None, None] * self.view_half_width  # (R, s, 1, 1, 1): rows
        x, y = np.broadcast_arrays(x, y)  # (R, s, R, 1, s)
        x = x.transpose(0, 2, 1, 3, 4).reshape(r, r, s * s)
        y = y.transpose(0, 2, 1, 3, 4).reshape(r, r, s * s)
        rho2 = x * x + y * y
        mask = rho2 < 1.0
        z = np.sqrt(np.clip(1.0 - rho2, 0.0, None))
        n = np.stack([x, y, z], -1)
        n[~mask] = (0.0, 0.0, 1.0)
        return n, mask


REFERENCE = Scene()


def reference_scene(resolution: int | None = None, supersample: int = 1):
    """The reference scene at ``resolution`` pixels square (default its own 256)."""
    return dataclasses.replace(REFERENCE, resolution=int(resolution or REFERENCE.resolution),
                               supersample=int(supersample))
