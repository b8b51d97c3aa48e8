"""The Mitsuba 3 ``brdfkit`` BSDF plugin: XML and dict scenes, agreement with the
quadrature renderer, near-mirror materials, the --mitsuba and --scene commands.

Tests that render need Mitsuba's LLVM backend with libLLVM 19 and skip, saying so, where
it is missing (CI installs ``libllvm19``)."""

from __future__ import annotations

import math
import os

import numpy as np
import pytest

from brdfkit.errors import BrdfkitError
from conftest import run_here
from helpers_foundation import lambert_table

torch = pytest.importorskip("torch")


def test_missing_libllvm_is_a_clear_error(monkeypatch):
    from brdfkit.render.mitsuba3 import loader as mp

    monkeypatch.setenv("DRJIT_LIBLLVM_PATH", "/nonexistent/libLLVM.so")
    with pytest.raises(BrdfkitError, match="apt-get install -y libllvm19"):
        mp.ensure_libllvm()
    monkeypatch.delenv("DRJIT_LIBLLVM_PATH")
    monkeypatch.setattr(mp, "LIBLLVM_CANDIDATES", ())
    monkeypatch.setattr(mp.glob, "glob", lambda pattern: [])
    with pytest.raises(BrdfkitError, match="apt-get install -y libllvm19"):
        mp.ensure_libllvm()
    assert "DRJIT_LIBLLVM_PATH" not in os.environ


@pytest.fixture(scope="module")
def mi():
    from brdfkit.render.mitsuba3 import loader as mp

    try:
        mp.ensure_libllvm()
    except BrdfkitError as e:
        pytest.skip(f"Mitsuba's LLVM backend unavailable: {e}")
    mod, _ = mp.load_mitsuba()
    old = torch.get_num_threads()
    torch.set_num_threads(1)
    yield mod
    torch.set_num_threads(old)


@pytest.fixture(scope="module")
def lambert_file(tmp_path_factory):
    from brdfkit.io.merl import write_merl

    folder = tmp_path_factory.mktemp("mitsuba")
    write_merl(folder / "lambert.binary", lambert_table([0.6, 0.5, 0.4]))
    return folder / "lambert.binary"


def _furnace_xml(bsdf: str, res: int = 16, spp: int = 64) -> str:
    return f"""<scene version="3.0.0">
  <integrator type="path"><integer name="max_depth" value="2"/><boolean name="hide_emitters" value="true"/></integrator>
  <sensor type="orthographic">
    <transform name="to_world"><scale x="1.1" y="1.1"/><lookat origin="0, 0, 10" target="0, 0, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="{res}"/><integer name="height" value="{res}"/>
      <rfilter type="box"/><string name="pixel_format" value="rgb"/></film>
    <sampler type="independent"><integer name="sample_count" value="{spp}"/></sampler>
  </sensor>
  <emitter type="constant"><rgb name="radiance" value="1.0, 1.0, 1.0"/></emitter>
  <shape type="sphere">{bsdf}</shape>
</scene>"""


def _centre(img):
    n = img.shape[0]
    return img[n // 4: 3 * n // 4, n // 4: 3 * n // 4].reshape(-1, 3)


def test_plugin_from_xml_string(mi, lambert_file):
    import brdfkit.files.brdf_file  # noqa: F401  registers the plugin's file opener (docs/render.md)
    from brdfkit.render.mitsuba3.scenes import render_scene

    xml = _furnace_xml(f'<bsdf type="brdfkit"><string name="filename" value="{lambert_file}"/></bsdf>')
    img = render_scene(mi.load_string(xml), 64)
    # Lambertian under a white furnace: radiance = albedo everywhere on the sphere.
    np.testing.assert_allclose(_centre(img).mean(0), [0.6, 0.5, 0.4], rtol=0.02)
    assert (img[0, 0] == 0).all()  # background: emitter hidden


def test_plugin_from_dict_with_registered_source(mi):
    from brdfkit.render.renderable import TableBRDF
    from brdfkit.render.mitsuba3.scenes import render_scene
    from brdfkit.render.mitsuba3.bsdf import register_source

    key = register_source(TableBRDF(lambert_table([0.3, 0.3, 0.9]), device="cpu"))
    scene = mi.load_string(_furnace_xml(f'<bsdf type="brdfkit"><string name="source" value="{key}"/></bsdf>'))
    d = {"type": "scene", "integrator": {"type": "path", "max_depth": 2, "hide_emitters": True},
         "sensor": {"type": "orthographic",
                    "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 10], target=[0, 0, 0], up=[0, 1, 0])
                    @ mi.ScalarTransform4f().scale([1.1, 1.1, 1]),
                    "film": {"type": "hdrfilm", "width": 16, "height": 16, "rfilter": {"type": "box"}},
                    "sampler": {"type": "independent", "sample_count": 64}},
         "emitter": {"type": "constant"},
         "sphere": {"type": "sphere", "bsdf": {"type": "brdfkit", "source": key}}}
    a = render_scene(mi.load_dict(d), 64)
    b = render_scene(scene, 64)
    np.testing.assert_allclose(_centre(a).mean(0), [0.3, 0.3, 0.9], rtol=0.02)
    np.testing.assert_allclose(_centre(a).mean(0), _centre(b).mean(0), rtol=0.02)


@pytest.mark.slow
def test_quadrature_agrees_with_mitsuba(mi):
    """The reference scene by both renderers, a glossy copper table: the quadrature image
    lies within Monte Carlo noise of the path-traced one."""
    import dataclasses

    from brdfkit.materials import synthetic
    from brdfkit.render import quadrature
    from brdfkit.render.renderable import TableBRDF
    from brdfkit.render.mitsuba3.scenes import render_reference
    from brdfkit.render.scene import Scene

    mat = synthetic.Material("copper", "conductor", 0.08, ior=synthetic.METALS["copper"][0],
                             k=synthetic.METALS["copper"][1])
    brdf = TableBRDF(synthetic.table(mat), "copper", device="cpu")
    scene = Scene(resolution=20)
    passes = np.stack([render_reference(brdf, scene, spp=32, seed=1000 * i) for i in range(8)])
    mean = passes.mean(0)
    sigma = passes.std(0, ddof=1) / math.sqrt(len(passes))
    quad, _ = quadrature.render(brdf, dataclasses.replace(scene, supersample=3))
    _, inside = dataclasses.replace(scene, supersample=3).pixel_normals()
    interior = inside.all(2)  # pixels wholly on the sphere (no silhouette coverage)
    assert interior.sum() > 150
    assert quad[interior].mean() == pytest.approx(mean[interior].mean(), rel=0.02)
    z = np.abs(quad - mean)[interior] / (sigma[interior] + 1e-3 * mean[interior] + 1e-6)
    assert np.mean(z < 4) > 0.97, np.sort(z.ravel())[-10:]
    for img in (quad, mean):  # background black (emitters hidden)
        assert (img[[0, 0, -1, -1], [0, -1, 0, -1]] == 0).all()


def test_near_mirror_renders_finite(mi):
    from brdfkit.materials import synthetic
    from brdfkit.render.renderable import TableBRDF
    from brdfkit.render.mitsuba3.scenes import render_reference
    from brdfkit.render.mitsuba3.bsdf import estimate_alpha
    from brdfkit.render.scene import Scene

    brdf = TableBRDF(synthetic.table(synthetic.STIFF[0]), "stiff-mirror", device="cpu")
    assert 0.002 <= estimate_alpha(brdf) < 0.02
    img = render_reference(brdf, Scene(resolution=16), spp=32)
    assert np.isfinite(img).all() and (img >= 0).all() and img.max() > 0.1


@pytest.mark.slow
def test_neural_brdf_in_mitsuba(mi, tmp_path):
    from helpers_model import make_model, material_table

    from brdfkit.api import encode, load_model
    from brdfkit.hypernet.neural_brdf import NeuralBRDF
    from brdfkit.render.mitsuba3.scenes import render_reference
    from brdfkit.render.scene import Scene

    make_model(tmp_path / "m.safetensors")
    model = load_model(tmp_path / "m.safetensors", device="cpu")
    brdf = NeuralBRDF.from_embedding(model, encode(material_table(0), model))
    img = render_reference(brdf, Scene(resolution=12), spp=8)
    assert np.isfinite(img).all() and img.max() > 0


def test_cli_mitsuba_and_user_scene(mi, lambert_file, tmp_path, capsys):
    from brdfkit.render.image import read_exr

    r = run_here(capsys, ["render", lambert_file, "--mitsuba", "--spp", 8, "--resolution", 16,
                     "-o", tmp_path / "a.exr", "--quiet"])
    assert r.returncode == 0, r.stderr
    assert read_exr(tmp_path / "a.exr").shape == (16, 16, 3)

    scene = tmp_path / "scene.xml"
    scene.write_text(_furnace_xml('<bsdf type="diffuse" id="mat"><rgb name="reflectance" value="0.1"/></bsdf>',
                                  res=32, spp=4))
    r = run_here(capsys, ["render", lambert_file, "--scene", scene, "--bsdf-id", "mat", "--spp", 32,
                     "--resolution", 16, "-o", tmp_path / "b.exr", "--quiet"])
    assert r.returncode == 0, r.stderr
    img = read_exr(tmp_path / "b.exr")
    assert img.shape == (16, 16, 3)
    np.testing.assert_allclose(_centre(img).mean(0), [0.6, 0.5, 0.4], rtol=0.05)  # ours, not 0.1

    r = run_here(capsys, ["render", lambert_file, "--scene", scene, "--bsdf-id", "nope", "-o", tmp_path / "c.exr"])
    assert r.returncode == 2 and "no <bsdf id=\"nope\">" in r.stderr and "mat" in r.stderr
    (tmp_path / "bad.xml").write_text("<scene><oops></scene>")
    r = run_here(capsys, ["render", lambert_file, "--scene", tmp_path / "bad.xml", "--bsdf-id", "mat",
                     "-o", tmp_path / "c.exr"])
    assert r.returncode == 2 and "not a Mitsuba XML scene" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1
