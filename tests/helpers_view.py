"""Helpers of the tests of ``brdfkit view`` and ``brdfkit export``: the page's blobs and
data decoded, the built-in residual's materials made quickly, and the Chromium
screenshots compared."""

from __future__ import annotations

import base64
import gzip
import json
import math

import numpy as np
import pytest


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


def psnr8(a, b) -> float:
    """PSNR (dB, peak 255) of two uint8 images."""
    mse = np.mean((np.asarray(a, np.float64) - np.asarray(b, np.float64)) ** 2)
    return math.inf if mse == 0 else 10 * math.log10(255.0 ** 2 / mse)


def page_json(html: str, element: str = "brdfkit-data"):
    """The JSON of a page's ``<script id=element>`` (its data, or its shaders)."""
    return json.loads(html.split(f'<script id="{element}" type="application/json">')[1].split("</script>")[0])


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
