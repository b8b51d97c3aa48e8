"""The quadrature's (pixel, node) pairs, one technique at a time.

For a block of pixels, each technique of :mod:`brdfkit.render.nodes` (cosine C,
half-vector B, light A) is a dense ``(P, N)`` grid of pairs whose geometry is mostly
fixed per node: the C nodes' local directions and solid-angle weights, the B nodes'
``theta_h`` (so their share terms), the A nodes' world directions, ramp ``rho`` and
patch radiance. :class:`Techniques` holds those per-node constants; :func:`block_pairs`
computes, per technique, what varies per pair (the shares of
:mod:`brdfkit.render.quadrature`, the weights, the per-pixel normalisation and the
environment radiance) and compacts the pairs that carry weight into the flat lists the
BRDFs are evaluated at.

Components are kept apart, ``(P, N)`` each: PyTorch's CPU kernels run 10x slower on the
strided components of ``(P, N, 3)`` tensors (and on ``(M, 3)`` broadcasts), which is most
of what the float64 renderer before this one spent.

Precision: per-pair quantities are float32 (the BRDFs get float32 directions anyway);
per-pixel frames, normalisation masses and scales are float64, as are the horizon test of
the B nodes (``wo . h`` and ``cos theta_i``, whose signs decide which pairs exist) and
their ``wi`` before rounding (next to the mirror direction a near-mirror BRDF is steep in
``wi``). The B nodes' ``theta_h`` is the ring's own (float64 per node; 2.5e-5 rad for the
first ring) instead of one recomputed from ``wi + wo``. Shares are written without
cancellation (``1 - s_B0 beta`` as ``(r + (1 - cut) + cut (1 - beta)) / (1 + r)``,
``1 - rho`` computed as such by :func:`_outside`), so a share near 0 keeps its relative
precision and the pairs kept are the float64 renderer's.
"""

from __future__ import annotations

import math

import numpy as np

from brdfkit.render.nodes import NodeSet, _frames, _half_share_table

__all__ = ["Techniques", "block_pairs"]


def _smoothstep(x):
    """``3 x^2 - 2 x^3`` of ``x`` clamped to ``[0, 1]``, in place: ``x`` a temporary."""
    x = x.clamp_(0.0, 1.0)
    t = x * -2.0
    return x.mul_(x).mul_(t.add_(3.0))


def theta_terms(q, th, light=True):
    """``(g, s_x, s_y)`` of ``theta_h`` (torch, any float dtype; ``s_y`` None unless
    ``light``): the share terms that depend on ``theta_h`` alone.

    With ``d_B`` and ``d_C`` the B and C node densities of
    :func:`brdfkit.render.nodes.half_share`: ``d_C / d_B = d_C (wo . h) g``, so that
    ``s_B0 = (1 - s_x) / (1 + (d_C (wo . h) g)^k)``; ``s_x`` is the smoothstep of the cut
    at ``half_extent`` (``cut = 1 - s_x``) and ``s_y = 1 - beta`` (the hand-over to the
    light nodes between ``light_handover``).
    """
    import torch

    k, p = q.half_rings, q.half_power
    th = th.clamp_min(1e-12)
    log_th = torch.log(th)
    # 8 pi dtheta/du of the rings theta = pi/2 (u / K)^p, as a function of theta: c th^e.
    e = (p - 1) / p
    c = 8 * math.pi * (math.pi / 2) * (p / k) * math.exp(-e * math.log(math.pi / 2))
    s = torch.sin(th)
    m = torch.sqrt(s).mul_(q.half_phi).clamp_min_(q.half_phi_min)
    g = (log_th * e).exp_().mul_(s).mul_(c).div_(m)
    lo, hi = math.log(q.light_handover[0]), math.log(q.light_handover[1])
    sy = _smoothstep(log_th.sub_(lo).mul_(1 / (hi - lo))) if light else None
    return g, _smoothstep(th.mul_(1 / q.half_extent)), sy


class _EnvLookup:
    """:meth:`brdfkit.render.envmap.EnvMap.radiance` (Mitsuba's bilinear lookup) from
    texture coordinates, by ``grid_sample`` on the map with its first column repeated
    after the last (the wrap in ``u``): the same texels and weights, to float32 rounding."""

    def __init__(self, env, device):
        import torch

        tex = torch.as_tensor(env.image, dtype=torch.float32, device=device).permute(2, 0, 1)
        self.h, self.w = tex.shape[1:]
        self.tex = torch.cat([tex, tex[:, :, :1]], 2)[None].contiguous()  # (1, 3, H, W + 1)

    def __call__(self, u, v):
        """float32 ``(3, M)`` radiance at texture coordinates ``u, v (M,)``."""
        import torch

        w = self.w
        x = (u - 0.5 / w) * w  # column j at u = (j + 0.5) / W
        x = x - torch.floor(x / w) * w
        # align_corners: -1 and 1 are the centres of the first and last columns (rows).
        # The grid as the (M, 2) view of a (2, M) tensor: grid_sample reads it strided
        # about twice as fast as it reads (and stack writes) an interleaved (M, 2) one.
        grid = u.new_empty((2, u.shape[0]))
        torch.sub(x.mul_(2.0 / w), 1, out=grid[0])
        torch.sub(v * 2, 1, out=grid[1])
        return torch.nn.functional.grid_sample(self.tex, grid.T[None, None], mode="bilinear",
                                               padding_mode="border", align_corners=True)[0, :, 0]


def _uv(x, y, z):
    """Texture coordinates of world directions given by their components (envmap
    convention)."""
    import torch

    u = torch.atan2(x, -z) / (2 * math.pi)
    return u - torch.floor(u), torch.arccos(y.clamp(-1.0, 1.0)) / math.pi


def _outside(rects, u, v):
    """``1 - rho``, the ramp of the old renderer's ``_rect_ramp`` (now only in
    ``tests/helpers_quadrature.py``), from texture coordinates; computed as such so that it keeps its relative precision next to 0
    (float32 ``rho`` rounds to 1 within 6e-8 of it).

    A rectangle at least twice its ramps wide has at most one ramp below 1 at any ``u``
    (and ``v``), so its product of four smoothsteps is ``s(a) s(b)``, ``a`` and ``b`` the
    distances to the nearer edges in ``u`` and ``v`` over the ramp widths;
    ``1 - s(a) s(b) = s'(a) + s'(b) - s'(a) s'(b)`` with ``s'(x) = 1 - s(x) = s(1 - x)``.
    ``u`` is taken periodically for a rectangle crossing ``u = 0`` or 1.
    """
    import torch

    out = None
    for u0, u1, v0, v1, ru, rv in rects:
        if u1 - u0 < 2 * ru or v1 - v0 < 2 * rv:
            uu = torch.where(u < u0, u + 1.0, u) if u0 < 0 else u
            o = 1 - (_smoothstep((uu - u0) / ru) * _smoothstep((u1 - uu) / ru)
                     * _smoothstep((v - v0) / rv) * _smoothstep((v1 - v) / rv))
        else:
            du = u - (u0 + u1) / 2
            if u0 < 0 or u1 > 1:
                du = du - torch.round(du)
            ou = _smoothstep(du.abs_().mul_(1 / ru).add_(1 - (u1 - u0) / (2 * ru)))
            ov = _smoothstep((v - (v0 + v1) / 2).abs_().mul_(1 / rv).add_(1 - (v1 - v0) / (2 * rv)))
            o = (ou + ov).sub_(ou.mul_(ov))
        out = o if out is None else torch.minimum(out, o)
    return torch.ones_like(u) if out is None else out


class Techniques:
    """Per-node constants of a :class:`~brdfkit.render.nodes.NodeSet` on one device.

    Parameters
    ----------
    ns
        The node set (quadrature settings and environment).
    env
        Its :class:`~brdfkit.render.envmap.EnvMap`.
    device
        Torch device.
    """

    def __init__(self, ns: NodeSet, env, device):
        import torch

        q = self.q = ns.q
        f32, f64 = dict(dtype=torch.float32, device=device), dict(dtype=torch.float64, device=device)
        self.device, self.rects = torch.device(device), ns.rects
        self.n_c, self.n_b, self.n_a = len(ns.cosine), len(ns.half), len(ns.light)
        self.d_c = q.cosine_grid ** 2 / math.pi  # d_C per unit of max(cos theta_i, 0.25)
        cos = torch.nn.functional.normalize(torch.as_tensor(ns.cosine, **f64), dim=-1)
        self.c = cos.float()
        self.c_dc = (self.d_c * cos[:, 2].clamp_min(0.25)).float()
        self.h64 = torch.as_tensor(ns.half, **f64)
        self.h = self.h64.float()
        th = torch.atan2(torch.sqrt(self.h64[:, 0] ** 2 + self.h64[:, 1] ** 2), self.h64[:, 2])
        g, sx, sy = theta_terms(q, th)
        self.b_g, self.b_cut, self.b_sy, self.b_beta = g.float(), (1 - sx).float(), sy.float(), (1 - sy).float()
        self.b_w4 = (4 * torch.as_tensor(ns.half_weight, **f64)).float()
        a = self.a64 = torch.as_tensor(ns.light, **f64)
        self.a = a.float()
        self.a_rho = (1 - _outside(ns.rects, *_uv(*a.T))).float()  # as the C and B nodes see it
        self.a_w = torch.as_tensor(ns.light_weight, **f32)
        self.a_rad = torch.as_tensor(ns.light_radiance, **f32).T.contiguous()  # (3, N_A)
        self.env = _EnvLookup(env, device)
        cos_o, share = _half_share_table(q)
        self.i_b = (np.asarray(cos_o), np.asarray(share))


def _theta_h(wi_x, wi_y, wi_z, wo):
    """``theta_h`` of pairs given by their local ``wi`` components (P, N) (from the
    components of ``wi + wo``, accurate next to 0)."""
    import torch

    hx, hy = wi_x + wo[:, 0:1], wi_y + wo[:, 1:2]
    return torch.atan2(hx.mul_(hx).add_(hy.mul_(hy)).sqrt_(), wi_z + wo[:, 2:3])


def _share_ratio(tq, d_c, woh, g):
    """``r = (d_C / d_B)^k`` (so ``s_B0 = cut / (1 + r)``)."""
    r = d_c * woh.clamp_min(1e-12) * g
    return r if tq.q.share_power == 1 else r ** tq.q.share_power


def block_pairs(tq: Techniques, normals, wo_world):
    """The pairs of a block of pixels that carry weight.

    Parameters
    ----------
    tq
        :class:`Techniques` on the normals' device.
    normals
        float64 ``(P, 3)`` unit world normals.
    wo_world
        float64 ``(3,)`` world view direction.

    Returns
    -------
    tuple
        ``(pix, wi, wo, rw, scales)`` of the ``M`` pairs, pixel by pixel: int32 ``(M,)``
        pixel in the block; float32 ``(M, 3)`` local ``wi`` and ``wo``, what the BRDF is
        evaluated at (column-major: views of ``(3, M)`` tensors); float32 ``(3, M)``
        radiance times weight (``L_env w s cos`` times the pixel's normalisation); and
        ``(scale, big)``: the float64 ``(P, 2)`` normalisation factors of the C and B
        nodes and the mask of those whose mass exceeds 1e-3
        (``RenderStats.scale_range``).
    """
    import torch

    f64 = dict(dtype=torch.float64, device=normals.device)
    t, bt = _frames(normals)
    frame64 = torch.stack([t, bt, normals], 1)  # (P, 3, 3): rows are the local axes
    wo64 = frame64 @ wo_world
    frame, wo = frame64.float(), wo64.float()
    p = normals.shape[0]
    to_world = [frame[:, :, i] for i in range(3)]  # d_world_i = local d . to_world[i]

    # A: world directions fixed; rho and radiance per node.
    ax, ay, az = (frame[:, i, :] @ tq.a.T for i in range(3))  # local components
    g, sx, sy = theta_terms(tq.q, _theta_h(ax, ay, az, wo))
    # wo . h = sqrt((1 + wo . wi) / 2), and wo . wi is the same in the world: per node.
    woh = torch.sqrt((1 + tq.a64 @ wo_world) / 2).float()
    r = _share_ratio(tq, tq.d_c * az.clamp_min(0.25), woh, g)
    above = normals @ tq.a64.T > 0  # the horizon test in float64, as for the B nodes
    geo_a = torch.where(above, tq.a_w * az, 0.0) * tq.a_rho / (1 + r)  # w cos rho / (1 + r)
    cut = 1 - sx
    weight_a = geo_a * (r + sx + cut * sy)  # w cos s_A
    mass_a = weight_a.sum(1, dtype=torch.float64) / math.pi
    mass_3 = (geo_a * cut * sy).sum(1, dtype=torch.float64) / math.pi

    # B: theta_h fixed per node; wi the mirror of wo about h.
    woh64 = wo64 @ tq.h64.T
    cos64 = 2 * woh64 * tq.h64[:, 2] - wo64[:, 2:3]
    woh, cos_b = woh64.float(), cos64.float()
    r = _share_ratio(tq, tq.d_c * cos_b.clamp_min(0.25), woh, tq.b_g)
    woh2 = 2 * woh
    # wi in float64 then rounded: next to the mirror direction the BRDF is steep in wi.
    bx, by = ((2 * woh64 * tq.h64[:, i] - wo64[:, i:i + 1]).float() for i in range(2))
    wc_b = torch.where((woh64 > 0) & (cos64 > 0), tq.b_w4 * woh * cos_b * tq.b_cut / (1 + r), 0.0)

    # C: local directions fixed; w cos = pi / N_C.
    c = tq.c
    g, sx, _ = theta_terms(tq.q, _theta_h(c[:, 0], c[:, 1], c[:, 2], wo), light=False)
    r = _share_ratio(tq, tq.c_dc, (wo @ c.T).add_(1.0).mul_(0.5).sqrt_(), g)
    share_c = (r + sx) / (1 + r)

    # World directions of C and B together: environment texture coordinates, 1 - rho.
    u, v = _uv(*(torch.cat([m @ c.T, woh2 * (m @ tq.h.T) - w], 1)
                 for m, w in zip(to_world, wo_world.tolist())))
    out = _outside(tq.rects, u, v)
    share_c = share_c * out[:, :tq.n_c]
    wc_b = wc_b * (out[:, tq.n_c:] * tq.b_sy + tq.b_beta)  # w cos s_B (1 - rho s_y = beta + (1 - rho) s_y)
    mass_c = share_c.sum(1, dtype=torch.float64) / tq.n_c
    mass_b = wc_b.sum(1, dtype=torch.float64) / math.pi

    # Normalise B and C to the exact measure of their shares, per pixel.
    i_b = torch.as_tensor(np.interp(wo64[:, 2].cpu().numpy(), *tq.i_b), **f64)
    target_b = i_b - mass_3
    target_c = 1.0 - target_b - mass_a
    mass = torch.stack([mass_c, mass_b], 1)
    scale = torch.where(mass > 1e-9, torch.stack([target_c, target_b], 1) / mass.clamp_min(1e-300), 1.0)
    sc = scale.float()
    n_cb = tq.n_c + tq.n_b
    weight = torch.cat([share_c * (sc[:, 0:1] * (math.pi / tq.n_c)), wc_b * sc[:, 1:2], weight_a], 1)
    rw = torch.cat([tq.env(u.reshape(-1), v.reshape(-1)).view(3, p, n_cb),
                    tq.a_rad[:, None, :].expand(3, p, tq.n_a)], 2) * weight  # (3, P, N)
    local = [torch.cat([c[:, i].expand(p, -1), b, a], 1)
             for i, (b, a) in enumerate(((bx, ax), (by, ay), (cos_b, az)))]
    keep = weight > 0
    idx = keep.reshape(-1).nonzero().squeeze(1)
    pix = torch.div(idx, weight.shape[1], rounding_mode="floor")
    # Column-major (M, 3) views: the BRDFs' per-component operations run on contiguous rows.
    wi = weight.new_empty((3, idx.shape[0]))
    for i, d in enumerate(local):
        torch.index_select(d.reshape(-1), 0, idx, out=wi[i])
    wi = wi.T
    wo = wo.T.contiguous().index_select(1, pix).T
    return pix.int(), wi, wo, rw.reshape(3, -1).index_select(1, idx), (scale, mass > 1e-3)
