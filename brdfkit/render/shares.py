"""What a quadrature pair's weight is made of, per pair: the techniques' share terms and the
environment's radiance in the pair's direction (NumPy).

* :func:`theta_terms`: the shares' factors that depend on ``theta_h`` alone (the
  half-vector rings' density, the cut at ``half_extent``, the hand-over to the light
  nodes), with :func:`ring_constants`, the rings' density law;
* :func:`uv`, :func:`outside`: a world direction's texture coordinates, and one minus the
  light rectangles' ramp there (where the light nodes take over);
* :class:`EnvLookup`: the environment's radiance at texture coordinates, Mitsuba's
  bilinear lookup (:meth:`brdfkit.render.envmap.EnvMap.radiance`) in float32.

:mod:`brdfkit.render.pairs` combines them into the pairs' weights; the method is
:mod:`brdfkit.render.quadrature`'s.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["ring_constants", "theta_terms", "uv", "outside", "EnvLookup"]

_F32 = np.float32
_HALF_PI = math.pi / 2


def _smoothstep(x):
    """``3 x^2 - 2 x^3`` of ``x`` clamped to ``[0, 1]``, in place: ``x`` a temporary."""
    np.clip(x, 0.0, 1.0, out=x)
    t = x * -2.0
    t += 3.0
    x *= x
    x *= t
    return x


def ring_constants(q) -> tuple[float, float]:
    """``(e, c)``: ``8 pi dtheta/du`` of the half-vector rings ``theta = pi/2 (u / K)^p``
    (:class:`brdfkit.render.nodes.NodeSet`), as a function of ``theta``, is ``c theta^e``.

    Examples
    --------
    >>> from brdfkit.render.scene import QUADRATURE
    >>> e, c = ring_constants(QUADRATURE)
    >>> round(e, 6) == round((QUADRATURE.half_power - 1) / QUADRATURE.half_power, 6)
    True
    """
    k, p = q.half_rings, q.half_power
    e = (p - 1) / p
    return e, 8 * math.pi * _HALF_PI * (p / k) * math.exp(-e * math.log(_HALF_PI))


def theta_terms(q, th, light=True):
    """``(g, s_x, s_y)`` of ``theta_h`` (NumPy, any float dtype; ``s_y`` None unless
    ``light``): the share terms that depend on ``theta_h`` alone.

    With ``d_B`` and ``d_C`` the B and C node densities of
    :func:`brdfkit.render.nodes.half_share`: ``d_C / d_B = d_C (wo . h) g``, so that
    ``s_B0 = (1 - s_x) / (1 + (d_C (wo . h) g)^k)``; ``s_x`` is the smoothstep of the cut
    at ``half_extent`` (``cut = 1 - s_x``) and ``s_y = 1 - beta`` (the hand-over to the
    light nodes between ``light_handover``).
    """
    th = np.maximum(th, 1e-12)
    log_th = np.log(th)
    e, c = ring_constants(q)
    s = np.sin(th)
    m = np.sqrt(s)
    m *= q.half_phi
    np.maximum(m, q.half_phi_min, out=m)
    g = log_th * e
    np.exp(g, out=g)
    g *= s
    g *= c
    g /= m
    lo, hi = math.log(q.light_handover[0]), math.log(q.light_handover[1])
    if light:
        log_th -= lo
        log_th *= 1 / (hi - lo)
    sy = _smoothstep(log_th) if light else None
    th *= 1 / q.half_extent
    return g, _smoothstep(th), sy


def uv(x, y, z):
    """Texture coordinates of world directions given by their components (the
    environment's convention, :func:`brdfkit.render.envmap.direction_to_uv`)."""
    u = np.arctan2(x, -z)
    u *= 1 / (2 * math.pi)
    u -= np.floor(u)
    v = np.arccos(np.clip(y, -1.0, 1.0))
    v *= 1 / math.pi
    return u, v


def outside(rects, u, v):
    """``1 - rho``: one minus the light rectangles' ramp (1 inside a rectangle, falling to
    0 over its margin), from texture coordinates; computed as such so that it keeps its
    relative precision next to 0 (float32 ``rho`` rounds to 1 within 6e-8 of it).

    A rectangle at least twice its ramps wide has at most one ramp below 1 at any ``u``
    (and ``v``), so its product of four smoothsteps is ``s(a) s(b)``, ``a`` and ``b`` the
    distances to the nearer edges in ``u`` and ``v`` over the ramp widths;
    ``1 - s(a) s(b) = s'(a) + s'(b) - s'(a) s'(b)`` with ``s'(x) = 1 - s(x) = s(1 - x)``.
    ``u`` is taken periodically for a rectangle crossing ``u = 0`` or 1.
    """
    out = None
    for u0, u1, v0, v1, ru, rv in rects:
        if u1 - u0 < 2 * ru or v1 - v0 < 2 * rv:
            uu = np.where(u < u0, u + 1.0, u) if u0 < 0 else u
            o = 1 - (_smoothstep((uu - u0) / ru) * _smoothstep((u1 - uu) / ru)
                     * _smoothstep((v - v0) / rv) * _smoothstep((v1 - v) / rv))
        else:
            du = u - (u0 + u1) / 2
            if u0 < 0 or u1 > 1:
                du -= np.round(du)
            np.abs(du, out=du)
            du *= 1 / ru
            du += 1 - (u1 - u0) / (2 * ru)
            ou = _smoothstep(du)
            dv = np.abs(v - (v0 + v1) / 2)
            dv *= 1 / rv
            dv += 1 - (v1 - v0) / (2 * rv)
            ov = _smoothstep(dv)
            o = ou + ov
            o -= ou * ov
        out = o if out is None else np.minimum(out, o, out=out)
    return np.ones_like(u) if out is None else out


class EnvLookup:
    """:meth:`brdfkit.render.envmap.EnvMap.radiance` (Mitsuba's bilinear lookup) from
    texture coordinates, float32: the map's three channels as planes with their first
    column repeated after the last (the wrap in ``u``), four texels gathered a channel
    (contiguous arithmetic: twice as fast as gathering 16-byte texels and weighting them
    with a broadcast)."""

    def __init__(self, env):
        img = np.asarray(env.image, _F32)
        self.h, self.w = img.shape[:2]
        planes = np.zeros((3, self.h, self.w + 1), _F32)
        planes[:, :, :self.w] = np.moveaxis(img, -1, 0)
        planes[:, :, self.w] = planes[:, :, 0]
        self.planes = planes.reshape(3, -1)

    def __call__(self, u, v):
        """float32 ``(3, M)`` radiance at texture coordinates ``u, v`` ``(M,)``."""
        w, h = self.w, self.h
        x = u - 0.5 / w
        x *= w  # column j at u = (j + 0.5) / W
        x -= np.floor(x * (1 / w)) * w
        y = v * (h - 1)
        x0 = np.floor(x)
        np.clip(x0, 0, w - 1, out=x0)
        y0 = np.floor(y)
        np.clip(y0, 0, h - 2, out=y0)
        x -= x0
        y -= y0
        i = y0.astype(np.intp)
        i *= w + 1
        i += x0.astype(np.intp)
        ox, oy = 1 - x, 1 - y
        weights = (ox * oy, x * oy, ox * y, x * y)
        corners = (i, i + 1, i + (w + 1), i + (w + 2))
        out = np.empty((3, x.shape[0]), _F32)
        for c, plane in enumerate(self.planes):
            o = plane[corners[0]] * weights[0]
            for k in range(1, 4):
                o += plane[corners[k]] * weights[k]
            out[c] = o
        return out
