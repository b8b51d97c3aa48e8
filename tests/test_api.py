"""The library API: encode (any N, any order), decode, eval_dirs, sparse, interpolate.

Models are untrained: these tests check the plumbing and the invariances that hold for
any weights (permutation invariance, chunking, agreement between the dense decode and
the model definition), not accuracy.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch

import brdfkit
from brdfkit import api
from brdfkit.io.embedding import Embedding
from brdfkit.errors import InputError, ModelMismatchError
from brdfkit.geometry import N_CELLS, cell_angles, io_from_half_diff
from brdfkit.hypernet.mapping import from_mapped
from brdfkit.io.merl import write_merl
from brdfkit.geometry import grid_hd
from brdfkit.hypernet.neural_brdf import NeuralBRDF
from brdfkit.io.samples import SampleSet, write_samples
from brdfkit.acquisition.sampling import draw_samples

from helpers_model import make_model, material_table


@pytest.fixture(scope="module")
def models(tmp_path_factory):
    folder = tmp_path_factory.mktemp("api-models")
    make_model(folder / "tiny.safetensors", seed=0)
    make_model(folder / "tiny2.safetensors", seed=1)
    make_model(folder / "default.safetensors", config={}, seed=0)
    return {name: api.load_model(folder / f"{name}.safetensors", device="cpu")
            for name in ("tiny", "tiny2", "default")}


@pytest.fixture(scope="module")
def table():
    return material_table(1)


def _shuffled(s: SampleSet, seed=0) -> SampleSet:
    p = np.random.default_rng(seed).permutation(len(s))
    return SampleSet(s.theta_h[p], s.theta_d[p], s.phi_d[p], s.rgb[p], s.source)


def test_permutation_invariance(models, table):
    samples = draw_samples(table, 4000, seed=0)
    for name in ("tiny", "default"):
        a = api.encode(samples, models[name])
        b = api.encode(_shuffled(samples), models[name])
        np.testing.assert_allclose(a.values, b.values, rtol=0, atol=1e-5)


@pytest.mark.parametrize("n", [1, 2, 40, 4000])
def test_any_number_of_samples(models, table, n):
    m = models["default"]
    e = api.encode(draw_samples(table, n, seed=n), m)
    assert e.values.shape == (40,) and e.values.dtype == np.float32
    assert np.isfinite(e.values).all()
    assert e.sample_count == n and e.decoder == m.digest


def test_encoder_matches_model_definition(models, table):
    """The chunked sum / N equals HyperBRDF.encode (the mean the model was trained with)."""
    from brdfkit.hypernet.mapping import to_mapped

    m = models["default"]
    s = draw_samples(table, 300, seed=5)
    ref = m.reference_at(s.theta_h, s.theta_d, s.phi_d)
    hd = torch.tensor(s.hd(), dtype=torch.float32)[None]
    mapped = torch.tensor(to_mapped(s.rgb, ref), dtype=torch.float32)[None]
    with torch.no_grad():
        z = m.net.encode(hd, mapped)[0].numpy()
    np.testing.assert_allclose(api.encode(s, m).values, z, rtol=1e-5, atol=1e-6)


def test_chunking_does_not_change_the_embedding(models, table, monkeypatch):
    import brdfkit.hypernet.kernels as neural

    m = models["tiny"]
    s = draw_samples(table, 5000, seed=2)
    whole = api.encode(s, m).values
    monkeypatch.setattr(neural, "ENCODE_CHUNK", 777)
    np.testing.assert_allclose(api.encode(s, m).values, whole, rtol=0, atol=1e-6)


def test_dense_table_uses_all_measured_cells(models, table):
    m = models["tiny"]
    e = api.encode(table, m, source="t", refine=False)  # the paper's pass (refined: test_compression)
    measured = np.isfinite(table).all(-1)
    assert e.sample_count == int(measured.sum()) and e.source == "t"
    # Same as encoding those cells as a sample set at the grid angles.
    idx = np.flatnonzero(measured.reshape(-1))
    s = SampleSet(*cell_angles(idx), table.reshape(-1, 3)[idx])
    np.testing.assert_allclose(api.encode(s, m).values, e.values, rtol=0, atol=1e-5)


def test_encode_from_paths(models, table, tmp_path):
    m = models["tiny"]
    write_merl(tmp_path / "mat.binary", table)
    s = draw_samples(table, 200, seed=3)
    write_samples(tmp_path / "s.csv", s)
    e_bin = api.encode(tmp_path / "mat.binary", m, refine=False)
    assert e_bin.source == "mat.binary"
    np.testing.assert_allclose(e_bin.values, api.encode(table, m, refine=False).values, atol=1e-6)
    e_csv = api.encode(str(tmp_path / "s.csv"), m)
    assert e_csv.source == "s.csv" and e_csv.sample_count == 200
    np.testing.assert_allclose(e_csv.values, api.encode(s, m).values, atol=1e-6)


def test_encode_bad_inputs(models, tmp_path):
    m = models["tiny"]
    with pytest.raises(InputError, match="cannot encode a list"):
        api.encode([1, 2, 3], m)
    with pytest.raises(InputError, match="shape"):
        api.encode(np.zeros((10, 3)), m)
    with pytest.raises(InputError, match="no measured cells"):
        api.encode(np.full((90, 90, 180, 3), np.nan), m)
    with pytest.raises(InputError, match="no such file"):
        api.encode(tmp_path / "missing.binary", m)
    (tmp_path / "junk.binary").write_bytes(b"junk")
    with pytest.raises(InputError, match="not a MERL table"):
        api.encode(tmp_path / "junk.binary", m)


def test_reference_at_grid_and_between(models):
    m = models["tiny"]
    flat = m.rho_ref.reshape(-1, 3)
    idx = np.flatnonzero(np.isfinite(flat).all(1))[::9973]
    th, td, pd = cell_angles(idx)
    np.testing.assert_array_equal(m.reference_at(th, td, pd), flat[idx].astype(np.float64))
    # Halfway between two measured phi_d cells: the mean of the two.
    ok = np.isfinite(flat).all(1)
    i = next(k for k in idx if k % 180 < 179 and ok[k + 1])
    a = cell_angles(np.array([i]))
    mid = m.reference_at(a[0], a[1], a[2] + np.pi / 360)
    np.testing.assert_allclose(mid[0], (flat[i] + flat[i + 1]) / 2, rtol=1e-5)


def test_reference_fallback_where_unmeasured(tmp_path):
    """Where the reference has no measured neighbour, the median of its measured cells."""
    ref = np.full((90, 90, 180, 3), np.nan)
    ref[:10] = 0.5
    ref[:4] = 0.1
    make_model(tmp_path / "m.safetensors", rho_ref=ref)
    m = api.load_model(tmp_path / "m.safetensors", "cpu")
    th, td, pd = cell_angles(np.array([60 * 16200 + 100, 2 * 16200 + 7]))
    got = m.reference_at(th, td, pd)
    np.testing.assert_allclose(got[0], [0.5, 0.5, 0.5])   # median: 6 of 10 rows are 0.5
    np.testing.assert_allclose(got[1], [0.1, 0.1, 0.1])   # its own cell


@pytest.mark.slow
def test_decode_shape_nan_pattern_non_negative(models, table):
    for name in ("tiny", "default"):
        m = models[name]
        out = api.decode(api.encode(draw_samples(table, 100, seed=1), m), m)
        assert out.shape == (90, 90, 180, 3) and out.dtype == np.float64
        unmeasured = ~np.isfinite(m.rho_ref).all(-1)
        np.testing.assert_array_equal(np.isnan(out).any(-1), unmeasured)
        np.testing.assert_array_equal(np.isnan(out).all(-1), unmeasured)
        assert (out[~unmeasured] >= 0).all() and np.isfinite(out[~unmeasured]).all()


def test_decode_matches_model_definition(models, table):
    """The blocked 2-D addmm decode equals network.hyponet_forward (batched baddbmm)."""
    from brdfkit.hypernet.network import hyponet_forward

    m = models["default"]
    e = api.encode(draw_samples(table, 500, seed=4), m)
    out = api.decode(e, m).reshape(-1, 3)
    idx = np.flatnonzero(np.isfinite(out).all(1))[::501]
    with torch.no_grad():
        w = m.net.hyponet_weights(torch.from_numpy(e.values)[None])
        mapped = hyponet_forward(w, torch.from_numpy(grid_hd()[idx])[None])[0].double().numpy()
    expect = from_mapped(mapped, m.rho_ref.reshape(-1, 3)[idx].astype(np.float64))
    np.testing.assert_allclose(out[idx], expect, rtol=1e-4, atol=1e-6)


def test_eval_dirs_and_eval_hd_agree_with_table(models, table):
    m = models["default"]
    nb = NeuralBRDF.from_embedding(m, api.encode(draw_samples(table, 300, seed=6), m))
    out = nb.to_table().reshape(-1, 3)
    idx = np.flatnonzero(np.isfinite(out).all(1))[::997]
    wi, wo = io_from_half_diff(*cell_angles(idx))
    v = nb.eval_dirs(torch.tensor(wi), torch.tensor(wo))
    assert v.shape == (idx.size, 3) and v.dtype == torch.float32
    np.testing.assert_allclose(v.numpy(), out[idx], rtol=1e-4, atol=1e-6)
    # Swapping wi and wo (reciprocity) gives the same values.
    np.testing.assert_allclose(nb.eval_dirs(torch.tensor(wo), torch.tensor(wi)).numpy(), out[idx],
                               rtol=1e-4, atol=1e-6)
    h = nb.eval_hd(torch.from_numpy(grid_hd()[idx]))
    np.testing.assert_allclose(h.numpy(), out[idx], rtol=1e-4, atol=1e-6)


def test_eval_dirs_below_horizon_is_zero(models, table):
    m = models["tiny"]
    nb = NeuralBRDF.from_embedding(m, api.encode(draw_samples(table, 50, seed=7), m))
    up = torch.tensor([[0.0, 0.0, 1.0], [0.6, 0.0, 0.8]])
    down = torch.tensor([[0.0, 0.0, -1.0], [0.6, 0.0, -0.8]])
    assert (nb.eval_dirs(up, down) == 0).all() and (nb.eval_dirs(down, up) == 0).all()
    assert (nb.eval_dirs(up, up) >= 0).all()


def test_decode_refuses_other_models_embedding(models, table):
    e = api.encode(draw_samples(table, 10), models["tiny"])
    with pytest.raises(ModelMismatchError, match="latent 7"):
        api.decode(e, models["tiny2"])
    with pytest.raises(ModelMismatchError):
        api.decode(e, models["default"])


def test_decode_from_emb_path(models, table, tmp_path):
    from brdfkit.io.embedding import write_embedding

    m = models["tiny"]
    e = api.encode(draw_samples(table, 10), m)
    write_embedding(tmp_path / "a.emb", e)
    np.testing.assert_array_equal(api.decode(tmp_path / "a.emb", m), api.decode(e, m))


def test_sparse(models, table, tmp_path):
    m = models["tiny"]
    s = draw_samples(table, 400, seed=8)
    out, e = api.sparse(s, m, refine=False)  # the paper's one pass (refined: test_refine)
    np.testing.assert_array_equal(out, api.decode(api.encode(s, m), m))
    assert e.sample_count == 400
    write_samples(tmp_path / "s.csv", s)
    out2, _ = api.sparse(tmp_path / "s.csv", m, refine=False)
    np.testing.assert_allclose(out2, out, rtol=1e-5, atol=1e-7)
    with pytest.raises(InputError, match=".csv sample set"):
        api.sparse(tmp_path / "x.binary", m)
    with pytest.raises(InputError, match="takes the option"):
        api.sparse(s, m, lam=0.1)


def test_interpolate_endpoints_exact(models, table):
    m = models["default"]
    a = api.encode(draw_samples(table, 50, seed=1), m)
    b = api.encode(draw_samples(material_table(0), 50, seed=2), m)
    np.testing.assert_array_equal(api.interpolate(a, b, 0.0).values, a.values)
    np.testing.assert_array_equal(api.interpolate(a, b, 1.0).values, b.values)
    mid = api.interpolate(a, b, 0.5)
    np.testing.assert_allclose(mid.values, (a.values.astype(np.float64) + b.values) / 2, rtol=1e-6)
    assert mid.decoder == m.digest and mid.values.dtype == np.float32
    assert api.decode(mid, m).shape == (90, 90, 180, 3)


def test_interpolate_refusals(models, table):
    a = api.encode(draw_samples(table, 20), models["tiny"])
    b = api.encode(draw_samples(table, 20, seed=9), models["tiny"])
    for t in (-0.1, 1.5):
        with pytest.raises(InputError, match="outside"):
            api.interpolate(a, b, t)
        e = api.interpolate(a, b, t, allow_extrapolation=True)
        np.testing.assert_allclose(e.values, (1 - t) * a.values.astype(np.float64) + t * b.values, rtol=1e-6)
    for t in (float("nan"), float("inf"), "abc"):
        with pytest.raises(InputError):
            api.interpolate(a, b, t, allow_extrapolation=True)
    other = api.encode(draw_samples(table, 20), models["tiny2"])
    with pytest.raises(ModelMismatchError, match="different decoders"):
        api.interpolate(a, other, 0.5)
    wrong_dim = Embedding(np.zeros(5, np.float32), "hypernet", a.decoder)
    with pytest.raises(ModelMismatchError):
        api.interpolate(a, wrong_dim, 0.5)


def test_public_names():
    assert brdfkit.encode is api.encode and brdfkit.decode is api.decode
    assert brdfkit.load_model is api.load_model and brdfkit.interpolate is api.interpolate
    assert brdfkit.sparse is api.sparse and brdfkit.Embedding is Embedding
