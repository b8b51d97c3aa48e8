"""The reference scene's quadrature nodes: the fixed directions and weights of the
cosine (C), half-vector (B) and light (A) techniques, and the share each technique takes
of a direction (see :mod:`brdfkit.render.quadrature` for the method and its sources).
"""

from __future__ import annotations

import math

import numpy as np

from brdfkit.render.scene import Quadrature

__all__ = ["NodeSet", "half_share", "frames", "half_share_table"]

# Sub-grid per light patch for its averaged radiance.
_PATCH_SUBGRID = 8


def _concentric(a, b):
    """Shirley-Chiu concentric map of ``[0,1]^2`` to the unit disk."""
    x, y = 2 * a - 1, 2 * b - 1
    big = np.abs(x) > np.abs(y)
    r = np.where(big, x, y)
    phi = np.where(big, (np.pi / 4) * y / np.where(x == 0, 1, x),
                   np.pi / 2 - (np.pi / 4) * x / np.where(y == 0, 1, y))
    return r * np.cos(phi), r * np.sin(phi)


class NodeSet:
    """The fixed quadrature directions and their weights for one environment.

    Attributes
    ----------
    cosine
        float64 ``(N_C, 3)`` local directions.
    half, half_weight
        float64 ``(N_B, 3)`` local half vectors; weights in half-vector solid angle (times
        ``4 wo.h`` for the solid angle of ``wi``).
    light, light_weight, light_radiance
        float64 ``(N_A, 3)`` world directions, solid-angle weights ``(N_A,)`` and
        patch-averaged radiance ``(N_A, 3)``.
    rects
        ``(u0, u1, v0, v1, ramp_u, ramp_v)`` per light rectangle.
    """

    def __init__(self, q: Quadrature, env):
        from brdfkit.render.envmap import uv_to_direction

        self.q = q
        n = q.cosine_grid
        a, b = np.meshgrid((np.arange(n) + 0.5) / n, (np.arange(n) + 0.5) / n, indexing="ij")
        x, y = _concentric(a.ravel(), b.ravel())
        self.cosine = np.stack([x, y, np.sqrt(np.clip(1 - x * x - y * y, 0, None))], -1)

        k, p = q.half_rings, q.half_power
        u = np.arange(k) + 0.5
        theta = (np.pi / 2) * (u / k) ** p
        dtheta_du = (np.pi / 2) * p * u ** (p - 1) / k ** p
        self.ring_m = np.maximum(q.half_phi_min, np.round(q.half_phi * np.sqrt(np.sin(theta)))).astype(int)
        hs, ws = [], []
        for t, dt, m in zip(theta, dtheta_du, self.ring_m):
            f = 2 * np.pi * (np.arange(m) + 0.5) / m
            hs.append(np.stack([np.sin(t) * np.cos(f), np.sin(t) * np.sin(f), np.full(m, np.cos(t))], -1))
            ws.append(np.full(m, np.sin(t) * dt * 2 * np.pi / m))
        self.half = np.concatenate(hs)
        self.half_weight = np.concatenate(ws)

        lights, weights, rads, rects = [], [], [], []
        for (u0, u1, v0, v1, nu, nv, ru, rv) in env.bright:
            nu = max(1, round(nu * q.light_density))
            nv = max(1, round(nv * q.light_density))
            du, dv = (u1 - u0) / nu, (v1 - v0) / nv
            uc, vc = np.meshgrid(u0 + (np.arange(nu) + 0.5) * du, v0 + (np.arange(nv) + 0.5) * dv,
                                 indexing="ij")
            uc, vc = uc.ravel(), vc.ravel()
            lights.append(uv_to_direction(uc % 1.0, vc))
            # Patch integrals on an s x s sub-grid: d(omega) = 2 pi^2 sin(pi v) du dv.
            s = _PATCH_SUBGRID
            off = (np.arange(s) + 0.5) / s - 0.5
            su = (uc[:, None, None] + off[None, :, None] * du) % 1.0
            sv = vc[:, None, None] + off[None, None, :] * dv
            su, sv = np.broadcast_arrays(su, sv)
            dw = 2 * np.pi ** 2 * np.sin(np.pi * sv) * du * dv / (s * s)
            rad = env.radiance(uv_to_direction(su.ravel(), sv.ravel())).reshape(len(uc), s * s, 3)
            w = dw.reshape(len(uc), s * s)
            weights.append(w.sum(1))
            rads.append((rad * w[..., None]).sum(1) / w.sum(1)[:, None])
            rects.append((u0, u1, v0, v1, ru, rv))
        self.light = np.concatenate(lights) if lights else np.zeros((0, 3))
        self.light_weight = np.concatenate(weights) if weights else np.zeros(0)
        self.light_radiance = np.concatenate(rads) if rads else np.zeros((0, 3))
        self.rects = rects

    @property
    def count(self) -> int:
        """Nodes per pixel before the horizon test."""
        return len(self.cosine) + len(self.half) + len(self.light)


def half_share(q: Quadrature, theta_h, wo_dot_h, cos_i):
    """``s_B0``: the half-vector nodes' share before the light rectangles, a function of
    the pair's geometry only (NumPy arrays, broadcastable).

    A balance between the half-vector nodes' density ``d_B`` (per steradian of ``wi``,
    with the ring count taken as a continuous function of ``theta_h``) and the cosine
    nodes' ``N_C max(cos theta_i, 0.25) / pi``, raised to ``q.share_power``, times a
    smooth cut to 0 at ``theta_h = half_extent``:
    ``s_B0 = cut / (1 + (d_C / d_B)^k)``.
    """
    k, p = q.half_rings, q.half_power
    th = np.clip(theta_h, 1e-12, None)
    u = k * (th / (math.pi / 2)) ** (1.0 / p)
    dth_du = (math.pi / 2) * p * u ** (p - 1) / k ** p
    m = np.maximum(q.half_phi * np.sqrt(np.sin(th)), q.half_phi_min)
    d_b = m / (2 * math.pi * np.sin(th) * dth_du * 4 * np.clip(wo_dot_h, 1e-12, None))
    d_c = q.cosine_grid ** 2 * np.clip(cos_i, 0.25, None) / math.pi
    x = np.clip(th / q.half_extent, 0.0, 1.0)
    cut = 1.0 - x * x * (3.0 - 2.0 * x)
    return cut / (1.0 + (d_c / d_b) ** q.share_power)


_SHARE_TABLES: dict = {}
# cos(theta_o) values per step of half_share_table: (2, 300, 180) float64 temporaries,
# 0.9 MB each (larger steps measured slower: the temporaries leave the cache).
_SHARE_CHUNK = 2


def half_share_table(q: Quadrature, n_o: int = 129, n_t: int = 300, n_p: int = 180):
    """``I_B(cos theta_o) = integral of s_B0(wi, wo) cos(theta_i) / pi dwi`` (:func:`half_share`) over the upper
    hemisphere at ``n_o`` values of ``cos theta_o`` (error about 1e-5), by a fine midpoint
    rule in half-vector space (``dwi = 4 wo.h dh``; ``wo`` in the ``xz`` plane, so
    ``phi_h`` in ``[0, pi]`` counts twice); computed once per setting and process.

    :func:`half_share` with its ``theta_h``-only factors (ring density, cut) computed once
    per ``(theta_h, phi_h)`` node instead of once per ``cos theta_o``, and
    ``_SHARE_CHUNK`` values of ``cos theta_o`` at a time, in place: 0.40 -> 0.04 s a
    process, the same table to 1e-15 relative (``tests/test_quadrature_pinned.py`` keeps the
    per-``cos theta_o`` loop it replaced).
    """
    key = (q, n_o, n_t, n_p)
    if key not in _SHARE_TABLES:
        k, p = q.half_rings, q.half_power
        cos_o = np.linspace(0.0, 1.0, n_o)
        th = (np.arange(n_t) + 0.5) / n_t * q.half_extent
        ph = (np.arange(n_p) + 0.5) / n_p * np.pi
        st, ct = np.sin(th)[:, None], np.cos(th)[:, None]
        hx, hz = st * np.cos(ph), np.broadcast_to(ct, (n_t, n_p))
        # half_share's d_C / d_B = d_c max(cos_i, 1/4) (wo.h) / a(theta_h), cut(theta_h).
        thc = np.clip(th, 1e-12, None)
        u = k * (thc / (math.pi / 2)) ** (1.0 / p)
        dth_du = (math.pi / 2) * p * u ** (p - 1) / k ** p
        m = np.maximum(q.half_phi * np.sqrt(np.sin(thc)), q.half_phi_min)
        a = (m / (2 * math.pi * np.sin(thc) * dth_du * 4))[:, None]
        x = np.clip(thc / q.half_extent, 0.0, 1.0)
        cut = (1.0 - x * x * (3.0 - 2.0 * x))[:, None]
        # f = cos_i 4 (wo.h) s_B0 sin(theta_h) / pi = cos_i (wo.h) lead / (1 + ratio).
        lead = np.ascontiguousarray(np.broadcast_to(4 * cut * st / np.pi, (n_t, n_p)))
        d_c_a = np.ascontiguousarray(np.broadcast_to(q.cosine_grid ** 2 / math.pi / a, (n_t, n_p)))
        hz2 = 2 * hz
        out = np.empty(n_o)
        for s in range(0, n_o, _SHARE_CHUNK):
            c = cos_o[s:s + _SHARE_CHUNK, None, None]
            woh = hx * np.sqrt(np.clip(1 - c * c, 0.0, None))
            woh += hz * c
            wi_z = woh * hz2
            wi_z -= c
            keep = woh > 0
            keep &= wi_z > 0
            ratio = np.clip(wi_z, 0.25, None)
            ratio *= np.clip(woh, 1e-12, None)
            ratio *= d_c_a
            if q.share_power != 1:
                ratio **= q.share_power
            ratio += 1.0
            f = wi_z * woh
            f *= lead
            f /= ratio
            f *= keep  # finite everywhere: 0 outside the hemisphere
            out[s:s + _SHARE_CHUNK] = 2 * f.reshape(len(c), -1).sum(1) * (q.half_extent / n_t) * (np.pi / n_p)
        _SHARE_TABLES[key] = (cos_o, out)
    return _SHARE_TABLES[key]


def frames(n):
    """Orthonormal tangent frames ``(t, b)`` of unit normals ``n`` ``(P, 3)`` (Duff et al.
    2017), continuous for ``n_z > -1``; float64 ``(P, 3)`` each."""
    n = np.asarray(n, np.float64)
    s = np.where(n[:, 2] >= 0, 1.0, -1.0)
    a = -1.0 / (s + n[:, 2])
    b = n[:, 0] * n[:, 1] * a
    t = np.stack([1 + s * n[:, 0] ** 2 * a, s * b, -s * n[:, 0]], -1)
    bt = np.stack([b, s + n[:, 1] ** 2 * a, -n[:, 1]], -1)
    return t, bt
