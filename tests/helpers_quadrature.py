"""A frozen copy of the quadrature renderer as it was before the per-kind rewrite
(``brdfkit.render.quadrature._render_pixels`` at commit e046ae5): the float64 pass over
the full (pixel x node) tensor, in torch, with the torch helpers it used (frozen here
since the renderer became NumPy). ``tests/test_quadrature_pinned.py`` pins the renderer
to it.
"""

from __future__ import annotations

import math

import numpy as np

from brdfkit.render.nodes import NodeSet
from brdfkit.render.nodes import half_share_table as _half_share_table
from brdfkit.render.scene import REFERENCE, Quadrature


def direction_to_uv(d):
    import torch

    u = torch.atan2(d[..., 0], -d[..., 2]) / (2 * math.pi)
    return u - torch.floor(u), torch.arccos(d[..., 1].clamp(-1.0, 1.0)) / math.pi


def _smoothstep(x):
    x = x.clamp(0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def _frames(n):
    """Orthonormal tangent frames (Duff et al. 2017), torch."""
    import torch

    s = torch.where(n[:, 2] >= 0, 1.0, -1.0).to(n.dtype)
    a = -1.0 / (s + n[:, 2])
    b = n[:, 0] * n[:, 1] * a
    t = torch.stack([1 + s * n[:, 0] ** 2 * a, s * b, -s * n[:, 0]], -1)
    bt = torch.stack([b, s + n[:, 1] ** 2 * a, -n[:, 1]], -1)
    return t, bt


def half_share(q, theta_h, wo_dot_h, cos_i):
    """:func:`brdfkit.render.nodes.half_share` in torch."""
    k, p = q.half_rings, q.half_power
    th = theta_h.clamp_min(1e-12)
    u = k * (th / (math.pi / 2)) ** (1.0 / p)
    dth_du = (math.pi / 2) * p * u ** (p - 1) / k ** p
    m = (q.half_phi * th.sin().sqrt()).clamp_min(q.half_phi_min)
    d_b = m / (2 * math.pi * th.sin() * dth_du * 4 * wo_dot_h.clamp_min(1e-12))
    d_c = q.cosine_grid ** 2 * cos_i.clamp_min(0.25) / math.pi
    x = (th / q.half_extent).clamp(0.0, 1.0)
    cut = 1.0 - x * x * (3.0 - 2.0 * x)
    return cut / (1.0 + (d_c / d_b) ** q.share_power)

BLOCK_PAIRS = 1 << 17


class _Nodes:
    """Torch copies of a :class:`NodeSet` on one device (float64: the first half-vector
    rings sit 1e-5 rad from the specular direction, below float32 resolution)."""

    def __init__(self, ns: NodeSet, device):
        import torch

        f = dict(dtype=torch.float64, device=device)
        self.cos = torch.as_tensor(ns.cosine, **f)
        self.half = torch.as_tensor(ns.half, **f)
        self.half_w = torch.as_tensor(ns.half_weight, **f)
        self.light = torch.as_tensor(ns.light, **f)
        self.light_w = torch.as_tensor(ns.light_weight, **f)
        self.light_rad = torch.as_tensor(ns.light_radiance, **f)
        self.rects = ns.rects
        self.n_c, self.n_b, self.n_a = len(ns.cosine), len(ns.half), len(ns.light)


def render_pixels_v1(brdfs, normals, env, wo_world=(0.0, 0.0, 1.0), q: Quadrature | None = None,
                      progress=None, stats=None):
    """The old ``_render_pixels(brdfs, ...)``, unchanged: a list of float32 ``(P, 3)``
    images, one per BRDF."""
    import torch

    q = q or REFERENCE.quadrature
    dev = torch.device("cpu")
    nd = _Nodes(NodeSet(q, env), dev)
    n_all = torch.as_tensor(np.asarray(normals, np.float64), dtype=torch.float64, device=dev)
    wo_w = torch.as_tensor(wo_world, dtype=torch.float64, device=dev)
    total = n_all.shape[0]
    outs = [torch.zeros(total, 3, dtype=torch.float64, device=dev) for _ in brdfs]
    n_nodes = nd.n_c + nd.n_b + nd.n_a
    block = max(1, BLOCK_PAIRS // n_nodes)
    kind_of = torch.cat([torch.full((nd.n_c,), 0), torch.full((nd.n_b,), 1),
                         torch.full((nd.n_a,), 2)]).to(dev)
    cos_o_tab, share_tab = _half_share_table(q)
    lo, hi = math.log(q.light_handover[0]), math.log(q.light_handover[1])
    evaluations, smin, smax = 0, math.inf, -math.inf
    with torch.no_grad():
        for s in range(0, total, block):
            n = n_all[s:s + block]
            p = n.shape[0]
            t, bt = _frames(n)
            frame = torch.stack([t, bt, n], 1)  # (P, 3, 3): rows are the local axes
            wo = frame @ wo_w  # (P, 3) local
            woh = wo @ nd.half.T  # (P, Nb)
            wi = torch.cat([nd.cos.expand(p, -1, -1),
                            2 * woh[..., None] * nd.half[None] - wo[:, None],  # mirror wo about h
                            torch.einsum("pij,nj->pni", frame, nd.light)], 1)  # (P, N, 3) local
            ok = wi[..., 2] > 0
            ok[:, nd.n_c:nd.n_c + nd.n_b] &= woh > 0
            pix, node = ok.nonzero(as_tuple=True)
            kind = kind_of[node]
            wi_l = torch.nn.functional.normalize(wi[pix, node], dim=-1)
            wo_l = wo[pix]
            cos = wi_l[:, 2]
            wi_w = (wi_l[:, :, None] * frame[pix]).sum(1)  # local -> world
            hv = wi_l + wo_l
            th = torch.atan2(torch.sqrt(hv[:, 0] ** 2 + hv[:, 1] ** 2), hv[:, 2])
            s_b0 = half_share(q, th, (wo_l * hv).sum(-1) / hv.norm(dim=-1), cos)
            beta = 1.0 - _smoothstep((torch.log(th.clamp_min(1e-30)) - lo) / (hi - lo))
            rho = _rect_ramp(nd.rects, wi_w)
            share = torch.where(kind == 0, (1 - s_b0) * (1 - rho),
                                torch.where(kind == 1, s_b0 * (1 - rho + rho * beta),
                                            rho * (1 - s_b0 * beta)))
            bi = (node - nd.n_c).clamp(0, max(nd.n_b - 1, 0))
            ai = (node - nd.n_c - nd.n_b).clamp(0, max(nd.n_a - 1, 0))
            w = torch.where(kind == 0, math.pi / (nd.n_c * cos),
                            torch.where(kind == 1, nd.half_w[bi] * 4 * woh[pix, bi] if nd.n_b else cos,
                                        nd.light_w[ai] if nd.n_a else cos))
            # Normalise B and C to the exact measure of their shares, per pixel.
            geo = w * cos / math.pi
            mass = torch.zeros(p, 4, dtype=torch.float64, device=dev)
            mass.index_put_((pix, kind), geo * share, accumulate=True)
            is_a = kind == 2
            mass[:, 3].index_add_(0, pix[is_a], (geo * s_b0 * rho * (1 - beta))[is_a])
            i_b = torch.as_tensor(np.interp(wo[:, 2].cpu().numpy(), cos_o_tab, share_tab),
                                  dtype=torch.float64, device=dev)
            target_b = i_b - mass[:, 3]
            target_c = 1.0 - target_b - mass[:, 2]
            scale = torch.ones(p, 3, dtype=torch.float64, device=dev)
            scale[:, 0] = torch.where(mass[:, 0] > 1e-9, target_c / mass[:, 0].clamp_min(1e-300), 1.0)
            scale[:, 1] = torch.where(mass[:, 1] > 1e-9, target_b / mass[:, 1].clamp_min(1e-300), 1.0)
            big = mass[:, :2] > 1e-3
            if big.any():
                smin = min(smin, float(scale[:, :2][big].min()))
                smax = max(smax, float(scale[:, :2][big].max()))
            weight = w * share * scale[pix, kind] * cos
            keep = weight > 0
            pix, kind, ai, wi_l, wo_l, wi_w, weight = (
                a[keep] for a in (pix, kind, ai, wi_l, wo_l, wi_w, weight))
            wi_f, wo_f = wi_l.float(), wo_l.float()
            radiance = torch.empty(pix.numel(), 3, dtype=torch.float64, device=dev)
            is_a = kind == 2
            radiance[is_a] = nd.light_rad[ai[is_a]]
            radiance[~is_a] = torch.from_numpy(env.radiance(wi_w[~is_a].float().numpy().astype(np.float64)))
            evaluations += int(pix.numel())
            for brdf, out in zip(brdfs, outs):
                f = torch.from_numpy(np.asarray(brdf.eval_dirs(wi_f.numpy(), wo_f.numpy()), np.float64))
                out[s:s + p].index_add_(0, pix, radiance * f * weight[:, None])
            if progress is not None:
                progress(min(total, s + p), total)
    if stats is not None:
        stats.evaluations = evaluations
        stats.scale_range = (smin, smax) if smin <= smax else (1.0, 1.0)
    return [out.float().cpu().numpy() for out in outs]


def _rect_ramp(rects, d):
    """``rho``: 1 inside the light rectangles, falling to 0 across their margins, for world
    directions ``d (N, 3)``."""
    import torch

    out = torch.zeros(d.shape[0], dtype=d.dtype, device=d.device)
    if not rects:
        return out
    # Texture coordinates only for directions in the rectangles' band of elevations.
    y = d[:, 1]
    band = torch.zeros_like(y, dtype=torch.bool)
    for _, _, v0, v1, _, _ in rects:
        band |= (y <= math.cos(math.pi * max(v0, 0.0))) & (y >= math.cos(math.pi * min(v1, 1.0)))
    idx = band.nonzero(as_tuple=True)[0]
    if idx.numel() == 0:
        return out
    u, v = direction_to_uv(d[idx])
    ramp_all = torch.zeros_like(u)
    for u0, u1, v0, v1, ru, rv in rects:
        uu = torch.where(u < u0, u + 1.0, u) if u0 < 0 else u  # a rectangle may cross u = 0
        ramp = (_smoothstep((uu - u0) / ru) * _smoothstep((u1 - uu) / ru)
                * _smoothstep((v - v0) / rv) * _smoothstep((v1 - v) / rv))
        ramp_all = torch.maximum(ramp_all, ramp)
    out[idx] = ramp_all
    return out
