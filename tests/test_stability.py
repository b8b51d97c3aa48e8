"""Numerical stability on stiff materials and extreme inputs (issue 6, docs/notes/stability.md).

Stiff materials are built with :class:`brdfkit.materials.synthetic.Material`: a silver GGX mirror
with ``alpha = 0.002`` (values up to 6.5e7 1/sr) and a black Lambertian (albedo 1e-3,
3.2e-4 1/sr everywhere). Every path a user runs on them (fit, encode, decode, sparse,
interpolate, metrics; render in ``test_render``-style checks where the renderer is
installed) must stay finite, and decoded values non-negative. Extreme inputs: grazing and
normal directions, ``phi_d`` at 0 and pi, one sample, all samples in one direction,
duplicated samples, a million samples.
"""

from __future__ import annotations

import math
import time
import tracemalloc

import numpy as np
import pytest
import torch

from brdfkit import api
from brdfkit.materials import synthetic
from brdfkit.io.embedding import Embedding
from brdfkit.errors import InputError
from brdfkit.geometry import hd_vectors
from brdfkit.hypernet.mapping import RHO_MAX, from_mapped, to_mapped
from brdfkit.evaluation.metrics import brdf_log_rmse
from brdfkit.geometry import grid_hd
from brdfkit.hypernet.neural_brdf import NeuralBRDF
from brdfkit.io.samples import SampleSet
from brdfkit.acquisition.sampling import draw_samples

from helpers_model import make_model

MIRROR = synthetic.Material("mirror-0.002", "conductor", 0.002, ior=synthetic.METALS["silver"][0],
                            k=synthetic.METALS["silver"][1])
BLACK = synthetic.Material("black-0.001", "dielectric", 0.3, albedo=(1e-3, 1e-3, 1e-3), ks=0.0)
HALF_PI = math.pi / 2


@pytest.fixture(scope="module")
def stiff():
    """``{"mirror": table, "black": table, "white": table}`` (read-only)."""
    out = {"mirror": synthetic.table(MIRROR), "black": synthetic.table(BLACK),
           "white": synthetic.table(synthetic.STIFF[2])}
    for t in out.values():
        t.setflags(write=False)
    return out


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    """An untrained tiny model; its reference table is the stiff white material, so the
    mirror maps to ~19 and the black to ~1e-3 (the far ends of the mapping)."""
    path = tmp_path_factory.mktemp("stab-model") / "model.safetensors"
    make_model(path)
    return api.load_model(path, "cpu")


def _finite_where_measured(table, rho_ref):
    measured = np.isfinite(rho_ref).all(-1)
    v = table[measured]
    return bool(np.isfinite(v).all() and (v >= 0).all() and np.isnan(table[~measured]).all())


# --- the stiff tables and the mapping ---------------------------------------------------

def test_stiff_tables_are_stiff(stiff):
    m, b = stiff["mirror"], stiff["black"]
    assert np.nanmax(m) > 1e7 and np.nanmin(m) < 1e-5  # peak and off-peak 12 decades apart
    assert np.nanmax(b) < 1e-3 and np.nanmin(b) > 0


@pytest.mark.parametrize("ref_kind", ["white", "mirror", "zero", "bright"])
def test_mapping_round_trip_on_stiff_tables(stiff, ref_kind):
    ref = {"white": stiff["white"], "mirror": stiff["mirror"], "zero": 0.0, "bright": 1e4}[ref_kind]
    for name in ("mirror", "black"):
        t = stiff[name]
        mapped = to_mapped(t, ref)
        assert np.isfinite(mapped[np.isfinite(t)]).all()
        back = from_mapped(mapped, ref, floor=0)  # the exact inverse; the default's bound: test_mapping
        big = np.isfinite(t) & (t > 1e-6)
        rel = np.abs(back[big] - t[big]) / t[big]
        assert rel.max() <= 1e-6, (name, rel.max())


def test_from_mapped_stays_finite_in_float32():
    # Regression: an extrapolated embedding (interpolate t = -10) made the hyponet predict
    # mapped values past 88.7, where expm1 overflows float32: decode gave infinity.
    mapped = torch.tensor([1e3, 89.0, float("inf"), -float("inf"), float("nan"), 5.0])  # float32
    out = from_mapped(mapped, torch.full((6,), 1e8))
    assert torch.isfinite(out[[0, 1, 2, 3, 5]]).all() and torch.isnan(out[4])
    assert out[0] == out[2] == RHO_MAX and 0 < out[3] <= 2e-5  # -inf: the lower bound, never 0
    assert from_mapped(mapped, torch.full((6,), 1e8), floor=0)[3] == 0
    # everything up to RHO_MAX still round-trips (the exact inverse; above its bound, the default)
    rho = np.array([0.0, 1e-6, 1.0, 6.5e7, 1e9, RHO_MAX])
    for ref in (0.0, 0.3, 1e4):
        np.testing.assert_allclose(from_mapped(to_mapped(rho, ref), ref, floor=0), rho, rtol=1e-6, atol=1e-12)
        np.testing.assert_allclose(from_mapped(to_mapped(rho, ref), ref)[2:], rho[2:], rtol=1e-6)


# --- training on stiff materials, and the trained model on them -------------------------

FIT_STEPS = 300


@pytest.fixture(scope="module")
def trained(stiff, tmp_path_factory):
    """A tiny hypernetwork trained on the mirror, the black and the white material, every
    batch holding all three (``conftest.TINY``; ~15 s on one core)."""
    from brdfkit.io.merl import write_merl
    from brdfkit.hypernet.training.loop import fit

    from conftest import TINY, TINY_LATENT

    folder = tmp_path_factory.mktemp("stab-fit")
    for name, table in stiff.items():
        write_merl(folder / f"{name}.binary", table)
    out = folder / "model.safetensors"
    fit(folder, out, latent_dim=TINY_LATENT, steps=FIT_STEPS, progress=False,
        **{**TINY, "batch_materials": 3})
    return api.load_model(out, "cpu"), folder


@pytest.mark.slow
def test_fit_on_mirror_black_and_white_stays_finite(trained):
    model, _ = trained
    assert model.meta["materials"] == ["black", "mirror", "white"]
    assert model.meta["steps"] == FIT_STEPS
    # no step was skipped for a non-finite loss or gradient, and none had to be
    assert model.meta["skipped_steps"] == 0
    for name, p in model.net.named_parameters():
        assert torch.isfinite(p).all(), name
    assert math.isfinite(model.meta["final_loss"]) and model.meta["final_mapped_mse"] < 1.0


@pytest.mark.slow
@pytest.mark.parametrize("name", ["mirror", "black"])
def test_encode_decode_sparse_metrics_on_stiff(trained, stiff, name):
    model, folder = trained
    emb = api.encode(folder / f"{name}.binary", model)  # dense: every measured cell
    assert np.isfinite(emb.values).all()
    dec = api.decode(emb, model)
    assert _finite_where_measured(dec, model.rho_ref)
    assert math.isfinite(brdf_log_rmse(dec, stiff[name]))
    rec, emb2 = api.sparse(draw_samples(stiff[name], 40, seed=1), model, refine_target="latent")
    assert np.isfinite(emb2.values).all() and _finite_where_measured(rec, model.rho_ref)
    assert math.isfinite(brdf_log_rmse(rec, stiff[name]))


@pytest.mark.slow
def test_interpolation_and_extrapolation_stay_finite(trained, stiff):
    model, _ = trained
    a = api.encode(draw_samples(stiff["mirror"], 400, seed=4), model, source="mirror")
    b = api.encode(draw_samples(stiff["black"], 400, seed=4), model, source="black")
    probe = torch.from_numpy(np.ascontiguousarray(grid_hd()[::97]))
    peak = {}
    for t in (-1000.0, -10.0, -3.0, 0.5, 3.0, 10.0, 1000.0):
        mix = api.interpolate(a, b, t, allow_extrapolation=True)
        nb = NeuralBRDF.from_embedding(model, mix)
        with torch.no_grad():
            peak[t] = float(nb.mapped(probe).abs().max())
        table = nb.to_table()
        assert _finite_where_measured(table, model.rho_ref), t
        assert np.nanmax(table) <= RHO_MAX
    # far out the hyponet predicts mapped values past 88.7, where expm1 overflows float32:
    # without from_mapped's clamp these tables held infinity (docs/notes/stability.md)
    assert max(peak[-1000.0], peak[1000.0]) > 88.8, peak


@pytest.mark.slow
def test_extrapolation_through_the_cli(trained, tmp_path, capsys):
    from brdfkit.cli import main
    from brdfkit.io.embedding import write_embedding
    from brdfkit.io.merl import read_merl

    model, folder = trained
    write_embedding(tmp_path / "a.emb", api.encode(folder / "mirror.binary", model))
    write_embedding(tmp_path / "b.emb", api.encode(folder / "black.binary", model))
    with pytest.raises(SystemExit) as e:
        main([str(x) for x in ["interpolate", tmp_path / "a.emb", tmp_path / "b.emb", "--t", "-10",
                               "--allow-extrapolation", "-o", tmp_path / "c.emb", "--binary",
                               tmp_path / "c.binary", "-m", model.path]])
    assert e.value.code == 0, capsys.readouterr().err
    assert _finite_where_measured(read_merl(tmp_path / "c.binary"), model.rho_ref)


# --- extreme directions ----------------------------------------------------------------

def _unit(v):
    v = torch.tensor(v, dtype=torch.float64)
    return v / v.norm(dim=-1, keepdim=True)


@pytest.mark.slow
def test_eval_dirs_at_extreme_directions(trained, stiff):
    model, _ = trained
    nb = NeuralBRDF.from_embedding(model, api.encode(draw_samples(stiff["mirror"], 500), model))
    g = 1e-9  # radians above the horizon
    wi = _unit([[0, 0, 1], [math.cos(g), 0, math.sin(g)], [math.cos(g), 0, math.sin(g)], [0.6, 0, 0.8],
                [0, 0, 1], [1, 0, 0], [1, 0, 0], [0, 0, 1], [0.6, 0.0, 0.8]])
    wo = _unit([[0, 0, 1], [-math.cos(g), 0, math.sin(g)], [math.cos(g), 0, math.sin(g)], [-0.6, 0, 0.8],
                [math.cos(g), 0, math.sin(g)], [-1, 0, 0], [1, 0, 0], [0, 0, -1], [0.6, 0.0, 0.8]])
    # normal; grazing mirror pair; grazing same direction; phi_d = 0; normal + grazing;
    # exactly at the horizon (twice); below; phi_d = pi (wi = wo off the normal)
    rho = nb.eval_dirs(wi, wo)
    assert torch.isfinite(rho).all() and (rho >= 0).all()
    assert (rho[[5, 6, 7]] == 0).all()  # at or below the horizon
    torch.testing.assert_close(nb.eval_dirs(wo, wi), rho)  # reciprocity
    # HD vectors at the corners of the angle domain, phi_d at 0 and pi (the same pair)
    corners = [(0, 0, 0), (0, 0, math.pi), (HALF_PI, HALF_PI, 0), (HALF_PI, HALF_PI, math.pi),
               (0, HALF_PI, 0), (0, HALF_PI, math.pi), (HALF_PI, 0, 0)]
    th, td, pd = (np.array(c, dtype=np.float64) for c in zip(*corners))
    out = nb.eval_hd(torch.from_numpy(hd_vectors(th, td, pd)))
    assert torch.isfinite(out).all() and (out >= 0).all()


def test_phi_d_at_pi_encodes_like_zero(model):
    # Regression: SampleSet.hd() did not fold phi_d, so phi_d = pi (the same direction
    # pair as phi_d = 0 by reciprocity) reached the encoder as another input.
    th, td = np.array([0.0, 0.3, HALF_PI]), np.array([HALF_PI, 0.5, 0.2])
    rgb = np.array([[1e4, 1e4, 1e4], [0.5, 0.4, 0.3], [1e-3, 1e-3, 1e-3]])
    base = api.encode(SampleSet(th, td, np.array([0.0, 1.0, 0.0]), rgb), model).values
    for pd in ([math.pi, 1.0 + math.pi, -1e-17], [2 * math.pi, 1.0 - 2 * math.pi, math.pi]):
        other = api.encode(SampleSet(th, td, np.array(pd), rgb), model).values
        np.testing.assert_allclose(other, base, rtol=1e-5, atol=1e-6)
    assert np.isfinite(base).all()


# --- sample counts -----------------------------------------------------------------------

def test_one_sample_one_direction_and_duplicates(model, stiff):
    s = draw_samples(stiff["mirror"], 300, seed=2)
    one = SampleSet(s.theta_h[:1], s.theta_d[:1], s.phi_d[:1], s.rgb[:1])
    z1 = api.encode(one, model)
    assert z1.sample_count == 1 and np.isfinite(z1.values).all()
    # all samples at one direction: the mean of identical features is that feature
    same = SampleSet(*(np.repeat(a, 1000, axis=0) for a in (one.theta_h, one.theta_d, one.phi_d, one.rgb)))
    np.testing.assert_allclose(api.encode(same, model).values, z1.values, rtol=1e-6, atol=1e-7)
    # every sample duplicated 3 times: the same mean
    dup = SampleSet(*(np.repeat(a, 3, axis=0) for a in (s.theta_h, s.theta_d, s.phi_d, s.rgb)))
    np.testing.assert_allclose(api.encode(dup, model).values, api.encode(s, model).values, rtol=1e-6, atol=1e-7)


def test_million_samples_bounded_time_and_memory(model, stiff):
    s = draw_samples(stiff["mirror"], 1_000_000, seed=3)
    input_bytes = sum(a.nbytes for a in (s.theta_h, s.theta_d, s.phi_d, s.rgb))  # 48 MB
    tracemalloc.start()
    try:
        t0 = time.perf_counter()
        emb = api.encode(s, model)
        seconds = time.perf_counter() - t0
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert emb.sample_count == 1_000_000 and np.isfinite(emb.values).all()
    # NumPy temporaries (HD vectors, reference values, cell indices): a few times the
    # input, never the per-sample activations (those are chunked; docs/notes/stability.md).
    assert peak < 4 * input_bytes, (peak, input_bytes)
    assert seconds < 60, seconds


# --- interpolation far outside [0, 1] ----------------------------------------------------

def test_absurd_extrapolation_is_refused_not_nan(model, stiff):
    # Regression: t = 1e20 overflowed the hyponet's float32 activations into NaN, which
    # write_merl would have stored as "not measured" cells.
    a = Embedding(np.full(model.cfg.latent_dim, 0.5), "hypernet", model.digest, "a")
    b = Embedding(np.full(model.cfg.latent_dim, -0.5), "hypernet", model.digest, "b")
    far = api.interpolate(a, b, 1e30, allow_extrapolation=True)
    with pytest.raises(InputError, match=r"hyponet overflows on this embedding .* cannot be decoded"):
        api.decode(far, model)
    nb = NeuralBRDF.from_embedding(model, far, "far.emb")
    with pytest.raises(InputError, match=r"^far\.emb: "):
        nb.eval_hd(torch.tensor([[0.0, 0.0, 1.0, 0.0, 0.0, 1.0]]))


# --- rendering and image metrics ---------------------------------------------------------

@pytest.fixture(scope="module")
def small_scene():
    import dataclasses

    from brdfkit.render.scene import REFERENCE

    return dataclasses.replace(REFERENCE, resolution=12)


def _image_ok(img):
    return bool(np.isfinite(img).all() and (img >= 0).all() and img.max() > 0)


@pytest.mark.slow
def test_render_and_image_metrics_on_stiff(trained, stiff, small_scene):
    from brdfkit.evaluation.metrics import image_metrics
    from brdfkit.render.renderable import TableBRDF
    from brdfkit.render.quadrature import render

    model, _ = trained
    images = {}
    for name in ("mirror", "black"):
        images[name], _ = render(TableBRDF(stiff[name], name=name), small_scene)
        nb = NeuralBRDF.from_embedding(model, api.encode(draw_samples(stiff[name], 400, seed=5), model))
        images[name + "-neural"], _ = render(nb, small_scene)
    for key, img in images.items():
        assert _image_ok(img), key
    assert images["mirror"].max() > 1.0 > 1e-2 > images["black"].max()  # the sun in the mirror
    for a, b in (("mirror-neural", "mirror"), ("black-neural", "black"), ("mirror", "black")):
        m = image_metrics(images[a], images[b])
        assert all(math.isfinite(m[k]) for k in ("psnr", "delta_e", "ssim")), (a, b, m)


def test_mitsuba_render_of_the_mirror(stiff, small_scene):
    from brdfkit.errors import BrdfkitError
    from brdfkit.render.renderable import TableBRDF
    from brdfkit.render.mitsuba3.scenes import render_reference
    from brdfkit.render.mitsuba3.loader import ensure_libllvm

    try:
        ensure_libllvm()
    except BrdfkitError as e:
        pytest.skip(f"Mitsuba's LLVM backend unavailable: {e}")
    img = render_reference(TableBRDF(stiff["mirror"], name="mirror"), small_scene, spp=4)
    assert _image_ok(img)


# --- real data (proxy MERL tables from ../shared) -----------------------------------------

@pytest.mark.slow
@pytest.mark.proxy
@pytest.mark.parametrize("name", ["chrome", "black-fabric"])
def test_proxy_mirror_and_black(trained, tmp_path_factory, small_scene, name):
    """The most mirror-like and a near-black MERL material (NBRDF proxies) through the
    mapping, encode, decode, sparse, metrics and rendering."""
    from brdfkit.io.merl import read_merl
    from brdfkit.evaluation.metrics import image_metrics
    from brdfkit.render.renderable import TableBRDF
    from brdfkit.render.quadrature import render

    from helpers_foundation import proxy_material

    model, _ = trained
    path = proxy_material(tmp_path_factory, name)
    table = read_merl(path)
    for ref in (model.rho_ref.astype(np.float64), 0.0, 1e4):
        back = from_mapped(to_mapped(table, ref), ref, floor=0)
        big = np.isfinite(table) & np.isfinite(back) & (table > 1e-6)
        assert (np.abs(back[big] - table[big]) <= 1e-6 * table[big]).all()
    emb = api.encode(path, model)
    dec = api.decode(emb, model)
    rec, _ = api.sparse(draw_samples(table, 40, seed=2), model)
    for t in (dec, rec):
        assert _finite_where_measured(t, model.rho_ref) and math.isfinite(brdf_log_rmse(t, table))
    ref_img, _ = render(TableBRDF(table, name=name), small_scene)
    img, _ = render(NeuralBRDF.from_embedding(model, emb), small_scene)
    assert _image_ok(ref_img) and _image_ok(img)
    assert all(math.isfinite(v) for v in image_metrics(img, ref_img).values())
