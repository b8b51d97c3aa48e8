"""``brdfkit view`` and ``brdfkit export`` without a browser: the tables' float16
textures, what the page's data holds (the renderer's own quadrature constants, brdfkit's
colours), the layouts the decoder's shader is given, its GLSL files assembled by what each
requires, the page's size, the export's folder and the commands' bad input, and a browser
that hangs. What the page draws is ``tests/test_view_browser.py``'s (headless Chromium):
no test here computes what a shader computes."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from conftest import one_error_line, run_cli
from helpers_view import blob_bytes, page_json, projected_embedding, shipped_models  # noqa: F401

from brdfkit.testing.examples import lambertian_table


def _glossy_table():
    from brdfkit.materials.synthetic import Material, table

    return table(Material("glossy", "dielectric", 0.05, albedo=(0.2, 0.1, 0.05)))


def test_the_pages_quadrature_is_the_renderers_own():
    """The node texture holds the renderer's per-node constants, as it rounds them."""
    from brdfkit.render.envmap import reference_envmap
    from brdfkit.render.nodes import NodeSet
    from brdfkit.render.pairs import Techniques
    from brdfkit.render.scene import QUADRATURE
    from brdfkit.view.quadrature_data import scene_quadrature

    data, env = scene_quadrature(), reference_envmap()
    tq = Techniques(NodeSet(QUADRATURE, env), env)
    nodes, (nc, nb, na) = data["nodes"], data["counts"]
    assert np.array_equal(nodes[1, :nb, 3], tq.b_g[:, 0]) and np.array_equal(nodes[2, :nb, 3], tq.b_w4[:, 0])
    assert np.array_equal(nodes[4, :na, 1:], tq.a_rad.T) and np.array_equal(nodes[0, :nc, 3], tq.c_dc[:, 0])
    assert np.array_equal(nodes[5, :data["uniforms"]["u_ib_count"], 0], tq.i_b[1].astype(np.float32))
    assert data["uniforms"]["u_counts"] == [nc, nb, na] and data["uniforms"]["u_rect_count"] == len(tq.rects)


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
    from brdfkit.testing.examples import tiny_basis
    from brdfkit.view.live import mapping_constants

    basis = tiny_basis(4)
    m = mapping_constants(basis)
    assert (m["tiny"], m["w_tiny"], m["eps"], m["cap"], m["w_floor"]) == pytest.approx(
        (mapping._TINY, mapping._W_TINY, mapping.EPS, mapping.CAP, basis.w_floor), rel=1e-9)


def test_a_materials_defines_name_every_layout_of_the_decoder(shipped_models):
    """``material_uniforms`` gives the shader each mapping constant's index, the textures'
    sum and, for a residual, the hyponet's offsets, where its tensors sit."""
    from brdfkit.embeddings.decoders import load_decoder
    from brdfkit.models.builtin import resolve_part
    from brdfkit.residual.network import hyponet_weights, net_input
    from brdfkit.view.live import hyponet_layout, live_material, mapping_constants, material_uniforms

    emb = projected_embedding(_glossy_table(), "merl80-l40", "residual", k=7)
    dec = load_decoder("residual", resolve_part("merl80-l40", "residual"))
    mat = live_material(emb, dec, "glossy")
    info = material_uniforms(mat)
    d, constants = info["defines"], mapping_constants(mat["basis"])
    assert [info["uniforms"]["brdfkit_mapping"][d[f"BRDFKIT_MAPPING_{n.upper()}"]] for n in constants] == \
        list(constants.values()) and d["BRDFKIT_MAPPING_SIZE"] == len(constants)
    assert d["BRDFKIT_TEXTURES"] == 3 and d["BRDFKIT_TAPS"] == "BRDFKIT_TAP(0) + BRDFKIT_TAP(1) + BRDFKIT_TAP(2)"
    cfg, state = mat["net"]
    layout = hyponet_layout(cfg.width)
    assert {k: d[f"BRDFKIT_NET_{k.upper()}"] for k in layout} == layout and d["BRDFKIT_WIDTH"] == 4 * layout["row"]
    c = np.asarray(mat["coefficients"]).reshape(7, 3)
    w1, b1, w2, b2, w3, b3 = (w[2] for w in hyponet_weights(state, cfg, net_input((c / mat["basis"].sigma[:7, None]).T,
                                                                                  cfg.k_max)))
    net = np.asarray(info["channels"][2]["brdfkit_net"], np.float32).reshape(-1, 4)
    row = lambda name, i=0: net[layout[name] + i * layout["row"]:][:layout["row"]].reshape(-1)[:cfg.width]  # noqa: E731
    assert np.array_equal(row("w1", 5), w1[5]) and np.array_equal(row("w2", cfg.width - 1), w2[-1])
    assert np.array_equal(row("b2"), b2) and np.array_equal(row("w3"), w3[:, 0]) and net[layout["b3"], 0] == b3[0]
    assert net.shape[0] == layout["size"] and info["channels"][2]["brdfkit_coefficients"][2:9] == \
        [float(x) for x in c[:, 2].astype(np.float32)]


def test_basis_textures_hold_the_slots_by_the_layout():
    from brdfkit.testing.examples import tiny_basis
    from brdfkit.view.live import basis_data, basis_textures, slot_layout

    basis = tiny_basis(4)
    part = basis.leading(3)
    tex = [t.reshape(-1, 4) for t in basis_textures(basis, 3)]
    assert slot_layout(3) == [[0, 1, 2, 3], [4]] and len(tex) == 2
    off = np.setdiff1d(np.arange(tex[0].shape[0]), part.cells)
    assert np.array_equal(tex[0][part.cells, 0], part.reference.astype(np.float32)) and (tex[0][off, 0] == -1).all()
    assert np.array_equal(tex[1][part.cells, 0], part.components[2].astype(np.float32)) and (tex[1][:, 1:] == 0).all()
    rec = basis_data(basis, 3, compress=False)
    assert rec["storage"] == "float32" and rec["layout"] == slot_layout(3) and rec["fill"][:2] == [-1.0, 0.0]
    values = np.frombuffer(blob_bytes(rec["values"]), np.float32).reshape(5, -1)
    assert np.array_equal(values[1], part.mean.astype(np.float32))


def test_a_shipped_basis_travels_in_its_own_storage(shipped_models):
    """The built-in's half-phi_d int8 basis goes to the page as stored, a third of the
    bytes of float32 (the page restores it: ``live.js``, drawn by the browser test)."""
    from brdfkit.basis.basis_file import load_basis
    from brdfkit.models.builtin import resolve_basis
    from brdfkit.view.live import basis_data

    part = load_basis(resolve_basis("merl80-l40")).leading(5)
    rec = basis_data(part, 5, compress=False)
    assert rec["storage"] == "compact"
    assert sum(rec[k]["bytes"] for k in ("reference", "mean", "components")) < 7 * 4 * part.cells.size / 3


def test_glsl_files_state_what_they_need():
    """Each program is its files in the order they require each other, each once; the
    export ships every file its two shaders need."""
    from brdfkit.view.export import _shader_files
    from brdfkit.view.page import PROGRAMS, SHADERS, glsl_files, glsl_program

    assert glsl_files("render.frag") == ["brdfkit_grid.glsl", "brdfkit_eval.glsl", "brdfkit_frame.glsl",
                                         "quadrature.glsl", "render.frag"]
    assert set(_shader_files()) == {"brdfkit_grid.glsl", "brdfkit_eval.glsl", "brdfkit_decode.glsl",
                                    "brdfkit_bake.frag"}
    assert {f for p in PROGRAMS.values() for f in glsl_files(p)} == set(SHADERS)
    assert "#pragma brdfkit" not in glsl_program("render.frag")
    with pytest.raises(ValueError, match="require each other: a.glsl -> b.glsl -> a.glsl"):
        glsl_files("a.glsl", {"a.glsl": "#pragma brdfkit require(b.glsl)\n", "b.glsl": "#pragma brdfkit require(a.glsl)"})


def test_the_pages_colours_are_brdfkits():
    """The Delta E view's colours are matplotlib's inferno as ``brdfkit compare`` draws it,
    the lobes' ``brdfkit plot``'s."""
    import matplotlib

    from brdfkit.figures.brdf_plot import COLOURS, THETA_O_DEG
    from brdfkit.view.page import _display_record, _lobe_record

    display, lobe = _display_record(), _lobe_record()
    lut = np.asarray(display["inferno"], np.uint8).reshape(-1, 4)
    assert np.array_equal(lut, matplotlib.colormaps["inferno"](np.arange(256), bytes=True))
    assert display["lines"] == list(COLOURS) and np.array_equal(lobe["theta_o"], THETA_O_DEG)
    assert lobe["uniforms"]["u_theta_o"] == [-89.5, 0.5]


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
    data = page_json(html)
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


def test_export_refuses_a_folder_that_holds_files_unless_forced(tmp_path, capsys, shipped_models):
    """Nothing of the user's is written over: a folder with a file in it is refused in
    one line before anything is written; with ``--force`` the export's files go in beside it."""
    from brdfkit.io.embedding import write_embedding

    write_embedding(tmp_path / "g.emb", projected_embedding(_glossy_table(), "merl80-l40", "basis", k=5))
    folder = tmp_path / "out"
    folder.mkdir()
    (folder / "README.md").write_text("mine")
    code, _, err = run_cli(capsys, ["export", tmp_path / "g.emb", "--glsl", folder])
    assert code == 2 and "holds files" in one_error_line(err) and "--force" in err
    assert [p.name for p in folder.iterdir()] == ["README.md"] and (folder / "README.md").read_text() == "mine"
    code, _, err = run_cli(capsys, ["export", tmp_path / "g.emb", "--glsl", folder, "--force"])
    assert code == 0, err
    doc = json.loads((folder / "material.json").read_text())
    assert doc["format"] == "brdfkit-glsl-material" and doc["version"] == 2 and doc["size"] == 15
    assert doc["defines"]["BRDFKIT_TEXTURES"] == 2 and len(doc["channels"]) == 3
    assert all((folder / t["file"]).stat().st_size == 180 * 90 * 90 * 16 for t in doc["textures"])
    readme = (folder / "README.md").read_text()
    assert "brdfkit_eval" in readme and "#define BRDFKIT_TAPS BRDFKIT_TAP(0) + BRDFKIT_TAP(1)" in readme
    code, _, err = run_cli(capsys, ["export", tmp_path / "g.emb", "--glsl", tmp_path / "new" / "deeper"])
    assert code == 0, err


def test_export_force_leaves_no_texture_of_an_earlier_larger_export(tmp_path, capsys, shipped_models):
    """``--force`` over an export of more components: its extra textures are removed (they
    would pass for part of the new export), the user's own files are kept."""
    from brdfkit.io.embedding import write_embedding

    for k in (9, 3):
        write_embedding(tmp_path / f"g{k}.emb", projected_embedding(_glossy_table(), "merl80-l40", "basis", k=k))
    folder = tmp_path / "out"
    assert run_cli(capsys, ["export", tmp_path / "g9.emb", "--glsl", folder])[0] == 0
    assert (folder / "brdfkit_basis2.bin").exists()
    (folder / "notes.txt").write_text("mine")
    code, _, err = run_cli(capsys, ["export", tmp_path / "g3.emb", "--glsl", folder, "--force"])
    assert code == 0, err
    doc = json.loads((folder / "material.json").read_text())
    bins = sorted(p.name for p in folder.glob("*.bin"))
    assert bins == [t["file"] for t in doc["textures"]] and "brdfkit_basis2.bin" not in bins
    assert (folder / "notes.txt").read_text() == "mine"


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
    data = page_json(html)
    half, scale = table_texture(read_bsdf_table(rgl))
    assert data["materials"][0]["scale"] == 1.0 / scale
    assert np.array_equal(np.frombuffer(blob_bytes(data["materials"][0]["table"]), np.float16), half.reshape(-1))
    assert data["samples"][0]["count"] == 1439
