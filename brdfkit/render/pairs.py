"""The quadrature's (pixel, node) pairs, one technique at a time, in NumPy.

For a block of pixels, each technique of :mod:`brdfkit.render.nodes` (cosine C,
half-vector B, light A) is a dense ``(N, P)`` grid of pairs, node-major, whose geometry
is mostly fixed per node: the C nodes' local directions and solid-angle weights, the B
nodes' ``theta_h`` (so their share terms, and their grid coordinate ``u_h``), the A
nodes' world directions, ramp ``rho`` and patch radiance. :class:`Techniques` holds
those per-node constants; :func:`block_pairs` computes, per technique, what varies per
pair (the shares of :mod:`brdfkit.render.quadrature`, the weights, the per-pixel
normalisation and the environment radiance), keeps the pairs that carry weight and gives
each its MERL grid coordinates (:func:`brdfkit.geometry.fractional_indices`), which is all
a table needs (:mod:`brdfkit.render.lookup`).

Node-major order: the pairs of one node over a block of neighbouring pixels look up
neighbouring cells of a table, so a table's gathers mostly hit the cache (a pixel-major
order measured about twice as slow a lookup).

Precision: per-pair quantities are float32; per-pixel frames, normalisation masses and
scales are float64, as are the horizon test of the B nodes (``wo . h`` and
``cos theta_i``, whose signs decide which pairs exist) and their ``wi`` before rounding.
The B nodes' ``theta_h`` is the ring's own (float64 per node; 2.5e-5 rad for the first
ring) instead of one recomputed from ``wi + wo``, and so is their ``u_h``; their
``theta_d`` and ``phi_d`` come from float64 dot products of ``wo`` with the node's own
frame. Shares are written without cancellation (``1 - s_B0 beta`` as
``(r + (1 - cut) + cut (1 - beta)) / (1 + r)``, ``1 - rho`` computed as such by
:func:`outside`), so a share near 0 keeps its relative precision.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from brdfkit.render.nodes import NodeSet, frames, half_share_table
from brdfkit.render.shares import EnvLookup, outside, theta_terms, uv

__all__ = ["Techniques", "PairBlock", "block_pairs"]

_F32 = np.float32
_HALF_PI = math.pi / 2


class Techniques:
    """Per-node constants of a :class:`~brdfkit.render.nodes.NodeSet`.

    Parameters
    ----------
    ns
        The node set (quadrature settings and environment).
    env
        Its :class:`~brdfkit.render.envmap.EnvMap`.
    """

    def __init__(self, ns: NodeSet, env):
        q = self.q = ns.q
        self.rects = ns.rects
        self.n_c, self.n_b, self.n_a = len(ns.cosine), len(ns.half), len(ns.light)
        self.d_c = q.cosine_grid ** 2 / math.pi  # d_C per unit of max(cos theta_i, 0.25)
        cos = ns.cosine / np.linalg.norm(ns.cosine, axis=-1, keepdims=True)
        self.c64, self.c = cos, cos.astype(_F32)
        self.c_dc = (self.d_c * np.clip(cos[:, 2], 0.25, None)).astype(_F32)[:, None]
        h = self.h64 = np.asarray(ns.half, np.float64)
        self.h = h.astype(_F32)
        th = np.arctan2(np.sqrt(h[:, 0] ** 2 + h[:, 1] ** 2), h[:, 2])
        g, sx, sy = theta_terms(q, th.copy())
        col = lambda a: np.ascontiguousarray(np.asarray(a, _F32)[:, None])  # noqa: E731
        self.b_g, self.b_cut, self.b_sy, self.b_beta = col(g), col(1 - sx), col(sy), col(1 - sy)
        self.b_w4 = col(4 * np.asarray(ns.half_weight))
        # Lookup: u_h per node; phi_d from wo and the node's frame (x', y') about h
        # (Rusinkiewicz: x' = R_z(phi_h) R_y(theta_h) x, y' = R_z(phi_h) y): wi = 2 (wo.h) h
        # - wo, so d = (wi . x', wi . y') = -(wo . x', wo . y').
        self.b_uh = np.sqrt(np.clip(th, 0, _HALF_PI) / _HALF_PI) * 90
        ph = np.arctan2(h[:, 1], h[:, 0])
        ct, st = np.cos(th), np.sin(th)
        self.b_x = -np.stack([ct * np.cos(ph), ct * np.sin(ph), -st], -1)
        self.b_y = -np.stack([-np.sin(ph), np.cos(ph), np.zeros_like(ph)], -1)
        self.b_x32, self.b_y32 = self.b_x.astype(_F32), self.b_y.astype(_F32)
        self.b_uh32 = self.b_uh.astype(_F32)[:, None]
        a = self.a64 = np.asarray(ns.light, np.float64).reshape(-1, 3)
        self.a = a.astype(_F32)
        self.a_rho = col(1 - outside(ns.rects, *uv(*a.T))) if len(a) else np.zeros((0, 1), _F32)
        self.a_w = col(ns.light_weight)
        self.a_rad = np.asarray(ns.light_radiance, _F32).reshape(-1, 3).T.copy()  # (3, N_A)
        self.env = EnvLookup(env)
        self.i_b = half_share_table(q)


@dataclasses.dataclass
class PairBlock:
    """The pairs of a block of pixels that carry weight, node-major (C, then B, then A).

    Attributes
    ----------
    pix
        int32 ``(M,)`` the pair's pixel in the block.
    coords
        float32 ``(3, M)`` MERL grid coordinates ``(u_h, u_d, u_p)``
        (:func:`brdfkit.geometry.fractional_indices` of the pair's angles).
    rw
        float32 ``(3, M)`` radiance times weight (``L_env w s cos`` times the pixel's
        normalisation).
    pixels
        ``P``, the block's pixels.
    scale, big
        float64 ``(P, 2)`` normalisation factors of the C and B nodes and the mask of
        those whose mass exceeds 1e-3 (``RenderStats.scale_range``).
    wi, wo
        float32 ``(3, M)`` local directions (toward the light, toward the camera), when
        asked for (:func:`block_pairs` ``directions``), else ``None``.
    """

    pix: np.ndarray
    coords: np.ndarray
    rw: np.ndarray
    pixels: int
    scale: np.ndarray
    big: np.ndarray
    wi: np.ndarray | None = None
    wo: np.ndarray | None = None

    @property
    def nbytes(self) -> int:
        return sum(a.nbytes for a in (self.pix, self.coords, self.rw) + tuple(
            a for a in (self.wi, self.wo) if a is not None))


def _theta_h(wi_x, wi_y, wi_z, wo):
    """``theta_h`` of pairs given by their local ``wi`` components ``(N, P)`` (from the
    components of ``wi + wo``, accurate next to 0); ``wo`` ``(3, P)``."""
    hx, hy = wi_x + wo[0], wi_y + wo[1]
    hx *= hx
    hy *= hy
    hx += hy
    return np.arctan2(np.sqrt(hx, out=hx), wi_z + wo[2])


def _share_ratio(tq, d_c, woh, g):
    """``r = (d_C / d_B)^k`` (so ``s_B0 = cut / (1 + r)``)."""
    r = d_c * np.maximum(woh, 1e-12)
    r *= g
    return r if tq.q.share_power == 1 else r ** tq.q.share_power


def _light(tq, ff, wo, normals, wo_world):
    """A nodes: their local components ``(3, N_A, P)``, weight ``w cos s_A`` and the
    masses ``(P,)`` of ``s_A`` and of the share the B nodes hand them."""
    loc = np.stack([tq.a @ ff[i].T for i in range(3)])  # local components, (3, N_A, P)
    ax, ay, az = loc
    g, sx, sy = theta_terms(tq.q, _theta_h(ax, ay, az, wo))
    # wo . h = sqrt((1 + wo . wi) / 2), and wo . wi is the same in the world: per node.
    woh = np.sqrt((1 + tq.a64 @ wo_world) / 2).astype(_F32)[:, None]
    r = _share_ratio(tq, tq.d_c * np.maximum(az, 0.25), woh, g)
    above = tq.a64 @ normals.T > 0  # the horizon test in float64, as for the B nodes
    geo = np.where(above, tq.a_w * az, _F32(0))
    geo *= tq.a_rho
    geo /= 1 + r  # w cos rho / (1 + r)
    cut = 1 - sx
    cut *= sy
    weight = r + sx
    weight += cut
    weight *= geo  # w cos s_A
    geo *= cut
    return loc, weight, weight.sum(0, dtype=np.float64) / math.pi, geo.sum(0, dtype=np.float64) / math.pi


def _half(tq, wo64):
    """B nodes: ``wo . h`` (float64), local ``wi`` ``(3, N_B, P)`` float32 and the weight
    ``w cos s_B0 cut`` before the light rectangles."""
    woh64 = tq.h64 @ wo64
    cos64 = 2 * woh64 * tq.h64[:, 2:3] - wo64[2]
    woh, cos_b = woh64.astype(_F32), cos64.astype(_F32)
    r = _share_ratio(tq, tq.d_c * np.maximum(cos_b, 0.25), woh, tq.b_g)
    # wi in float64 then rounded: next to the mirror direction the BRDF is steep in wi.
    loc = np.stack([(2 * woh64 * tq.h64[:, i:i + 1] - wo64[i]).astype(_F32) for i in range(2)] + [cos_b])
    wc = tq.b_w4 * woh
    wc *= cos_b
    wc *= tq.b_cut
    wc /= 1 + r
    wc[(woh64 <= 0) | (cos64 <= 0)] = 0
    return woh64, loc, wc


def _cosine_share(tq, wo):
    """C nodes: their share ``s_C`` before the light rectangles, ``(N_C, P)``."""
    c = tq.c
    g, sx, _ = theta_terms(tq.q, _theta_h(c[:, 0:1], c[:, 1:2], c[:, 2:3], wo), light=False)
    woh = c @ wo
    woh += 1.0
    woh *= 0.5
    r = _share_ratio(tq, tq.c_dc, np.sqrt(woh, out=woh), g)
    sx += r
    r += 1
    sx /= r
    return sx


def block_pairs(tq: Techniques, normals, wo_world, directions: bool = False) -> PairBlock:
    """The pairs of a block of pixels that carry weight (:class:`PairBlock`).

    Parameters
    ----------
    tq
        :class:`Techniques`.
    normals
        float64 ``(P, 3)`` unit world normals.
    wo_world
        float64 ``(3,)`` world view direction.
    directions
        Also keep the pairs' local ``wi`` and ``wo`` (a BRDF evaluated from directions,
        :class:`brdfkit.render.measured.MeasuredBRDF`).
    """
    normals = np.asarray(normals, np.float64)
    wo_world = np.asarray(wo_world, np.float64)
    t, bt = frames(normals)
    f64 = np.stack([t, bt, normals])  # (3, P, 3): local axis i of each pixel, in the world
    wo64 = f64 @ wo_world  # (3, P)
    ff, wo = f64.astype(_F32), wo64.astype(_F32)
    p = normals.shape[0]
    a_loc, weight_a, mass_a, mass_3 = _light(tq, ff, wo, normals, wo_world)
    woh64, b_loc, wc_b = _half(tq, wo64)
    share_c = _cosine_share(tq, wo)
    # World directions of C and B together: environment texture coordinates, 1 - rho.
    woh2 = 2 * woh64.astype(_F32)
    world = []
    for i in range(3):
        b = tq.h @ ff[:, :, i]
        b *= woh2
        b -= _F32(wo_world[i])
        world.append(np.concatenate([tq.c @ ff[:, :, i], b]))
    u, v = uv(*world)
    out = outside(tq.rects, u, v)
    share_c *= out[:tq.n_c]
    out_b = out[tq.n_c:]
    out_b *= tq.b_sy
    out_b += tq.b_beta
    wc_b *= out_b  # w cos s_B (1 - rho s_y = beta + (1 - rho) s_y)
    mass_c = share_c.sum(0, dtype=np.float64) / tq.n_c
    mass_b = wc_b.sum(0, dtype=np.float64) / math.pi
    # Normalise B and C to the exact measure of their shares, per pixel.
    target_b = np.interp(wo64[2], *tq.i_b) - mass_3
    target_c = 1.0 - target_b - mass_a
    mass = np.stack([mass_c, mass_b], 1)
    big = mass > 1e-9
    scale = np.where(big, np.stack([target_c, target_b], 1) / np.where(big, mass, 1.0), 1.0)
    sc = scale.astype(_F32)
    share_c *= sc[:, 0] * _F32(math.pi / tq.n_c)
    wc_b *= sc[:, 1]
    weight = np.concatenate([share_c, wc_b, weight_a])  # (N, P), node-major
    idx = np.flatnonzero(weight > 0)
    node, pix = np.divmod(idx, p)
    n_cb = tq.n_c + tq.n_b
    m_cb = int(np.searchsorted(node, n_cb))
    m_c = int(np.searchsorted(node[:m_cb], tq.n_c))
    w = weight.reshape(-1)[idx]
    rw = np.empty((3, idx.size), _F32)
    rw[:, :m_cb] = tq.env(u.reshape(-1)[idx[:m_cb]], v.reshape(-1)[idx[:m_cb]])
    rw[:, m_cb:] = tq.a_rad[:, node[m_cb:] - n_cb]
    rw *= w
    # Grid coordinates on the (node, pixel) grid, then the kept pairs' gathered: no gather
    # of directions (a C node's is per node, a pixel's wo per pixel).
    grid = np.empty((3, tq.n_c + tq.n_b + tq.n_a, p), _F32)
    wo_row = wo[:, None, :]
    _coords(tq.c.T[:, :, None], wo_row, grid[:, :tq.n_c])
    _coords_half(tq, woh64, wo, grid[:, tq.n_c:n_cb])
    _coords(a_loc, wo_row, grid[:, n_cb:])
    coords = grid.reshape(3, -1)[:, idx]
    keep = (None, None)
    if directions:
        wi = np.concatenate([np.broadcast_to(tq.c.T[:, :, None], (3, tq.n_c, p)), b_loc, a_loc], 1)
        keep = (wi.reshape(3, -1)[:, idx], wo[:, pix])
    return PairBlock(pix.astype(np.int32), coords, rw, p, scale, mass > 1e-3, *keep)


def _fold(phi, out_u):
    """``u_p`` of ``phi_d`` in ``(-pi, pi]``: folded into ``[0, pi)`` (reciprocity) and
    scaled to the grid's ``[0, 180)``, into ``out_u``."""
    phi[phi < 0] += _F32(math.pi)
    phi *= _F32(180 / math.pi)
    phi[phi >= 180] -= 180  # phi_d just below a multiple of pi can round up to 180
    np.maximum(phi, 0, out=out_u)


def _coords(wi, wo, out):
    """Grid coordinates of pairs from their local directions, float32 ``(3, ...)``
    broadcast together (a grid of nodes by pixels, or a list of pairs) into ``out``
    ``(3, ...)``: ``theta_h`` from ``wi + wo`` (atan2, accurate next to 0), ``theta_d`` as
    the half angle between them (``atan2(|wi - wo|, |wi + wo|)``), ``phi_d`` as the
    azimuth of ``wi`` about ``h`` (Rusinkiewicz's frame, without forming the rotations)."""
    if out[0].size == 0:
        return
    hx, hy, hz = wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]
    s2 = hx * hx
    s2 += hy * hy
    l2 = hz * hz
    l2 += s2
    th = np.arctan2(np.sqrt(s2), hz)
    d2 = np.square(wi[0] - wo[0])
    d2 += np.square(wi[1] - wo[1])
    d2 += np.square(wi[2] - wo[2])
    length = np.sqrt(l2, out=l2)
    td = np.arctan2(np.sqrt(d2, out=d2), length)
    # d_y = wi . y' and d_x = wi . x', both times |H| s_H > 0.
    dy = wi[1] * wo[0]
    dy -= wi[0] * wo[1]
    dy *= length
    dx = wi[0] * hx
    dx += wi[1] * hy
    dx *= hz
    dx -= wi[2] * s2
    pd = np.arctan2(dy, dx)
    _grid(th, td, pd, out)


def _coords_half(tq, woh64, wo, out):
    """Grid coordinates of the B nodes by pixels ``(3, N_B, P)``: ``u_h`` the ring's,
    ``theta_d = arccos(wo . h)`` (float64 ``wo . h``), ``phi_d`` from ``wo`` and the
    node's frame."""
    td = np.arccos(np.clip(woh64, -1.0, 1.0)).astype(_F32)
    pd = np.arctan2(tq.b_y32 @ wo, tq.b_x32 @ wo)
    out[0] = tq.b_uh32
    np.clip(td, 0, _HALF_PI, out=td)
    np.multiply(td, _F32(90 / _HALF_PI), out=out[1])
    _fold(pd, out[2])


def _grid(th, td, pd, out):
    """:func:`brdfkit.geometry.fractional_indices` of float32 angles, into ``out``."""
    np.clip(th, 0, _HALF_PI, out=th)
    th *= _F32(1 / _HALF_PI)
    np.sqrt(th, out=th)
    np.multiply(th, _F32(90), out=out[0])
    np.clip(td, 0, _HALF_PI, out=td)
    np.multiply(td, _F32(90 / _HALF_PI), out=out[1])
    _fold(pd, out[2])
