"""The quadrature renderer pinned to the one it replaced (issue 14 item 1): the per-technique
float32 passes of :mod:`brdfkit.render.pairs` (NumPy since issue 44, node-major, the
B nodes' grid coordinates from their own frames) against the frozen float64 torch
renderer of ``helpers_quadrature``, and the pairs kept from one render for the next.

Tolerance: every pixel within 1e-4 of the old one relative to ``max(|old|, 0.01)``
(measured: 7e-6 at the sun's reflection in the near-mirror, 6e-7 elsewhere), the same
BRDF evaluations, the same normalisation range to 1e-6.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from helpers_foundation import lambert_table
from helpers_quadrature import render_pixels_v1

torch = pytest.importorskip("torch")

RES = 24


def _materials():
    from brdfkit.materials import synthetic

    copper = synthetic.Material("copper-0.05", "conductor", 0.05, ior=synthetic.METALS["copper"][0],
                                k=synthetic.METALS["copper"][1])
    return [synthetic.STIFF[2], synthetic.STIFF[0], synthetic.STIFF[3], copper]


def _normals(res=RES, supersample=1):
    from brdfkit.render.scene import Scene

    n, inside = Scene(resolution=res, supersample=supersample).pixel_normals()
    return n[inside]


def _pinned(new, old, new_stats, old_stats):
    assert new.dtype == old.dtype == np.float32 and new.shape == old.shape
    rel = np.abs(new.astype(np.float64) - old) / np.maximum(np.abs(old), 0.01)
    assert rel.max() < 1e-4, rel.max()
    assert new_stats.evaluations == old_stats.evaluations > 0
    np.testing.assert_allclose(new_stats.scale_range, old_stats.scale_range, rtol=1e-6)


@pytest.mark.parametrize("index", range(4), ids=lambda i: _materials()[i].name)
def test_synthetic_tables_match_the_old_renderer(index):
    from brdfkit.evaluation import metrics
    from brdfkit.materials import synthetic
    from brdfkit.render import quadrature
    from brdfkit.render.renderable import TableBRDF
    from brdfkit.render.envmap import reference_envmap

    m = _materials()[index]
    brdf = TableBRDF(synthetic.table(m), m.name, device="cpu")
    normals, env = _normals(), reference_envmap()
    old_stats, new_stats = quadrature.RenderStats(), quadrature.RenderStats()
    old = render_pixels_v1([brdf], normals, env, stats=old_stats)[0]
    quadrature.clear_cache()
    new = quadrature.render_pixels(brdf, normals, env, stats=new_stats)
    _pinned(new, old, new_stats, old_stats)
    assert metrics.psnr(new.reshape(1, -1, 3), old.reshape(1, -1, 3)) > 100


def test_uniform_environment_no_light_nodes_and_supersampling_match():
    from brdfkit.render import quadrature
    from brdfkit.render.renderable import TableBRDF
    from brdfkit.render.envmap import uniform_envmap

    brdf = TableBRDF(lambert_table([0.2, 0.5, 0.8]), device="cpu")
    normals, env = _normals(12, supersample=2), uniform_envmap((1.5, 1.0, 0.5))
    old_stats, new_stats = quadrature.RenderStats(), quadrature.RenderStats()
    old = render_pixels_v1([brdf], normals, env, stats=old_stats)[0]
    new = quadrature.render_pixels(brdf, normals, env, stats=new_stats)
    _pinned(new, old, new_stats, old_stats)


def test_kept_pairs_give_the_same_image_and_are_bounded(monkeypatch):
    from brdfkit.materials import synthetic
    from brdfkit.render import quadrature
    from brdfkit.render.renderable import TableBRDF
    from brdfkit.render.scene import Scene

    brdf = TableBRDF(synthetic.table(synthetic.STIFF[0]), device="cpu")
    scene = Scene(resolution=12)
    quadrature.clear_cache()
    calls = []
    cold_stats, warm_stats = quadrature.RenderStats(), quadrature.RenderStats()
    cold, _ = quadrature.render(brdf, scene, stats=cold_stats, progress=lambda d, t: calls.append((d, t)))
    assert len(quadrature._PAIRS) == 1
    warm, _ = quadrature.render(brdf, scene, stats=warm_stats, progress=lambda d, t: calls.append((d, t)))
    np.testing.assert_array_equal(cold, warm)
    assert (cold_stats.evaluations, cold_stats.scale_range) == (warm_stats.evaluations, warm_stats.scale_range)
    assert calls[-1][0] == calls[-1][1] and len(calls) % 2 == 0 and calls[: len(calls) // 2] == calls[len(calls) // 2:]
    # Another scene replaces it; one over the byte bound is not kept; clear_cache empties it.
    quadrature.render(brdf, Scene(resolution=10))
    assert len(quadrature._PAIRS) == 1
    monkeypatch.setattr(quadrature, "PAIR_CACHE_BYTES", 1000)
    quadrature.render(brdf, Scene(resolution=11))
    assert not quadrature._PAIRS
    monkeypatch.undo()
    quadrature.render(brdf, scene)
    quadrature.clear_cache()
    assert not quadrature._PAIRS and not quadrature._TECHNIQUES


def test_outside_of_the_light_rectangles_and_environment_lookup():
    from brdfkit.render.envmap import reference_envmap
    from brdfkit.render.shares import EnvLookup, outside, uv
    from helpers_quadrature import _rect_ramp

    env = reference_envmap()
    g = torch.Generator().manual_seed(0)
    d = torch.nn.functional.normalize(torch.randn(20000, 3, dtype=torch.float64, generator=g), dim=-1)
    rects = [(u0, u1, v0, v1, ru, rv) for u0, u1, v0, v1, _, _, ru, rv in env.bright]  # NodeSet.rects
    dn = d.numpy()
    u, v = uv(*dn.T)
    out = outside(rects, u, v)
    np.testing.assert_allclose(out, 1 - _rect_ramp(rects, d).numpy(), atol=1e-12)
    assert 0 < (out < 1).mean() < 0.1
    # A rectangle moved across u = 0 ramps the same at the moved directions.
    (u0, u1, v0, v1, ru, rv), shift = rects[1], -0.1 - rects[1][0]
    moved = outside([(u0 + shift, u1 + shift, v0, v1, ru, rv)], np.remainder(u + shift, 1.0), v)
    np.testing.assert_allclose(moved, outside(rects[1:], u, v), atol=1e-9)
    assert (moved < 1).any()
    # Mitsuba's bilinear lookup (EnvMap.radiance, float64), to the float32 arithmetic of
    # the texture coordinates and the weights (bounded per direction: _lookup_bound).
    d32 = dn.astype(np.float32)
    got = EnvLookup(env)(*uv(*d32.T)).T
    want = env.radiance(d32.astype(np.float64))
    bound = _lookup_bound(np.asarray(env.image, np.float64), *uv(*d32.astype(np.float64).T))
    assert (np.abs(got - want) <= bound[:, None]).all(), float((np.abs(got - want).max(1) / bound).max())
    assert np.median(bound) < 1e-4  # where the map is smooth, float32's rounding alone


# float32 arctan2 and arccos are within this many ULP of the exact result: NumPy's accuracy
# tests hold its float32 inverse trigonometric functions to 3 (numpy/_core/tests/data/
# umath-validation-set-arc*.csv), whichever SIMD code the CPU runs (the CPUs differ).
TRIG_ULP = 3


def _lookup_bound(img, u, v):
    """The largest difference between :class:`EnvLookup` on float32 texture coordinates and
    the float64 lookup at the same float32 directions, per direction ``(M,)``: a position
    error of ``dx`` texels in u and ``dy`` in v moves a bilinear lookup by at most the
    largest jump between adjacent texels there times it; float32 weights and sums add a
    few roundings of the largest texel there.

    ``dx``: ``arctan2`` (``TRIG_ULP`` ULP of an angle up to pi, over 2 pi), then the scale
    by ``1 / 2 pi``, the wrap into ``[0, 1)`` and the half-texel shift (each half an ULP of
    1), in texels of a row of ``W``; ``dy``: ``arccos`` (over pi) and the scale (two half
    ULPs of 1), then ``v (H - 1)`` (half an ULP), in texels of ``H - 1``. The float64
    reference's own error is negligible (1e-16)."""
    h, w = img.shape[:2]
    half = 2.0 ** -24  # half an ULP of 1 in float32
    trig = TRIG_ULP * float(np.spacing(np.float32(np.pi)))
    dx = w * (trig / (2 * np.pi) + 3 * half)
    dy = (h - 1) * (trig / np.pi + 3 * half)
    jump_u = np.abs(np.roll(img, -1, axis=1) - img).max(-1)  # column j to j + 1, wrapping
    jump_v = np.abs(np.diff(img, axis=0)).max(-1)  # row i to i + 1
    peak = img.max(-1)
    col = np.floor(u * w - 0.5).astype(np.int64)
    row = np.clip(np.floor(v * (h - 1)).astype(np.int64), 0, h - 2)
    # The texels a lookup next to its float64 position can read: one column and row more
    # on each side (float32 may cross a texel's edge).
    lu = lv = top = np.zeros(u.shape)
    for dr in (-1, 0, 1, 2):
        r = np.clip(row + dr, 0, h - 1)
        for dc in (-1, 0, 1, 2):
            c = (col + dc) % w
            lu, top = np.maximum(lu, jump_u[r, c]), np.maximum(top, peak[r, c])
            lv = np.maximum(lv, jump_v[np.clip(r, 0, h - 2), c])
    return lu * dx + lv * dy + 16 * half * top


def test_share_terms_match_half_share():
    from brdfkit.render.nodes import half_share
    from brdfkit.render.shares import theta_terms
    from brdfkit.render.scene import REFERENCE

    q = REFERENCE.quadrature
    th = np.array([2.5e-5, 1e-3, 0.01, 0.3, 1.0, 1.5])
    woh = np.array([0.9, 0.5, 0.99, 0.7, 0.3, 0.05])
    cos = np.array([0.8, 0.1, 0.5, 0.9, 0.2, 0.05])
    g, sx, sy = theta_terms(q, th.copy())
    d_c = q.cosine_grid ** 2 * np.clip(cos, 0.25, None) / math.pi
    np.testing.assert_allclose((1 - sx) / (1 + d_c * woh * g), half_share(q, th, woh, cos), rtol=1e-12)
    lo, hi = math.log(q.light_handover[0]), math.log(q.light_handover[1])
    x = np.clip((np.log(th) - lo) / (hi - lo), 0, 1)
    np.testing.assert_allclose(sy, x * x * (3 - 2 * x), atol=1e-15)


def _half_share_table_v1(q, n_o=129, n_t=300, n_p=180):
    """The per-``cos theta_o`` loop over :func:`half_share` that
    ``nodes.half_share_table`` was until its vectorisation (frozen)."""
    from brdfkit.render.nodes import half_share

    cos_o = np.linspace(0.0, 1.0, n_o)
    th = (np.arange(n_t) + 0.5) / n_t * q.half_extent
    ph = (np.arange(n_p) + 0.5) / n_p * np.pi
    st, ct = np.sin(th)[:, None], np.cos(th)[:, None]
    hx, hz = st * np.cos(ph), np.broadcast_to(ct, (n_t, n_p))
    thb = np.broadcast_to(th[:, None], (n_t, n_p))
    out = np.empty(n_o)
    for i, c in enumerate(cos_o):
        so = math.sqrt(max(0.0, 1 - c * c))
        woh = hx * so + hz * c
        wi_z = 2 * woh * hz - c
        share = half_share(q, thb, woh, wi_z)
        f = np.where((woh > 0) & (wi_z > 0), wi_z * 4 * woh * share, 0.0) * st / np.pi
        out[i] = 2 * f.sum() * (q.half_extent / n_t) * (np.pi / n_p)
    return cos_o, out


@pytest.mark.parametrize("settings", [{}, {"share_power": 2.0, "half_extent": 1.2, "cosine_grid": 6}],
                         ids=["reference", "other"])
def test_half_share_table_matches_the_loop(settings):
    import dataclasses

    from brdfkit.render import nodes
    from brdfkit.render.scene import REFERENCE

    q = dataclasses.replace(REFERENCE.quadrature, **settings)
    nodes._SHARE_TABLES.clear()
    cos_o, got = nodes.half_share_table(q, n_o=33)
    want_cos, want = _half_share_table_v1(q, n_o=33)
    np.testing.assert_array_equal(cos_o, want_cos)
    assert want.min() >= 0 and want.max() > 0.1
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-15)
    assert nodes.half_share_table(q, n_o=33)[1] is got  # once per process
