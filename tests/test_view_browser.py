"""The page of ``brdfkit view`` in a real browser: headless Chromium (software WebGL) opens
it from disk at ``#still=N&size=256`` and its screenshots are compared with ``brdfkit
render``'s PNGs, on a diffuse, a glossy and a metallic material (teflon, blue metallic
paint, chrome steel: the NBRDF fits brdfkit ships, embedded in ``merl80-l40``'s basis, the
metallic one with its residual's correction):

* table mode against the render: PSNR >= 40 dB;
* the shader's own decode against table mode: PSNR >= 45 dB (``--live`` for the two basis
  embeddings, the page of ``brdfkit export --glsl`` for the residual one);

and the page of ``brdfkit view teflon.binary chrome-steel.emb`` opens, with its Delta E
2000 view, and the page's JavaScript makes the residual's hyponet weights. Skipped, with
the install advice, where Chromium is absent (``.ci/run`` installs it). Chromium's WebGL
runs on the CPU here, so a 256-pixel still takes seconds: one module fixture makes every
page and screenshot once (one residual bake, the costly decode on a CPU).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import run_cli_uncaptured
from helpers_view import display_u8, projected_embedding, psnr8

from brdfkit.view.browser import INSTALL_ADVICE, Browser, find_chromium, screenshot

pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(find_chromium() is None, reason=INSTALL_ADVICE)]

# (material, what it stands for, embedding kind)
MATERIALS = (("teflon", "diffuse", "basis"), ("blue-metallic-paint", "glossy", "basis"),
             ("chrome-steel", "metallic", "residual"))
SIZE = 256


def _renders(paths, size):
    """``brdfkit render PATH`` of each path at ``size`` pixels, linear, in one quadrature
    pass (each image that of the command, to the bit)."""
    from brdfkit.files.brdf_file import load_brdf
    from brdfkit.render.quadrature import render_many
    from brdfkit.render.scene import reference_scene

    return [img for img, _ in render_many([load_brdf(p, device="cpu") for p in paths], reference_scene(size))]


def _cli(*args):
    code, err = run_cli_uncaptured(args)
    assert code == 0, err
    return err


@pytest.fixture(scope="module")
def pictures(tmp_path_factory):
    from brdfkit.io.embedding import write_embedding
    from brdfkit.io.merl import write_merl
    from brdfkit.materials.nbrdf_networks import material_table
    from brdfkit.models.builtin import models_folder, read_manifest

    folder = tmp_path_factory.mktemp("view")
    with pytest.MonkeyPatch.context() as mp:
        mp.delenv("BRDFKIT_BUILTIN_MODELS", raising=False)
        if not read_manifest(models_folder()).installed():
            pytest.skip("no built-in model files in this checkout (brdfkit/models)")
        embs = []
        for name, _, kind in MATERIALS:
            table = material_table(name)
            if name == "teflon":
                write_merl(folder / "teflon.binary", table)  # what `brdfkit material teflon` writes
            embs.append(folder / f"{name}.emb")
            write_embedding(embs[-1], projected_embedding(table, "merl80-l40", kind))
        renders = [display_u8(img) for img in _renders(embs, SIZE)]  # the PNGs of brdfkit render --png
        _cli("view", *embs, "-o", folder / "table.html")
        _cli("view", *embs[:2], "--live", "-o", folder / "live.html")
        _cli("export", embs[2], "--glsl", folder / "export")
        _cli("view", folder / "teflon.binary", embs[2], "-o", folder / "p.html")
        small = _renders([folder / "teflon.binary", embs[2]], 64)
        shots = {}
        with Browser(SIZE) as b:
            for i in range(3):
                shots["table", i] = screenshot(folder / "table.html", f"still={i + 1}", SIZE, browser=b)
            for i in range(2):
                shots["live", i] = screenshot(folder / "live.html", f"still={i + 1}", SIZE, browser=b)
            shots["live", 2] = screenshot(folder / "export" / "view.html", "still=1", SIZE, browser=b)
            net = _page_hyponet(b)  # of the page just drawn
            shots["p", 0] = screenshot(folder / "p.html", "still=reference", 64, browser=b)
            shots["p", "difference"] = screenshot(folder / "p.html", "still=2&view=difference&scale=5", 64, browser=b)
    return {"folder": folder, "renders": renders, "small": small, "shots": shots, "net": net}


def _page_hyponet(b):
    """The red channel's hyponet weights the open page's JavaScript makes of its first
    material's numbers."""
    expr = ("(async () => { const v = window.brdfkitViewer, m = v.data.materials[0], b = v.data.live.bases[m.basis];"
            " const c = []; for (let j = 0; j < m.k; j++) c.push(m.coefficients[3 * j] / b.sigma[j]);"
            " return Array.from(await v.live.hyponet(m.net, c)); })()")
    return np.asarray(b.evaluate(expr, await_promise=True), np.float64)


@pytest.mark.parametrize("i", range(3), ids=[f"{m[1]}-{m[0]}" for m in MATERIALS])
def test_table_mode_renders_as_brdfkit_render(pictures, i):
    got, want = pictures["shots"]["table", i], pictures["renders"][i]
    assert got.shape == want.shape == (SIZE, SIZE, 3)
    assert want.max() > 60  # a lit sphere, not a black square
    assert psnr8(got, want) >= 40.0


@pytest.mark.parametrize("i", range(3), ids=[f"{m[1]}-{m[0]}-{m[2]}" for m in MATERIALS])
def test_live_and_export_render_as_table_mode(pictures, i):
    """The shader's own decode (``--live``; the residual one by ``brdfkit export``'s page)."""
    assert psnr8(pictures["shots"]["live", i], pictures["shots"]["table", i]) >= 45.0


def test_the_export_page_runs_the_exported_glsl(pictures):
    folder = pictures["folder"] / "export"
    html = (folder / "view.html").read_text()
    shaders = json.loads(html.split('<script id="brdfkit-shaders" type="application/json">')[1]
                         .split("</script>")[0])
    for name, f in (("eval", "brdfkit_eval.glsl"), ("decode", "brdfkit_decode.glsl"), ("bake", "brdfkit_bake.frag")):
        assert shaders[name] == (folder / f).read_text()
    doc = json.loads((folder / "material.json").read_text())
    assert doc["kind"] == "residual" and doc["size"] == 39 and len(doc["uniforms"]["brdfkit_net"]) == 3
    assert all((folder / t["file"]).stat().st_size == 180 * 90 * 90 * 16 for t in doc["textures"])
    assert "brdfkit_eval" in (folder / "README.md").read_text()


def test_the_pages_hypernetwork_is_the_residuals(pictures):
    """The hyponet weights the page's JavaScript makes of a material's numbers are those
    of the residual's NumPy forward pass (``brdfkit export`` writes those)."""
    from brdfkit.view.export import material_uniforms
    from brdfkit.view.inputs import read_inputs

    with pytest.MonkeyPatch.context() as mp:
        mp.delenv("BRDFKIT_BUILTIN_MODELS", raising=False)
        mat = read_inputs([pictures["folder"] / "chrome-steel.emb"], live=True)[0].live
    want = np.asarray(material_uniforms(mat)["uniforms"]["brdfkit_net"][0])
    got = pictures["net"]
    assert got.shape == want.shape and np.allclose(got, want, rtol=1e-4, atol=1e-5 * np.abs(want).max())


def test_the_page_of_a_table_and_an_embedding_opens_from_disk(pictures):
    """``brdfkit view teflon.binary chrome-steel.emb``: the reference, and chrome steel's
    Delta E 2000 against it in the colours and scale of ``brdfkit compare``."""
    from brdfkit.evaluation.metrics import delta_e_2000_map

    teflon, chrome = pictures["small"]
    assert psnr8(pictures["shots"]["p", 0], display_u8(teflon)) >= 40.0
    de = delta_e_2000_map(chrome, teflon)
    stops = np.array([[0.0015, 0.0005, 0.0139], [0.1293, 0.0473, 0.2908], [0.3415, 0.0623, 0.4294],
                      [0.5409, 0.1347, 0.4151], [0.7357, 0.2159, 0.3302], [0.8943, 0.3534, 0.1936],
                      [0.9784, 0.5579, 0.0349], [0.9746, 0.7977, 0.2063], [0.9884, 0.9984, 0.6449]])
    x = np.clip(de / 5.0, 0, 1) * 8
    i = np.minimum(np.floor(x).astype(int), 7)
    want = np.round(255 * (stops[i] + (x - i)[..., None] * (stops[i + 1] - stops[i]))).astype(np.uint8)
    assert psnr8(pictures["shots"]["p", "difference"], want) >= 30.0

