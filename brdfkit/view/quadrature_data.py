"""The reference scene's quadrature as the texture and uniforms a shader integrates with.

``brdfkit render`` computes each pixel of the reference scene as a sum over three fixed
node sets (:mod:`brdfkit.render.quadrature`: cosine C, half-vector B, light A), with
shares that depend on the pair's geometry and a per-pixel normalisation. What does not
depend on the pixel is the renderer's own per-node constants
(:class:`brdfkit.render.pairs.Techniques`, in float32 as the renderer rounds them),
packed here as the rows of a texture for the page's fragment shader
(``assets/quadrature.glsl``), which computes per pixel, in float32, what
:func:`brdfkit.render.pairs.block_pairs` computes per pixel:

* row 0, C nodes: ``(x, y, z, d_C max(z, 1/4))``, the local direction and its cosine
  nodes' density;
* rows 1 and 2, B nodes: ``(h_x, h_y, h_z, g)`` and ``(cut, s_y, beta, 4 w)``: the half
  vector, the ring-density term ``g`` and the cut and hand-over terms of its ``theta_h``
  (:func:`brdfkit.render.shares.theta_terms`), and its solid-angle weight;
* rows 3 and 4, A nodes: ``(x, y, z, rho)`` and ``(w, L_r, L_g, L_b)``: the world
  direction, the light rectangles' ramp there, the solid-angle weight and the
  patch-averaged radiance;
* row 5: ``I_B(cos theta_o)`` at evenly spaced ``cos theta_o``
  (:func:`brdfkit.render.nodes.half_share_table`), the normalisation's target.

The scalars the shader needs (the rings' density law, the cut, the hand-over, the light
rectangles) are its uniforms, by name (:func:`scene_quadrature`'s ``uniforms``), set as
they are by the page.

Examples
--------
>>> data = scene_quadrature()
>>> data["counts"], data["nodes"].shape, data["uniforms"]["u_counts"]
((100, 143, 108), (6, 143, 4), [100, 143, 108])
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["scene_quadrature", "scene_uniforms", "MAX_RECTS"]

MAX_RECTS = 4
"""The most light rectangles ``assets/quadrature.glsl`` takes (its ``u_rect`` arrays)."""


def _nodes(tq) -> np.ndarray:
    """float32 ``(6, N, 4)``: the rows of the module's docstring, ``N`` the largest count."""
    _, i_b = tq.i_b
    n = max(tq.n_c, tq.n_b, tq.n_a, len(i_b))
    nodes = np.zeros((6, n, 4), np.float32)
    nodes[0, :tq.n_c] = np.column_stack([tq.c, tq.c_dc])
    nodes[1, :tq.n_b] = np.column_stack([tq.h, tq.b_g])
    nodes[2, :tq.n_b] = np.column_stack([tq.b_cut, tq.b_sy, tq.b_beta, tq.b_w4])
    if tq.n_a:
        nodes[3, :tq.n_a] = np.column_stack([tq.a, tq.a_rho])
        nodes[4, :tq.n_a] = np.column_stack([tq.a_w, tq.a_rad.T])
    nodes[5, :len(i_b), 0] = i_b
    return nodes


def scene_uniforms(tq, view_half_width: float) -> dict:
    """The uniforms of ``assets/quadrature.glsl`` and ``render.frag`` of a
    :class:`~brdfkit.render.pairs.Techniques`: name -> number or flat list (an array or
    vector uniform's values in order)."""
    from brdfkit.render.shares import ring_constants

    q = tq.q
    if len(tq.rects) > MAX_RECTS:
        raise ValueError(f"{len(tq.rects)} light rectangles; the page's shader takes at most {MAX_RECTS}")
    e, c = ring_constants(q)
    lo, hi = math.log(q.light_handover[0]), math.log(q.light_handover[1])
    rects, ramps = np.zeros((MAX_RECTS, 4)), np.zeros((MAX_RECTS, 2))
    for i, r in enumerate(tq.rects):
        rects[i], ramps[i] = r[:4], r[4:6]
    return {"u_counts": [tq.n_c, tq.n_b, tq.n_a], "u_ring": [e, c, float(q.half_phi), float(q.half_phi_min)],
            "u_share": [1 / q.half_extent, lo, 1 / (hi - lo), tq.d_c], "u_share_power": float(q.share_power),
            "u_ib_count": len(tq.i_b[1]), "u_rect_count": len(tq.rects), "u_rect": rects.ravel().tolist(),
            "u_ramp": ramps.ravel().tolist(), "u_view_half_width": float(view_half_width)}


def scene_quadrature(scene=None, env=None) -> dict:
    """The per-node constants and uniforms of a scene's quadrature (module docstring).

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
        ``nodes`` float32 ``(6, N, 4)`` (the rows above), ``counts`` ``(N_C, N_B, N_A)``,
        ``uniforms`` (:func:`scene_uniforms`), ``env`` float32 ``(H, W, 3)`` radiance.
    """
    from brdfkit.render.envmap import reference_envmap
    from brdfkit.render.nodes import NodeSet
    from brdfkit.render.pairs import Techniques
    from brdfkit.render.scene import REFERENCE

    scene = scene or REFERENCE
    env = env if env is not None else reference_envmap()
    tq = Techniques(NodeSet(scene.quadrature, env), env)
    return {"nodes": _nodes(tq), "counts": (tq.n_c, tq.n_b, tq.n_a),
            "uniforms": scene_uniforms(tq, scene.view_half_width), "env": np.asarray(env.image, np.float32)}
