"""``brdfkit view`` and ``brdfkit export`` without a browser: the page's quadrature (its
shader transliterated to NumPy) against the renderer's pixels, the tables' float16
textures, the live basis and network records restored as the page restores them, the GLSL
export's uniforms, the page's size and the commands' bad input. The browser's own pictures
are ``tests/test_view_browser.py``."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from conftest import one_error_line, run_cli
from helpers_view import blob_bytes, projected_embedding, shade_like_the_page, shipped_models, table_brdf  # noqa: F401

from brdfkit.testing.examples import lambertian_table


def _normals():
    """Normals that see the sun's and the window's highlights, the horizon, and others."""
    from brdfkit.render.envmap import SUN_UV, uv_to_direction

    sun = uv_to_direction(*SUN_UV)
    rng = np.random.default_rng(1)
    n = rng.normal(size=(6, 3))
    n[:, 2] = np.abs(n[:, 2]) + 0.05
    n = np.vstack([n, sun + [0, 0, 1], [0.0, 0.0, 1.0], [0.99, 0.0, 0.14], [0.3, -0.6, 0.2]])
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def _glossy_table():
    from brdfkit.materials.synthetic import Material, table

    return table(Material("glossy", "dielectric", 0.05, albedo=(0.2, 0.1, 0.05)))


@pytest.mark.parametrize("make", [lambertian_table, _glossy_table], ids=["diffuse", "glossy"])
def test_the_pages_quadrature_is_the_renderers(make):
    """The page's shader (in NumPy: ``helpers_view.shade_like_the_page``) gives the
    renderer's pixels to float32 rounding, near the sun's highlight too."""
    from brdfkit.render.envmap import reference_envmap
    from brdfkit.render.quadrature import render_pixels
    from brdfkit.render.renderable import TableBRDF
    from brdfkit.view.quadrature_data import scene_quadrature

    table, env, data = make(), reference_envmap(), scene_quadrature()
    normals = _normals()
    ref = render_pixels(TableBRDF(table, device="cpu"), normals, env)
    page = np.stack([shade_like_the_page(table_brdf(table), n, data, env) for n in normals])
    assert np.allclose(page, ref, rtol=2e-5, atol=1e-7 * ref.max()), np.abs(page - ref).max()


def test_the_normalisation_table_is_the_renderers():
    from brdfkit.render import nodes
    from brdfkit.render.scene import QUADRATURE
    from brdfkit.view.quadrature_data import half_share_integral

    table = getattr(nodes, "half_share_table", None) or getattr(nodes, "_half_share_table")
    assert np.allclose(half_share_integral(QUADRATURE)[1], table(QUADRATURE)[1], rtol=1e-12, atol=1e-15)


def test_a_table_travels_as_float16_with_its_unmeasured_cells():
    from brdfkit.view.textures import blob, encode_planes, table_texture

    t = lambertian_table() * 3e5  # beyond float16's range until scaled
    t[3, 4, 5] = np.nan
    half, scale = table_texture(t)
    assert 2.0 ** 13 < np.nanmax(t) * scale <= 2.0 ** 14 and half.dtype == np.float16
    back = half.astype(np.float64).reshape(t.shape) / scale
    ok = np.isfinite(t)
    assert np.allclose(back[ok], t[ok], rtol=1e-3) and (back[~ok] < 0).all()
    raw = encode_planes(half)
    for compress in (True, False):
        b = blob(raw, compress=compress, planes=True)
        assert np.array_equal(np.frombuffer(blob_bytes(b), np.float16), half.reshape(-1))


def test_a_table_adds_at_most_12_mb_to_a_page(tmp_path):
    """35 MB of MERL file, 11.7 MB of base64 float16 uncompressed; gzip makes it less."""
    from brdfkit.io.merl import write_merl
    from brdfkit.view.page import write_page

    write_merl(tmp_path / "a.binary", lambertian_table())
    write_merl(tmp_path / "b.binary", lambertian_table((0.2, 0.3, 0.4)) * (1 + np.linspace(0, 1, 180))[:, None])
    one = write_page([tmp_path / "a.binary"], tmp_path / "one.html", compress=False)["bytes"]
    two = write_page([tmp_path / "a.binary", tmp_path / "b.binary"], tmp_path / "two.html", compress=False)["bytes"]
    assert 11_000_000 < two - one <= 12_000_000
    packed = write_page([tmp_path / "a.binary", tmp_path / "b.binary"], tmp_path / "z.html")["bytes"]
    assert packed < two


def test_sample_rows_place_in_plane_samples_on_the_lobe():
    from brdfkit.geometry import half_diff_from_io
    from brdfkit.io.samples import SampleSet
    from brdfkit.view.inputs import sample_rows

    ti, to = math.radians(30), np.radians([-20.0, 50.0])
    wi = np.array([[-math.sin(ti), 0, math.cos(ti)]] * 2)
    wo = np.stack([np.sin(to), 0 * to, np.cos(to)], 1)
    th, _, td, pd = half_diff_from_io(wi, wo)
    rows = sample_rows(SampleSet(th, td, pd, np.full((2, 3), 0.5)))
    assert np.allclose(rows[:, 3], 30, atol=1e-4) and np.allclose(rows[:, 4], [-20, 50], atol=1e-4)
    assert np.allclose(rows[:, 5], 0, atol=1e-3) and np.allclose(rows[:, 2], 0.5)


def test_the_mapping_constants_are_the_bases():
    from brdfkit.basis import mapping
    from brdfkit.view.live import mapping_constants

    m = mapping_constants(0.005)
    assert (m["tiny"], m["w_tiny"], m["eps"], m["cap"]) == pytest.approx(
        (mapping._TINY, mapping._W_TINY, mapping.EPS, mapping.CAP), rel=1e-9)


def _restore(record):
    """The basis slots (reference, mean, components) over the basis's cells, as
    ``live.js`` restores them (``BasisSlots``)."""
    n = 90 * 90 * 180
    cells = np.flatnonzero(np.unpackbits(np.frombuffer(blob_bytes(record["cell_mask"]), np.uint8))[:n])
    k = record["k"]
    if record["storage"] == "float32":
        return cells, np.frombuffer(blob_bytes(record["values"]), np.float32).reshape(k + 2, -1)
    stored = np.unpackbits(np.frombuffer(blob_bytes(record["stored_mask"]), np.uint8))[:n].astype(bool)
    pos = np.full(n, -1)
    pos[stored] = np.arange(stored.sum())
    p, own = cells % 180, pos[cells]
    left, right = pos[cells - p + np.maximum(p - 1, 0)], pos[cells - p + (p + 1) % 180]
    both = (left >= 0) & (right >= 0)

    def expand(v):
        half = np.float32(0.5)
        mean = v[np.maximum(left, 0)] * half + v[np.maximum(right, 0)] * half
        return np.where(own >= 0, v[np.maximum(own, 0)], np.where(both, mean, v[np.where(left >= 0, left, right)]))

    q = np.frombuffer(blob_bytes(record["components"]), np.int8).reshape(k, -1)
    scales = np.frombuffer(blob_bytes(record["scales"]), np.float32).reshape(k, -1)
    comps = q.astype(np.float32) * np.repeat(scales, record["block"], axis=1)[:, :q.shape[1]]
    half = [np.frombuffer(blob_bytes(record[s]), np.float16).astype(np.float32) for s in ("reference", "mean")]
    return cells, np.stack([expand(a) for a in (*half, *comps)])


def test_a_tiny_basis_travels_in_float32():
    from brdfkit.testing.examples import tiny_basis
    from brdfkit.view.live import basis_data

    basis = tiny_basis(4)
    rec = basis_data(basis, 3, compress=False)
    cells, slots = _restore(rec)
    part = basis.leading(3)
    assert rec["storage"] == "float32" and np.array_equal(cells, part.cells)
    assert np.array_equal(slots, np.vstack([part.reference, part.mean, part.components]))


def test_a_shipped_basis_travels_in_its_own_storage(shipped_models):
    """The built-in's half-phi_d int8 basis, restored as the page restores it, is the
    basis brdfkit decodes with (to float32 rounding), in a third of the bytes."""
    from brdfkit.basis.basis_file import load_basis
    from brdfkit.models.builtin import resolve_basis
    from brdfkit.view.live import basis_data

    part = load_basis(resolve_basis("merl80-l40")).leading(5)
    rec = basis_data(part, 5)
    cells, slots = _restore(rec)
    assert rec["storage"] == "compact" and np.array_equal(cells, part.cells)
    want = np.vstack([part.reference, part.mean, part.components])
    assert np.allclose(slots, want, rtol=1e-6, atol=1e-6 * np.abs(want).max())


def _hyponet_like_the_shader(net: np.ndarray, width: int, hd: np.ndarray) -> np.ndarray:
    """``brdfkit_hyponet`` of ``assets/brdfkit_decode.glsl`` in NumPy, from ``brdfkit_net``."""
    v = np.asarray(net, np.float64).reshape(-1)
    w1 = v[:6 * width].reshape(6, width)
    b1 = v[6 * width:7 * width]
    w2 = v[7 * width:7 * width + width * width].reshape(width, width)
    b2 = v[(7 + width) * width:(8 + width) * width]
    w3 = v[(8 + width) * width:(9 + width) * width]
    b3 = v[(9 + width) * width]
    h = np.maximum(np.maximum(hd @ w1 + b1, 0) @ w2 + b2, 0)
    return h @ w3 + b3


def test_the_exported_hyponet_is_the_residuals(shipped_models):
    """``material.json``'s ``brdfkit_net`` of each channel, run as the shader runs it, gives
    the residual's own correction at the grid's cells."""
    from brdfkit.embeddings.decoders import load_decoder
    from brdfkit.geometry import grid_hd
    from brdfkit.models.builtin import resolve_part
    from brdfkit.view.export import material_uniforms
    from brdfkit.view.live import live_material

    emb = projected_embedding(_glossy_table(), "merl80-l40", "residual", k=7)
    dec = load_decoder("residual", resolve_part("merl80-l40", "residual"))
    mat = live_material(emb, dec, "glossy")
    info = material_uniforms(mat)
    width = info["defines"]["BRDFKIT_WIDTH"]
    hd = grid_hd()[dec.obj.basis.cells[::997]]
    want = dec.obj.correction(np.asarray(mat["coefficients"]).reshape(7, 3), hd)
    got = np.stack([_hyponet_like_the_shader(info["uniforms"]["brdfkit_net"][ch], width, hd.astype(np.float64))
                    for ch in range(3)], 1)
    assert np.allclose(got, want, rtol=1e-4, atol=1e-5), np.abs(got - want).max()
    coef = info["uniforms"]["brdfkit_coefficients"][1]
    assert len(coef) == 4 * info["defines"]["BRDFKIT_TEXTURES"] and coef[:2] == [0.0, 1.0]


def test_view_writes_a_page_and_says_its_size(tmp_path, capsys):
    from brdfkit.io.merl import write_merl
    from brdfkit.io.samples import SampleSet, write_samples

    write_merl(tmp_path / "a.binary", lambertian_table())
    write_samples(tmp_path / "s.csv", SampleSet(np.array([0.1, 0.2]), np.array([0.3, 0.4]), np.array([1.0, 2.0]),
                                                np.full((2, 3), 0.2)))
    code, _, err = run_cli(capsys, ["view", tmp_path / "a.binary", tmp_path / "s.csv", "-o", tmp_path / "p.html"])
    assert code == 0, err
    size = (tmp_path / "p.html").stat().st_size
    assert f"{size:,} bytes" in err and "a (table)" in err and "points: s" in err
    html = (tmp_path / "p.html").read_text()
    data = json.loads(html.split('<script id="brdfkit-data" type="application/json">')[1].split("</script>")[0])
    assert [m["label"] for m in data["materials"]] == ["a"] and data["samples"][0]["count"] == 2
    assert "http://" not in html and "https://" not in html and "<script src" not in html  # nothing from a network


@pytest.mark.parametrize("args, words", [
    (["x.txt", "-o", "p.html"], "brdfkit view takes BRDF files"),
    (["s.csv", "-o", "p.html"], "no BRDF among the inputs"),
    (["a.binary", "-o", "p.png"], "must be an .html file"),
    (["a.binary", "-o", "missing/p.html"], "does not exist"),
])
def test_view_refuses_bad_input_in_one_line(tmp_path, capsys, monkeypatch, args, words):
    from brdfkit.io.merl import write_merl
    from brdfkit.io.samples import SampleSet, write_samples

    monkeypatch.chdir(tmp_path)
    write_merl("a.binary", lambertian_table())
    write_samples("s.csv", SampleSet(np.array([0.1]), np.array([0.3]), np.array([1.0]), np.full((1, 3), 0.2)))
    (tmp_path / "x.txt").write_text("hello")
    code, _, err = run_cli(capsys, ["view", *args])
    assert code == 2 and words in one_error_line(err)


def test_export_refuses_what_it_cannot_decode(tmp_path, capsys):
    from brdfkit.io.embedding import Embedding, write_embedding
    from brdfkit.io.merl import write_merl

    write_merl(tmp_path / "a.binary", lambertian_table())
    code, _, err = run_cli(capsys, ["export", tmp_path / "a.binary", "--glsl", tmp_path / "out"])
    assert code == 2 and "takes an embedding" in one_error_line(err)
    write_embedding(tmp_path / "h.emb", Embedding(np.zeros(7), "hypernet", "ab" * 32, "x"))
    code, _, err = run_cli(capsys, ["export", tmp_path / "h.emb", "--glsl", tmp_path / "out"])
    assert code == 2 and "a hypernet embedding has no GLSL decoder" in one_error_line(err)


def test_a_silent_browser_ends_in_one_line_within_its_deadline(tmp_path, monkeypatch):
    """A Chromium that starts and never answers (here a program that sleeps on the pipe)
    is given up at the deadline, killed, and said in one line."""
    import time

    from brdfkit.view.browser import BrowserError, screenshot

    silent = tmp_path / "chromium"
    silent.write_text("#!/bin/sh\nexec sleep 600\n")
    silent.chmod(0o755)
    monkeypatch.setenv("BRDFKIT_CHROMIUM", str(silent))
    t0 = time.monotonic()
    with pytest.raises(BrowserError) as caught:
        screenshot(tmp_path / "page.html", timeout=2)
    assert time.monotonic() - t0 < 10 and "did not answer Target.createTarget within 2 s" in str(caught.value)
    assert "\n" not in str(caught.value)


@pytest.mark.realdata
@pytest.mark.slow
def test_a_page_of_rgls_own_file_and_a_cornell_file(tmp_path, capsys):
    """An RGL ``.bsdf`` travels as its reciprocal table; a Cornell ``.brdf`` as points."""
    import os
    from pathlib import Path

    from brdfkit.io.rgl_bsdf import read_bsdf_table
    from brdfkit.view.textures import table_texture

    root = os.environ.get("BRDFKIT_REAL_DATA")
    rgl, cornell = (Path(root or "") / "rgl" / "chm_mint_rgb.bsdf", Path(root or "") / "cornell" / "acryl_blue.brdf")
    if not root or not rgl.is_file() or not cornell.is_file():
        pytest.skip("$BRDFKIT_REAL_DATA/rgl/chm_mint_rgb.bsdf or cornell/acryl_blue.brdf is absent")
    code, _, err = run_cli(capsys, ["view", rgl, cornell, "-o", tmp_path / "p.html"])
    assert code == 0, err
    html = (tmp_path / "p.html").read_text()
    data = json.loads(html.split('<script id="brdfkit-data" type="application/json">')[1].split("</script>")[0])
    half, scale = table_texture(read_bsdf_table(rgl))
    assert data["materials"][0]["scale"] == 1.0 / scale
    assert np.array_equal(np.frombuffer(blob_bytes(data["materials"][0]["table"]), np.float16), half.reshape(-1))
    assert data["samples"][0]["count"] == 1439
