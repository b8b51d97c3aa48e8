"""The reference scene's quadrature as the arrays a shader integrates over.

``brdfkit render`` computes each pixel of the reference scene as a sum over three fixed
node sets (:mod:`brdfkit.render.quadrature`: cosine C, half-vector B, light A), with
shares that depend on the pair's geometry and a per-pixel normalisation. Everything in it
that does not depend on the pixel is a per-node constant: this module computes those
constants once, in float64 rounded to float32, from the renderer's own node set
(:class:`brdfkit.render.nodes.NodeSet`) and share function
(:func:`brdfkit.render.nodes.half_share`), so that the page's fragment shader
(``assets/quadrature.glsl``) repeats, per pixel and in float32, what
:func:`brdfkit.render.pairs.block_pairs` computes per pixel:

* row 0, C nodes: ``(x, y, z, d_C max(z, 1/4))``, the local direction and its cosine
  nodes' density;
* rows 1 and 2, B nodes: ``(h_x, h_y, h_z, g)`` and ``(cut, s_y, beta, 4 w)``: the half
  vector, the ring-density term ``g`` and the cut and hand-over terms of its ``theta_h``
  (``theta_terms`` of :mod:`brdfkit.render.pairs`), and its solid-angle weight;
* rows 3 and 4, A nodes: ``(x, y, z, rho)`` and ``(w, L_r, L_g, L_b)``: the world
  direction, the light rectangles' ramp there, the solid-angle weight and the
  patch-averaged radiance;
* row 5: ``I_B(cos theta_o)`` at 129 evenly spaced ``cos theta_o``, the half-vector nodes'
  exact share of the cosine-weighted hemisphere (the normalisation's target), integrated
  by the renderer's midpoint rule.

Examples
--------
>>> data = scene_quadrature()
>>> data["counts"], data["nodes"].shape
((100, 143, 108), (6, 143, 4))
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["scene_quadrature", "theta_terms", "outside", "half_share_integral"]


def _smoothstep(x):
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def theta_terms(q, theta_h):
    """``(g, s_x, s_y)`` of ``theta_h`` (radians, NumPy float64): the renderer's share
    terms that depend on ``theta_h`` alone (``brdfkit.render.pairs.theta_terms``).

    ``g`` turns the cosine nodes' density into the ratio ``d_C / d_B = d_C (wo . h) g``;
    ``s_x`` is the smoothstep of the cut at ``half_extent`` and ``s_y = 1 - beta`` the
    hand-over to the light nodes between ``light_handover[0]`` and ``[1]``.
    """
    k, p = q.half_rings, q.half_power
    th = np.clip(np.asarray(theta_h, np.float64), 1e-12, None)
    e, c = _ring_constants(q)
    s = np.sin(th)
    m = np.maximum(np.sqrt(s) * q.half_phi, q.half_phi_min)
    g = np.exp(e * np.log(th)) * s * c / m
    lo, hi = math.log(q.light_handover[0]), math.log(q.light_handover[1])
    return g, _smoothstep(th / q.half_extent), _smoothstep((np.log(th) - lo) / (hi - lo))


def _ring_constants(q):
    """``(e, c)``: ``8 pi dtheta/du`` of the rings ``theta = pi/2 (u / K)^p`` is
    ``c theta^e``."""
    k, p = q.half_rings, q.half_power
    e = (p - 1) / p
    return e, 8 * math.pi * (math.pi / 2) * (p / k) * math.exp(-e * math.log(math.pi / 2))


def outside(rects, u, v):
    """``1 - rho``: 0 inside every light rectangle, 1 away from them, smooth over their
    margins (``brdfkit.render.pairs``), at texture coordinates ``u, v`` (NumPy)."""
    u, v = np.asarray(u, np.float64), np.asarray(v, np.float64)
    out = np.ones(np.broadcast(u, v).shape)
    for u0, u1, v0, v1, ru, rv in rects:
        if u1 - u0 < 2 * ru or v1 - v0 < 2 * rv:
            uu = np.where(u < u0, u + 1.0, u) if u0 < 0 else u
            o = 1 - (_smoothstep((uu - u0) / ru) * _smoothstep((u1 - uu) / ru)
                     * _smoothstep((v - v0) / rv) * _smoothstep((v1 - v) / rv))
        else:
            du = u - (u0 + u1) / 2
            if u0 < 0 or u1 > 1:
                du = du - np.round(du)
            ou = _smoothstep(np.abs(du) / ru + 1 - (u1 - u0) / (2 * ru))
            ov = _smoothstep(np.abs(v - (v0 + v1) / 2) / rv + 1 - (v1 - v0) / (2 * rv))
            o = ou + ov - ou * ov
        out = np.minimum(out, o)
    return out


def half_share_integral(q, n_o: int = 129, n_t: int = 300, n_p: int = 180):
    """``(cos_o, I_B)``: ``I_B = integral of s_B0 cos(theta_i) / pi dwi`` over the upper
    hemisphere (:func:`brdfkit.render.nodes.half_share`) at ``n_o`` evenly spaced
    ``cos theta_o`` in ``[0, 1]``, by the renderer's midpoint rule in half-vector space
    (``dwi = 4 (wo . h) dh``, ``wo`` in the ``xz`` plane so ``phi_h`` in ``[0, pi]`` counts
    twice); about 1e-5 from the exact integral, and the renderer's own table to rounding."""
    from brdfkit.render.nodes import half_share

    cos_o = np.linspace(0.0, 1.0, n_o)
    th = (np.arange(n_t) + 0.5) / n_t * q.half_extent
    ph = (np.arange(n_p) + 0.5) / n_p * np.pi
    hx, hz = np.sin(th)[:, None] * np.cos(ph)[None, :], np.broadcast_to(np.cos(th)[:, None], (n_t, n_p))
    th2 = np.broadcast_to(th[:, None], (n_t, n_p))
    out = np.empty(n_o)
    for i, c in enumerate(cos_o):
        woh = hx * math.sqrt(max(1 - c * c, 0.0)) + hz * c
        wi_z = 2 * woh * hz - c
        keep = (woh > 0) & (wi_z > 0)
        f = np.where(keep, half_share(q, th2, woh, wi_z) * wi_z * 4 * woh * np.sin(th2) / np.pi, 0.0)
        out[i] = 2 * f.sum() * (q.half_extent / n_t) * (np.pi / n_p)
    return cos_o, out


def _uv(d):
    u = np.arctan2(d[..., 0], -d[..., 2]) / (2 * np.pi)
    return u - np.floor(u), np.arccos(np.clip(d[..., 1], -1.0, 1.0)) / np.pi


def scene_quadrature(scene=None, env=None) -> dict:
    """The per-node constants of the reference scene's quadrature (module docstring).

    Parameters
    ----------
    scene
        :class:`brdfkit.render.scene.Scene` (default the reference scene); its
        quadrature settings.
    env
        :class:`brdfkit.render.envmap.EnvMap` (default the reference environment).

    Returns
    -------
    dict
        ``nodes`` float32 ``(6, N, 4)`` (the rows above, ``N`` the largest count),
        ``counts`` ``(N_C, N_B, N_A)``, ``rects`` (the light rectangles, ``(u0, u1, v0,
        v1, ramp_u, ramp_v)`` each), ``constants`` (the scalars the shader needs, by
        name), ``env`` float32 ``(H, W, 3)`` radiance and ``view_half_width``.
    """
    from brdfkit.render.envmap import reference_envmap
    from brdfkit.render.nodes import NodeSet
    from brdfkit.render.scene import REFERENCE

    scene = scene or REFERENCE
    env = env if env is not None else reference_envmap()
    q = scene.quadrature
    ns = NodeSet(q, env)
    d_c = q.cosine_grid ** 2 / math.pi
    c = ns.cosine / np.linalg.norm(ns.cosine, axis=1, keepdims=True)
    h = ns.half
    g, sx, sy = theta_terms(q, np.arctan2(np.hypot(h[:, 0], h[:, 1]), h[:, 2]))
    a = ns.light
    rects = [tuple(float(x) for x in r) for r in ns.rects]
    cos_o, i_b = half_share_integral(q)
    counts = (len(c), len(h), len(a))
    n = max(max(counts), len(i_b))
    nodes = np.zeros((6, n, 4))
    nodes[0, :counts[0]] = np.column_stack([c, d_c * np.clip(c[:, 2], 0.25, None)])
    nodes[1, :counts[1]] = np.column_stack([h, g])
    nodes[2, :counts[1]] = np.column_stack([1 - sx, sy, 1 - sy, 4 * ns.half_weight])
    if counts[2]:
        nodes[3, :counts[2]] = np.column_stack([a, 1 - outside(rects, *_uv(a))])
        nodes[4, :counts[2]] = np.column_stack([ns.light_weight, ns.light_radiance])
    nodes[5, :len(i_b), 0] = i_b
    e, ring_c = _ring_constants(q)
    constants = {"ring_e": e, "ring_c": ring_c, "half_phi": float(q.half_phi), "half_phi_min": float(q.half_phi_min),
                 "half_extent": float(q.half_extent), "handover_lo": math.log(q.light_handover[0]),
                 "handover_hi": math.log(q.light_handover[1]), "d_c": d_c, "share_power": float(q.share_power),
                 "ib_count": len(i_b)}
    return {"nodes": nodes.astype(np.float32), "counts": counts, "rects": rects, "constants": constants,
            "env": np.asarray(env.image, np.float32), "view_half_width": float(scene.view_half_width)}
