"""Helpers of the tests of ``brdfkit view`` and ``brdfkit export``: the page's shaders
transliterated to NumPy (what the browser computes, checked against the renderer without a
browser), the page's blobs decoded, the built-in residual's materials made quickly, and the
Chromium screenshots compared."""

from __future__ import annotations

import base64
import gzip
import math

import numpy as np
import pytest

from brdfkit.view.quadrature_data import outside, theta_terms


def blob_bytes(b: dict) -> bytes:
    """A page blob's bytes, as ``blobs.js`` decodes them."""
    raw = base64.b64decode(b["data"])
    raw = gzip.decompress(raw) if b["enc"] == "gzip" else raw
    assert len(raw) == b["bytes"]
    if not b["planes"]:
        return raw
    n = len(raw) // 2
    out = bytearray(len(raw))
    out[0::2], out[1::2] = raw[:n], raw[n:]
    return bytes(out)


def _uv(d):
    u = np.arctan2(d[..., 0], -d[..., 2]) / (2 * np.pi)
    return u - np.floor(u), np.arccos(np.clip(d[..., 1], -1, 1)) / np.pi


def _theta_h(wi, wo):
    return np.arctan2(np.hypot(wi[..., 0] + wo[0], wi[..., 1] + wo[1]), wi[..., 2] + wo[2])


def shade_like_the_page(brdf, n, data, env) -> np.ndarray:
    """``quadrature_shade`` of ``assets/quadrature.glsl`` in NumPy (float64) at one world
    normal ``n``: ``brdf(wi (M, 3), wo (3,)) -> (M, 3)``, ``data`` the
    :func:`~brdfkit.view.quadrature_data.scene_quadrature`, ``env`` its
    :class:`~brdfkit.render.envmap.EnvMap`."""
    q_nodes, (nc, nb, na) = data["nodes"].astype(np.float64), data["counts"]
    from brdfkit.render.scene import REFERENCE

    q = REFERENCE.quadrature
    s = 1.0 if n[2] >= 0 else -1.0
    a = -1.0 / (s + n[2])
    b = n[0] * n[1] * a
    t = np.array([1 + s * n[0] ** 2 * a, s * b, -s * n[0]])
    bt = np.array([b, s + n[1] ** 2 * a, -n[1]])
    m = np.stack([t, bt, n], 1)  # columns: local -> world
    wo = np.array([t[2], bt[2], n[2]])
    d_c = data["constants"]["d_c"]

    def env_at(u, v):
        return env_bilinear(env.image, u, v)

    # A
    p, pq = q_nodes[3, :na], q_nodes[4, :na]
    loc = p[:, :3] @ m
    g, sx, sy = theta_terms(q, _theta_h(loc, wo))
    r = d_c * np.clip(loc[:, 2], 0.25, None) * np.sqrt(0.5 * (1 + p[:, 2])) * g
    geo = np.where(loc[:, 2] > 0, pq[:, 0] * loc[:, 2], 0.0) * p[:, 3] / (1 + r)
    w_a = geo * (r + sx + (1 - sx) * sy)
    mass_a, mass_3 = w_a.sum() / np.pi, (geo * (1 - sx) * sy).sum() / np.pi
    sum_a = (pq[:, 1:] * w_a[:, None] * brdf(loc, wo)).sum(0)
    # B
    p, pq = q_nodes[1, :nb], q_nodes[2, :nb]
    woh = p[:, :3] @ wo
    cos_b = 2 * woh * p[:, 2] - wo[2]
    keep = (woh > 0) & (cos_b > 0)
    r = d_c * np.clip(cos_b, 0.25, None) * np.clip(woh, 1e-12, None) * p[:, 3]
    w_b = np.where(keep, pq[:, 3] * woh * cos_b * pq[:, 0] / (1 + r), 0.0)
    u, v = _uv(2 * woh[:, None] * (p[:, :3] @ m.T) - np.array([0, 0, 1.0]))
    w_b = w_b * (outside(data["rects"], u, v) * pq[:, 1] + pq[:, 2])
    wi_b = np.column_stack([2 * woh[:, None] * p[:, :2] - wo[:2], cos_b])
    sum_b = (env_at(u, v) * w_b[:, None] * np.where(keep[:, None], brdf(wi_b, wo), 0.0)).sum(0)
    mass_b = w_b.sum() / np.pi
    # C
    p = q_nodes[0, :nc]
    g, sx, _ = theta_terms(q, _theta_h(p[:, :3], wo))
    r = p[:, 3] * np.sqrt(0.5 * (p[:, :3] @ wo + 1)) * g
    u, v = _uv(p[:, :3] @ m.T)
    share = (r + sx) / (1 + r) * outside(data["rects"], u, v)
    sum_c = (env_at(u, v) * share[:, None] * brdf(p[:, :3], wo)).sum(0)
    mass_c = share.sum() / nc
    ib = np.interp(wo[2], np.linspace(0, 1, data["constants"]["ib_count"]),
                   q_nodes[5, :data["constants"]["ib_count"], 0])
    target_b = ib - mass_3
    target_c = 1 - target_b - mass_a
    scale_c = target_c / mass_c if mass_c > 1e-9 else 1.0
    scale_b = target_b / mass_b if mass_b > 1e-9 else 1.0
    return sum_c * scale_c * math.pi / nc + sum_b * scale_b + sum_a


def env_bilinear(image, u, v):
    """``q_env`` of ``assets/quadrature.glsl``: Mitsuba's bilinear lookup of a lat-long map."""
    h, w = image.shape[:2]
    x = (u - 0.5 / w) * w
    x = x - np.floor(x / w) * w
    y = v * (h - 1)
    x0, y0 = np.clip(np.floor(x), 0, w - 1), np.clip(np.floor(y), 0, h - 2)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    x0, y0 = x0.astype(int), y0.astype(int)
    x1 = (x0 + 1) % w
    img = np.asarray(image, np.float64)
    return ((1 - fy) * ((1 - fx) * img[y0, x0] + fx * img[y0, x1])
            + fy * ((1 - fx) * img[y0 + 1, x0] + fx * img[y0 + 1, x1]))


def table_brdf(table):
    """``brdfkit_eval`` of ``assets/brdfkit_eval.glsl`` in NumPy: the renderer's lookup."""
    from brdfkit.geometry import half_diff_from_io
    from brdfkit.geometry.trilinear import lookup_trilinear

    def brdf(wi, wo):
        wo = np.broadcast_to(wo, wi.shape)
        th, _, td, pd = half_diff_from_io(wi, wo)
        out = lookup_trilinear(table, th, td, pd, fill=0.0)
        return np.where(((wi[:, 2] > 0) & (wo[:, 2] > 0))[:, None], out, 0.0)

    return brdf


def psnr8(a, b) -> float:
    """PSNR (dB, peak 255) of two uint8 images."""
    mse = np.mean((np.asarray(a, np.float64) - np.asarray(b, np.float64)) ** 2)
    return math.inf if mse == 0 else 10 * math.log10(255.0 ** 2 / mse)


def png_pixels(path) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(path).convert("RGB"))


def display_u8(img) -> np.ndarray:
    """A linear render as ``brdfkit render --png`` writes it (uint8)."""
    from brdfkit.render.display import display_encode

    return np.round(display_encode(img) * 255.0).astype(np.uint8)


@pytest.fixture
def shipped_models(monkeypatch):
    """The package's own built-in models (every other test sees an empty folder)."""
    from brdfkit.models.builtin import models_folder, read_manifest

    monkeypatch.delenv("BRDFKIT_BUILTIN_MODELS", raising=False)
    if not read_manifest(models_folder()).installed():
        pytest.skip("no built-in model files in this checkout (brdfkit/models)")


def projected_embedding(table, model: str, kind: str, k: int = 13, correction: float = 1.0):
    """A basis or residual embedding of ``table`` by the least-squares projection onto the
    built-in ``model``'s basis (a real embedding of that kind, made in a second instead of
    ``brdfkit encode``'s minutes; ``correction`` the residual's weight)."""
    from brdfkit.embeddings.decoders import load_decoder
    from brdfkit.io.embedding import Embedding
    from brdfkit.models.builtin import resolve_part

    dec = load_decoder(kind, resolve_part(model, kind))
    basis = dec.obj.basis if kind == "residual" else dec.obj
    c = basis.leading(k).project(table).astype(np.float32)
    if kind == "basis":
        return Embedding(c.reshape(-1), "basis", dec.digest, "test")
    return Embedding(c.reshape(-1), "residual", dec.digest, "test", parts={"basis": dec.obj.basis_digest,
                     "residual": dec.digest}, options={"correction": float(correction)})
