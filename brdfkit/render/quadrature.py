"""The reference-scene renderer: deterministic quadrature, no path tracing.

A convex object under a distant environment sees nothing but the environment, so each
pixel of the reference scene (:mod:`brdfkit.render.scene`) is the direct-lighting integral

    L_o(wo) = integral over the upper hemisphere of L_env(wi) f(wi, wo) cos(theta_i) dwi

at the pixel centre's sphere normal (known in closed form). It is computed with a fixed
set of directions per pixel, the same for every render, so images are noise-free and
reproducible. Three node sets ("techniques") each cover what makes the integrand sharp
somewhere, and a partition of unity ``s_C + s_B + s_A = 1`` over directions says which
technique integrates which part (deterministic multiple importance sampling; Veach and
Guibas 1995). Each node adds ``w s_X L_env f cos``, ``w`` its solid-angle weight.

* **Cosine nodes** (C): an ``n x n`` grid of cell midpoints, concentric disk map
  (Shirley and Chiu 1997) projected to the hemisphere; ``w = pi / (N_C cos(theta_i))``.
  Smooth lighting on diffuse and rough materials.
* **Half-vector nodes** (B): rings ``k = 0 .. K-1`` at ``theta_h = pi/2 (u / K)^p``,
  ``u = k + 1/2``, ``M_k = max(M_min, round(M sqrt(sin theta_h)))`` azimuths each, ``wi``
  the mirror of ``wo`` about each ``h``; ``w = 4 (wo.h) sin(theta_h) dtheta_h/du 2 pi / M_k``.
  With ``p = 3`` the first ring is ``pi/2 (1 / 2K)^3`` (2.5e-5 rad for ``K = 20``) from
  the specular direction, so near-mirror lobes (and MERL's own square-root ``theta_h``
  spacing) are resolved.
* **Light nodes** (A): a fixed grid of world directions in each rectangle of
  ``EnvMap.bright`` (the sun and the window of the reference map), uniform in texture
  coordinates; each node carries the environment radiance *averaged over its patch*
  (integrated once on a fine sub-grid), so the sun's power is exact however few nodes
  cover it.

Shares: ``s_B = s_B0 (1 - rho + rho beta)``, ``s_A = rho (1 - s_B0 beta)``,
``s_C = (1 - s_B0)(1 - rho)``. ``s_B0`` (:func:`half_share`) is the balance heuristic
between the half-vector and cosine nodes' densities (``d_B / (d_B + d_C)``, the ring count
taken as continuous in ``theta_h`` and ``d_C`` floored at a quarter of its value at the
normal, so that coarse outer rings never own the horizon), times a smooth cut to 0 at
``theta_h = half_extent``. ``rho`` is a ramp that is 1 inside a light rectangle and falls
to 0 over its margin, and ``beta`` = 1 for ``theta_h < light_handover[0]`` falling
(smoothly in ``log theta_h``) to 0 at ``light_handover[1]``: near the specular direction
the dense half-vector rings see a bright source better than the light grid does,
elsewhere the light grid does. Cosine nodes never take a share inside a light rectangle,
so no coarse node ever lands on the sun.

Finally each technique is normalised so that, for every pixel, its weights integrate its
share of the cosine-weighted hemisphere exactly: ``sum w s_B cos / pi`` to the tabulated
``integral s_B0 cos / pi`` (a function of ``theta_o`` only, minus the part the light
nodes hold), the cosine nodes to the rest. This makes the quadrature exact for a
constant BRDF under any environment that is constant outside the light rectangles, and
changes the weights by well under 1% otherwise (:attr:`RenderStats.scale_range`).

The BRDF is evaluated only at the queried direction pairs above the horizon with a
non-zero share (``brdf.eval_dirs``: a trilinear table lookup or the hyponet itself),
in blocks of pixels x nodes. Background pixels are black. Everything runs in torch on
the BRDF's device.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .nodes import NodeSet, _frames, _half_share_table, _Nodes, _rect_ramp, _smoothstep, half_share  # noqa: F401 (NodeSet, half_share re-exported)
from .scene import REFERENCE, Quadrature, Scene

__all__ = ["NodeSet", "RenderStats", "render", "render_many", "render_pixels"]

# Pairs (pixel x node) per block: large enough to amortise Python, small enough for cache.
BLOCK_PAIRS = 1 << 17


@dataclasses.dataclass
class RenderStats:
    """What a render did, filled in by :func:`render_pixels` when passed one.

    Attributes
    ----------
    evaluations
        BRDF evaluations made (per BRDF, when several are rendered in one pass).
    scale_range
        ``(min, max)`` of the per-pixel normalisation factors of the half-vector and
        cosine nodes (``(1, 1)`` when none applied).
    """

    evaluations: int = 0
    scale_range: tuple = (1.0, 1.0)


def render_pixels(brdf, normals, env, wo_world=(0.0, 0.0, 1.0), q: Quadrature | None = None,
                  progress=None, stats: RenderStats | None = None):
    """Direct lighting of surface points with world normals ``normals``.

    Parameters
    ----------
    brdf
        Object with ``eval_dirs(wi, wo)`` (see :mod:`brdfkit.render.brdf`).
    normals
        Array-like ``(P, 3)`` unit world normals.
    env
        :class:`~brdfkit.render.envmap.EnvMap`.
    wo_world
        World view direction (towards the camera), the same for all points.
    q
        Quadrature settings (default: the reference scene's).
    progress
        Optional callable ``progress(done_points, total_points)``.
    stats
        Optional :class:`RenderStats`, filled in with the BRDF evaluations made and the
        range of the normalisation factors.

    Returns
    -------
    numpy.ndarray
        float32 ``(P, 3)`` outgoing radiance.
    """
    return _render_pixels([brdf], normals, env, wo_world, q, progress, stats)[0]


def _render_pixels(brdfs, normals, env, wo_world=(0.0, 0.0, 1.0), q: Quadrature | None = None,
                   progress=None, stats: RenderStats | None = None):
    """:func:`render_pixels` of several BRDFs in one pass: the nodes, shares and weights
    are computed once and each BRDF is evaluated at the same direction pairs; each image
    is the one a render of that BRDF alone gives, to the bit (same operations, same
    order)."""
    import torch

    q = q or REFERENCE.quadrature
    devs = [getattr(b, "device", None) or torch.device("cpu") for b in brdfs]
    if len({str(torch.device(d)) for d in devs}) != 1:
        raise ValueError(f"BRDFs rendered together must share a device, got {sorted(map(str, devs))}")
    dev = devs[0]
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
            radiance[~is_a] = env.radiance(wi_w[~is_a].float()).double()
            evaluations += int(pix.numel())
            for brdf, out in zip(brdfs, outs):
                f = brdf.eval_dirs(wi_f, wo_f).double()
                out[s:s + p].index_add_(0, pix, radiance * f * weight[:, None])
            if progress is not None:
                progress(min(total, s + p), total)
    if stats is not None:
        stats.evaluations = evaluations
        stats.scale_range = (smin, smax) if smin <= smax else (1.0, 1.0)
    return [out.float().cpu().numpy() for out in outs]


def render(brdf, scene: Scene = REFERENCE, env=None, progress=None, stats: RenderStats | None = None):
    """Render the reference scene.

    Parameters
    ----------
    brdf
        Object with ``eval_dirs`` (:class:`~brdfkit.render.brdf.TableBRDF`,
        :class:`~brdfkit.model.brdf.NeuralBRDF`).
    scene
        :class:`~brdfkit.render.scene.Scene` (resolution, quadrature).
    env
        Environment (default :func:`~brdfkit.render.envmap.reference_envmap`).
    progress
        Optional callable ``progress(done_pixels, total_pixels)``.
    stats
        Optional :class:`RenderStats` to fill in (see :func:`render_pixels`).

    Returns
    -------
    tuple
        ``(image, mask)``: float32 ``(R, R, 3)`` linear-sRGB radiance (background 0, the
        average of the pixel's sample points) and the boolean mask ``(R, R)`` of pixels
        with at least one sample point on the object.
    """
    return render_many([brdf], scene, env, progress, stats)[0]


def render_many(brdfs, scene: Scene = REFERENCE, env=None, progress=None, stats: RenderStats | None = None):
    """Render the reference scene with each of ``brdfs`` in one pass (``brdfkit metrics``
    of two tables): the quadrature's nodes, shares and weights are computed once and every
    BRDF is evaluated at the same direction pairs, so each image equals :func:`render` of
    that BRDF alone, to the bit.

    Parameters
    ----------
    brdfs
        Sequence of objects with ``eval_dirs``, on one device.
    scene, env, progress, stats
        As for :func:`render` (``stats.evaluations`` counts the evaluations of one BRDF).

    Returns
    -------
    list
        ``(image, mask)`` per BRDF, as :func:`render` returns them.
    """
    from .envmap import reference_envmap

    env = env if env is not None else reference_envmap()
    normals, inside = scene.pixel_normals()
    images = _render_pixels(list(brdfs), normals[inside], env, q=scene.quadrature, progress=progress,
                            stats=stats)
    out = []
    for pixels in images:
        samples = np.zeros(normals.shape, np.float32)
        samples[inside] = pixels
        out.append((samples.mean(2), inside.any(2)))
    return out
