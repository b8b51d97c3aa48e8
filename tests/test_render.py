"""Reference-scene rendering: environment map, quadrature renderer, images, render and
metrics commands."""

from __future__ import annotations

import json
import math
import os
import re
import subprocess
import sys

import numpy as np
import pytest

from brdfkit.errors import FormatError, InputError
from conftest import run_here
from helpers_foundation import lambert_table

class _Analytic:
    """A synthetic material evaluated in closed form (no table): ground truth for the
    quadrature (a renderable BRDF with ``eval_dirs`` alone, evaluated at the pairs'
    directions)."""

    name = "analytic"

    def __init__(self, material):
        self.m = material

    def eval_dirs(self, wi, wo):
        from brdfkit.materials.synthetic import evaluate

        return evaluate(self.m, np.asarray(wi, np.float64), np.asarray(wo, np.float64)).astype(np.float32)


# -- environment map


def test_envmap_deterministic_and_featured():
    from brdfkit.render.envmap import SUN_RADIANCE, reference_envmap

    a = reference_envmap.__wrapped__()
    b = reference_envmap.__wrapped__()
    assert a.image.dtype == np.float32 and a.image.shape == (128, 256, 3)
    assert np.array_equal(a.image, b.image) and a.digest() == b.digest()
    img = a.image
    assert img.max() == pytest.approx(SUN_RADIANCE, rel=1e-6)  # the sun's centre texel
    assert (img[0] == img[0, 0]).all() and (img[-1] == img[-1, 0]).all()  # constant poles
    sky, ground = img[20].mean(0), img[110].mean(0)
    assert sky[2] > sky[0] and ground[0] > ground[2]  # blue sky, brown ground
    assert (img > 2.0).sum() > 100  # the window
    assert len(a.bright) == 2


def test_envmap_lookup_hits_texels():
    from brdfkit.render.envmap import reference_envmap, uv_to_direction

    env = reference_envmap()
    h, w = env.shape
    rng = np.random.default_rng(0)
    i, j = rng.integers(1, h - 1, 200), rng.integers(0, w, 200)
    d = uv_to_direction((j + 0.5) / w, i / (h - 1))
    got = env.radiance(d)
    np.testing.assert_allclose(got, env.image[i, j], rtol=1e-5, atol=1e-6)


def test_envmap_exr_cached(tmp_path):
    from brdfkit.render.envmap import reference_envmap
    from brdfkit.render.image import read_exr

    env = reference_envmap()
    p = env.exr_path(tmp_path)
    assert p == env.exr_path(tmp_path)
    assert np.array_equal(read_exr(p), env.image)


# -- quadrature


def test_lambert_uniform_environment_closed_form():
    from brdfkit.render import quadrature
    from brdfkit.render.renderable import TableBRDF
    from brdfkit.render.envmap import uniform_envmap
    from brdfkit.render.scene import Scene

    albedo = np.array([0.2, 0.5, 0.8])
    radiance = np.array([1.5, 1.0, 0.5])
    stats = quadrature.RenderStats()
    img, mask = quadrature.render(TableBRDF(lambert_table(albedo), device="cpu"), Scene(resolution=16),
                                  env=uniform_envmap(radiance), stats=stats)
    assert mask.sum() > 100 and (img[~mask] == 0).all()
    np.testing.assert_allclose(img[mask], np.broadcast_to(albedo * radiance, img[mask].shape), rtol=1e-3)
    lo, hi = stats.scale_range
    assert 0.97 < lo <= hi < 1.06  # the normalisation is a small correction, not a fix-up


def _albedo_reference(material, theta_o, n=500):
    """Directional albedo by a fine midpoint rule in half-vector space (independent of
    the renderer's nodes and weights)."""
    from brdfkit.materials.synthetic import evaluate

    wo = np.array([math.sin(theta_o), 0.0, math.cos(theta_o)])
    t = (np.arange(n) + 0.5) / n
    th = (math.pi / 2) * t ** 3
    dth = (math.pi / 2) * 3 * t ** 2 / n
    ph = (np.arange(2 * n) + 0.5) / (2 * n) * 2 * math.pi
    st = np.sin(th)[:, None]
    h = np.stack([st * np.cos(ph), st * np.sin(ph), np.broadcast_to(np.cos(th)[:, None], (n, 2 * n))], -1)
    woh = h @ wo
    wi = 2 * woh[..., None] * h - wo
    ok = (woh > 0) & (wi[..., 2] > 0)
    f = evaluate(material, wi, np.broadcast_to(wo, wi.shape))
    g = np.where(ok[..., None], f * wi[..., 2:3] * 4 * woh[..., None], 0.0)
    return (g * (st * dth[:, None])[..., None]).sum((0, 1)) * (2 * math.pi / (2 * n))


@pytest.mark.parametrize("which", ["glossy", "mirror"])
def test_quadrature_matches_independent_integral(which):
    """Glossy and near-mirror GGX under a uniform environment: the rendered radiance is the
    directional albedo, computed here by a separate fine integration."""
    from brdfkit.materials import synthetic
    from brdfkit.render import quadrature
    from brdfkit.render.envmap import uniform_envmap

    mat = synthetic.STIFF[0] if which == "mirror" else \
        synthetic.Material("glossy", "dielectric", 0.1, albedo=(0.3, 0.2, 0.1))
    angles = np.array([0.0, 0.5, 1.0])
    normals = np.stack([np.sin(angles), np.zeros(3), np.cos(angles)], -1)
    got = quadrature.render_pixels(_Analytic(mat), normals, uniform_envmap())
    ref = np.stack([_albedo_reference(mat, a) for a in angles])
    np.testing.assert_allclose(got, ref, rtol=0.01)


def test_quadrature_deterministic_and_mirror_finite():
    from brdfkit.materials import synthetic
    from brdfkit.render import quadrature
    from brdfkit.render.renderable import TableBRDF
    from brdfkit.render.scene import Scene

    brdf = TableBRDF(synthetic.table(synthetic.STIFF[0]), "stiff-mirror", device="cpu")
    stats = quadrature.RenderStats()
    a, mask = quadrature.render(brdf, Scene(resolution=12), stats=stats)
    b, _ = quadrature.render(brdf, Scene(resolution=12))
    assert np.array_equal(a, b)
    assert np.isfinite(a).all() and (a >= 0).all()
    assert a[mask].max() > 1.0  # the sun's reflection
    assert stats.evaluations > 0


def test_supersampling_averages_points():
    from brdfkit.render.scene import Scene

    n1, m1 = Scene(resolution=8).pixel_normals()
    n3, m3 = Scene(resolution=8, supersample=3).pixel_normals()
    assert n1.shape == (8, 8, 1, 3) and n3.shape == (8, 8, 9, 3)
    np.testing.assert_allclose(n3[:, :, 4], n1[:, :, 0])  # the middle point is the centre
    np.testing.assert_allclose(np.linalg.norm(n3[m3], axis=-1), 1.0)
    assert m3.any(2).sum() >= m1[..., 0].sum()


# -- images


def test_exr_round_trip_and_png(tmp_path):
    from PIL import Image

    from brdfkit.render.image import read_exr, write_exr, write_png

    rng = np.random.default_rng(1)
    img = rng.uniform(0, 5, (7, 9, 3)).astype(np.float32)
    write_exr(tmp_path / "a.exr", img)
    assert np.array_equal(read_exr(tmp_path / "a.exr"), img)
    write_png(tmp_path / "a.png", img)
    png = np.asarray(Image.open(tmp_path / "a.png"))
    assert png.shape == (7, 9, 3) and png.dtype == np.uint8
    from brdfkit.render.display import display_encode

    np.testing.assert_array_equal(png, np.round(display_encode(img) * 255).astype(np.uint8))
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".brdfkit-tmp")]


def test_bad_images(tmp_path):
    from brdfkit.render.image import read_exr, write_exr

    (tmp_path / "fake.exr").write_text("not an image")
    with pytest.raises(FormatError, match="not an OpenEXR"):
        read_exr(tmp_path / "fake.exr")
    write_exr(tmp_path / "ok.exr", np.ones((4, 4, 3)))
    data = (tmp_path / "ok.exr").read_bytes()
    (tmp_path / "cut.exr").write_bytes(data[: len(data) // 2])
    with pytest.raises(FormatError):
        read_exr(tmp_path / "cut.exr")
    with pytest.raises(InputError, match="no such file"):
        read_exr(tmp_path / "missing.exr")
    with pytest.raises(InputError, match="NaN"):
        write_exr(tmp_path / "nan.exr", np.full((2, 2, 3), np.nan))


def test_render_package_is_lazy():
    code = ("import sys, brdfkit.render, brdfkit.evaluation.metrics; "
            "print(any(m in sys.modules for m in ('torch', 'mitsuba', 'colour')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


# -- commands


@pytest.fixture(scope="module")
def lambert_file(tmp_path_factory):
    from brdfkit.io.merl import write_merl

    folder = tmp_path_factory.mktemp("brdfs")
    write_merl(folder / "lambert.binary", lambert_table([0.6, 0.5, 0.4]))
    return folder / "lambert.binary"


@pytest.mark.slow
def test_cli_render_and_metrics(lambert_file, tmp_path, capsys):
    from brdfkit.render.image import read_exr

    exr, png = tmp_path / "a.exr", tmp_path / "a.png"
    r = run_here(capsys, ["render", lambert_file, "-o", exr, "--png", png, "--resolution", 16, "--quiet"])
    assert r.returncode == 0, r.stderr
    img = read_exr(exr)
    assert img.shape == (16, 16, 3) and png.stat().st_size > 0
    centre = img[7:9, 7:9].mean((0, 1))
    assert (centre > 0.05).all() and centre[0] > centre[2]  # albedo 0.6, 0.5, 0.4

    r = run_here(capsys, ["metrics", "--ref", exr, exr, "--json"])
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout) == {"psnr": 100.0, "delta_e": 0.0, "ssim": 1.0, "brdf_log_rmse": None}

    # a BRDF file against its own render: rendered at the image's size, identical
    r = run_here(capsys, ["metrics", "--ref", exr, lambert_file, "--json"])
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["psnr"] == 100.0


@pytest.mark.slow
def test_cli_metrics_folders(lambert_file, tmp_path, capsys):
    from brdfkit.render.image import write_exr

    a, b = tmp_path / "pred", tmp_path / "ref"
    a.mkdir()
    b.mkdir()
    rng = np.random.default_rng(2)
    ref1, ref2 = rng.uniform(0, 1, (16, 16, 3)), rng.uniform(0, 1, (16, 16, 3))
    write_exr(b / "m1.exr", ref1)
    write_exr(b / "m2.exr", ref2)
    write_exr(a / "m1.exr", ref1)
    write_exr(a / "m2.exr", ref2 * 0.8)
    write_exr(a / "only-here.exr", ref2)
    (b / "lambert.binary").symlink_to(lambert_file)
    (a / "lambert.binary").symlink_to(lambert_file)
    r = run_here(capsys, ["metrics", "--ref", b, a, "--json", "--resolution", 16])
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert set(out["materials"]) == {"m1", "m2", "lambert"}
    assert out["materials"]["m1"]["psnr"] == 100.0
    assert out["materials"]["lambert"]["brdf_log_rmse"] == 0.0
    assert out["materials"]["m2"]["brdf_log_rmse"] is None
    assert out["materials"]["m2"]["psnr"] < 40 and out["materials"]["m2"]["delta_e"] > 0.5
    psnrs = [v["psnr"] for v in out["materials"].values()]
    assert out["mean"]["psnr"] == pytest.approx(sum(psnrs) / 3)
    assert out["mean"]["brdf_log_rmse"] == 0.0
    assert "only-here" in r.stderr
    r = run_here(capsys, ["metrics", "--ref", b, a, "--resolution", 16])  # the table
    assert r.returncode == 0 and "mean" in r.stdout and "m2" in r.stdout


def test_cli_bad_inputs(lambert_file, tmp_path, capsys):
    (tmp_path / "fake.exr").write_text("hello")
    (tmp_path / "x.txt").write_text("hello")
    cases = [
        (["render", tmp_path / "missing.binary", "-o", tmp_path / "o.exr"], "no such file"),
        (["render", tmp_path / "x.txt", "-o", tmp_path / "o.exr"], "not a BRDF file"),
        (["render", lambert_file, "-o", tmp_path / "o.png"], ".exr"),
        (["render", lambert_file, "-o", lambert_file], "refusing to overwrite"),
        (["render", lambert_file, "-o", tmp_path / "o.exr", "--scene", tmp_path / "x.txt"], "--bsdf-id"),
        (["metrics", "--ref", tmp_path / "fake.exr", tmp_path / "fake.exr"], "not an OpenEXR"),
        (["metrics", "--ref", tmp_path / "fake.exr", tmp_path / "missing.exr"], "no such file"),
        (["metrics", "--ref", tmp_path / "x.txt", tmp_path / "x.txt"], "not a BRDF"),
        (["metrics", "--ref", tmp_path / "fake.exr", tmp_path], "folder"),
    ]
    for args, needle in cases:
        r = run_here(capsys, args)
        assert r.returncode == 2, (args, r.stderr)
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and needle in lines[0], (args, r.stderr)
        assert "Traceback" not in r.stderr
    r = run_here(capsys, ["metrics"])
    assert r.returncode == 2 and "--ref REF PRED" in r.stderr and "--json" in r.stderr


@pytest.mark.parametrize("paths, ref, pred", [
    (["x.emb", "r.binary"], "r.binary", "x.emb"),  # an embedding is the prediction, in either order
    (["r.bsdf", "x.emb"], "r.bsdf", "x.emb"),
    (["p.binary", "s.csv"], "s.csv", "p.binary"),  # a sample file is the reference, in either order
    (["m.BRDF", "p.emb"], "m.BRDF", "p.emb"),
])
def test_metrics_roles_told_by_the_kinds(paths, ref, pred):
    from brdfkit.cli.metrics import roles

    assert roles(paths, None) == (pred, ref)
    assert roles(list(reversed(paths)), None) == (pred, ref)
    assert roles([pred], ref) == (pred, ref)


@pytest.mark.parametrize("paths, ref, message", [
    (["a.binary", "b.binary"], None, "which one is the reference? name it: brdfkit metrics --ref REF PRED"),
    (["a.exr", "b.binary"], None, "which one is the reference?"),
    (["a.emb", "b.emb"], None, "which one is the reference?"),
    (["a.csv", "b.brdf"], None, "two sample files; PRED must be a BRDF file"),
    (["a.binary", "b.binary"], "r.binary", "metrics --ref r.binary: give one PRED"),
    (["a.binary"], None, "expected --ref REF PRED, got 1 path(s)"),
])
def test_metrics_roles_of_one_kind_need_ref(paths, ref, message):
    """Two inputs of one kind could be either way round: ``metrics`` took ``PRED REF`` and
    ``compare`` takes ``REF PRED``, so the old order is refused, not read the other way."""
    from brdfkit.cli.metrics import roles

    with pytest.raises(InputError, match=re.escape(message)):
        roles(paths, ref)


@pytest.mark.slow
def test_metrics_ref_and_compare_ref_in_process(tmp_path, capsys):
    """``metrics --ref REF PRED`` and ``compare --ref REF PRED...`` (= ``compare REF
    PRED...``) score the same; two images without ``--ref`` are one line, exit 2."""
    from brdfkit.render.image import write_exr
    from conftest import one_error_line, run_cli

    rng = np.random.default_rng(5)
    ref, pred = tmp_path / "ref.exr", tmp_path / "pred.exr"
    write_exr(ref, rng.uniform(0, 1, (16, 16, 3)).astype(np.float32))
    write_exr(pred, rng.uniform(0, 1, (16, 16, 3)).astype(np.float32))
    code, out, err = run_cli(capsys, ["metrics", "--ref", ref, pred, "--json"])
    assert code == 0, err
    scores = json.loads(out)
    sheets = []
    for args in (["--ref", ref, pred], [ref, pred]):
        code, out, err = run_cli(capsys, ["compare", *args, "-o", tmp_path / "s.png", "--json"])
        assert code == 0, err
        sheets.append(json.loads(out))
    assert sheets[0] == sheets[1] and sheets[0]["reference"] == str(ref)
    assert sheets[0]["predictions"]["pred"] == scores  # the same score function
    code, _, err = run_cli(capsys, ["metrics", pred, ref, "--json"])
    assert code == 2 and "which one is the reference" in one_error_line(err)
    code, _, err = run_cli(capsys, ["compare", ref, "-o", tmp_path / "t.png"])
    assert code == 2 and "no prediction" in one_error_line(err) and not (tmp_path / "t.png").exists()


@pytest.mark.slow
def test_cli_render_embedding(tmp_path, capsys):
    """An .emb with its model renders through NeuralBRDF.eval_dirs (no dense table)."""
    from helpers_model import make_model, material_table

    from brdfkit.api import encode, load_model
    from brdfkit.io.embedding import write_embedding
    from brdfkit.hypernet.neural_brdf import NeuralBRDF
    from brdfkit.render import quadrature
    from brdfkit.render.image import read_exr
    from brdfkit.render.scene import Scene

    make_model(tmp_path / "m.safetensors")
    model = load_model(tmp_path / "m.safetensors", device="cpu")
    emb = encode(material_table(0), model)
    write_embedding(tmp_path / "w.emb", emb)
    r = run_here(capsys, ["render", tmp_path / "w.emb", "-m", tmp_path / "m.safetensors", "-o", tmp_path / "w.exr",
                     "--resolution", 12, "--quiet"])
    assert r.returncode == 0, r.stderr
    img = read_exr(tmp_path / "w.exr")
    expected, _ = quadrature.render(NeuralBRDF.from_embedding(model, emb), Scene(resolution=12))
    np.testing.assert_allclose(img, expected, rtol=1e-4, atol=1e-6)
    assert np.isfinite(img).all() and img.max() > 0
    r = run_here(capsys, ["render", tmp_path / "w.emb", "-o", tmp_path / "x.exr"])  # no $BRDFKIT_MODEL (conftest)
    assert r.returncode == 2 and "model" in r.stderr


def test_sun_coverage_rows_only_are_the_full_coverage():
    """The sun's texel coverage evaluated on the rows near it only (a start-up cost of
    every render) equals the one over all rows, to the bit."""
    import math

    from brdfkit.render import envmap

    s = envmap.uv_to_direction(*envmap.SUN_UV)
    cos_r = math.cos(math.radians(envmap.SUN_RADIUS_DEG))
    disc = lambda uu, vv: (envmap.uv_to_direction(uu, vv) @ s >= cos_r).astype(np.float64)  # noqa: E731
    r_v = math.radians(envmap.SUN_RADIUS_DEG) / math.pi
    full = envmap._texel_coverage(256, 128, disc)
    rows = envmap._texel_coverage(256, 128, disc, v_range=(envmap.SUN_UV[1] - r_v, envmap.SUN_UV[1] + r_v))
    assert full.sum() > 0
    np.testing.assert_array_equal(rows, full)
