"""The learnt-prior method (``prior``): the closed-form fit around a prior mean
(:mod:`brdfkit.prior.model`), its model file (:mod:`brdfkit.prior.prior_file`)
and its training (:mod:`brdfkit.prior.fit`, ``brdfkit fit --method prior``).

Tables are cheap analytic ones (a Lambertian base and a Gaussian lobe in ``theta_h``
with a Fresnel-like rise in ``theta_d``, computed on the ``(theta_h, theta_d)`` rows
and broadcast over ``phi_d``); models are tiny and untrained, or given a random head so
that the prior mean is not zero. The tests check the algebra, the file and the plumbing,
not how well a trained model does (``benchmarks/eval_sparse.py``).
"""

from __future__ import annotations

import dataclasses
import json
import re
import struct

import numpy as np
import pytest

from brdfkit.errors import FormatError, InputError
from brdfkit.geometry import GRID_SHAPE, HALF_PI, grid_angles, valid_mask
from brdfkit.methods import get_method
from brdfkit.basis import EPS, fit_basis, load_basis, save_basis
from brdfkit.prior.prior_file import is_prior_file, load_prior, save_prior
from brdfkit.prior.model import PriorConfig, PriorModel, prior_net, sample_rows, solve
from brdfkit.io.samples import SampleSet
from brdfkit.acquisition.sampling import draw_samples

from conftest import run_cli

CFG = PriorConfig(n_components=3, latent_dim=4, width=8)


@pytest.fixture(scope="module")
def make_table():
    """``f(albedo, alpha, ks, f0) ->`` float64 ``(90, 90, 180, 3)``, NaN where MERL
    measures nothing."""
    th, td, pd = grid_angles()
    th, td = np.meshgrid(th, td, indexing="ij")
    unmeasured = ~valid_mask()
    tint = np.array([1.0, 0.85, 0.7])
    wobble = 1 + 0.1 * np.cos(2 * pd)  # a little phi_d dependence

    def make(albedo, alpha, ks, f0):
        lobe = ks * np.exp(-(th / alpha) ** 2) * (1 + f0 * (1 - np.cos(td)) ** 5)
        t = (np.asarray(albedo, np.float64) / np.pi + (lobe[..., None] * tint))[:, :, None, :] \
            * wobble[None, None, :, None]
        t = np.broadcast_to(t, GRID_SHAPE + (3,)).copy()
        t[unmeasured] = np.nan
        return t

    return make


def _params(seed, n):
    rng = np.random.default_rng(seed)
    return [(rng.uniform(0.02, 0.8, 3), rng.uniform(0.05, 0.5), rng.uniform(0.2, 5.0), rng.uniform(0.0, 3.0))
            for _ in range(n)]


@pytest.fixture(scope="module")
def tables(make_table):
    """Eight training tables and one held out."""
    return [make_table(*p) for p in _params(11, 9)]


@pytest.fixture(scope="module")
def basis(tables):
    return fit_basis(tables[:8], n_components=3, names=[f"m{i}" for i in range(8)])


def _model(basis, seed=None):
    """A tiny model: untrained (``seed`` ``None``: the head's last layer zero, so the
    plain basis fit) or with a random head (a non-zero prior mean, as a trained one)."""
    import torch

    net = prior_net(CFG)
    if seed is not None:
        torch.manual_seed(seed)
        with torch.no_grad():
            for p in net.parameters():
                p.copy_(torch.randn_like(p) * 0.5)
    net.eval()
    return PriorModel(basis, net, CFG, {"materials": list(basis.materials), "steps": 0})


@pytest.fixture(scope="module")
def fresh(basis):
    return _model(basis)


@pytest.fixture(scope="module")
def noisy(basis):
    return _model(basis, seed=5)


def _on_basis(table, basis):
    """The reconstructed values on the basis cells ``(P, 3)``; NaN everywhere else."""
    flat = table.reshape(-1, 3)
    off = np.ones(flat.shape[0], bool)
    off[basis.cells] = False
    assert np.isnan(flat[off]).all()
    return flat[basis.cells]


# --- the closed-form fit ----------------------------------------------------------------------

@pytest.mark.slow
def test_an_untrained_model_is_the_plain_basis_fit(fresh, tables):
    samples = draw_samples(tables[8], 300, seed=1)
    with_prior = fresh.coefficients(samples, use_prior=True)
    np.testing.assert_array_equal(with_prior, fresh.coefficients(samples, use_prior=False))
    assert with_prior.shape == (3, 3) and with_prior.dtype == np.float64
    table = fresh.reconstruct(samples)
    vals = _on_basis(table, fresh.basis)
    assert table.shape == GRID_SHAPE + (3,) and np.isfinite(vals).all() and (vals >= 0).all()


def _numpy_solve(tab, rho, w, cos, sigma, s2, lam, mu=None):
    """The module docstring's weighted ridge, per channel, in float64 numpy::

        min_c sum_s q_s (A_s c - b_s)^2 + |(c - mu) / sigma|^2
        q_s = g_s^2 / s2 + 1 / lam,   g_s = cos_i (rho + eps / w) / (1 + rho cos_i)
        b_s = ln((rho w + eps) / (x_ref + eps)) - mean
    """
    ref, mean, a = tab[:, 0], tab[:, 1], tab[:, 2:]
    out = np.empty((3, a.shape[1]))
    for ch in range(3):
        r = rho[:, ch]
        b = np.log((r * w + EPS) / (ref + EPS)) - mean
        g = cos * (r + EPS / w) / (1 + r * cos)
        q = g ** 2 / s2 + 1 / lam
        lhs = a.T @ (q[:, None] * a) + np.diag(1 / sigma ** 2)
        rhs = a.T @ (q * b) + (0 if mu is None else mu[ch] / sigma ** 2)
        out[ch] = np.linalg.solve(lhs, rhs)
    return out


@pytest.mark.slow
def test_solve_is_the_weighted_ridge_of_the_docstring(basis, tables):
    import torch

    rng = np.random.default_rng(2)
    sets = [draw_samples(tables[8], 200, seed=3), draw_samples(tables[2], 200, seed=4, distribution="cells")]
    rows = [sample_rows(basis, s) for s in sets]
    assert all(r[0].all() for r in rows)  # drawn from measured cells: all on the basis
    # float32 inputs, as the model passes them; the reference in float64 from the same values.
    tab, rho, w, cos = (np.stack([r[i] for r in rows]).astype(np.float32) for i in (1, 4, 2, 3))
    sigma = np.stack([basis.sigma, basis.sigma * 1.5]).astype(np.float32)
    mu = (rng.normal(size=(2, 3, 3)) * sigma[:, None]).astype(np.float32)
    T = torch.from_numpy
    for m in (None, mu):
        c, b = solve(T(tab), T(rho), T(w), T(cos), T(sigma), CFG.s2, CFG.lam, None if m is None else T(m))
        assert c.dtype == torch.float32 and tuple(c.shape) == (2, 3, 3) and tuple(b.shape) == (2, 200, 3)
        for i in range(2):
            want = _numpy_solve(*(x[i].astype(np.float64) for x in (tab, rho, w, cos, sigma)), CFG.s2, CFG.lam,
                                None if m is None else m[i].astype(np.float64))
            np.testing.assert_allclose(c[i].numpy(), want, rtol=2e-4, atol=1e-4 * np.abs(want).max())
    # The prior mean moves the answer (the test above is not trivially about mu = 0).
    c0, _ = solve(T(tab), T(rho), T(w), T(cos), T(sigma), CFG.s2, CFG.lam)
    c1, _ = solve(T(tab), T(rho), T(w), T(cos), T(sigma), CFG.s2, CFG.lam, T(mu))
    assert float((c1 - c0).abs().max()) > 1e-3 * float(c0.abs().max())


def test_many_samples_outweigh_the_prior_mean(basis, tables):
    import torch

    big = draw_samples(tables[8], 20000, seed=6)
    ok, tab, w, cos, rho, _ = sample_rows(basis, big)
    assert ok.all()
    sig = torch.from_numpy(basis.sigma)[None]
    mu = 2.0 * sig[:, None].expand(1, 3, 3).clone()  # two standard deviations off
    moved = []
    for n in (20, 200, 2000, 20000):  # nested sets: each holds the one before
        args = [torch.from_numpy(a[:n].astype(np.float32))[None] for a in (tab, rho, w, cos)]
        c0, _ = solve(*args, sig, CFG.s2, CFG.lam)
        c1, _ = solve(*args, sig, CFG.s2, CFG.lam, mu)
        moved.append(float(((c1 - c0) / sig[:, None]).abs().max()))
    assert all(a > b for a, b in zip(moved, moved[1:])), moved
    assert moved[-1] < 0.05 * moved[0], moved


@pytest.mark.parametrize("spread", [False, True])
def test_the_numpy_network_and_solve_are_the_torch_ones(basis, tables, spread):
    """A reconstruction evaluates the network and the closed form in NumPy
    (:class:`PriorWeights`); the training in torch: the same numbers, to float32 rounding."""
    import torch

    from brdfkit.prior.model import PriorWeights

    cfg = dataclasses.replace(CFG, spread=spread)
    torch.manual_seed(3)
    net = prior_net(cfg).eval()
    with torch.no_grad():
        for p in net.parameters():
            p.copy_(torch.randn_like(p) * 0.5)
    arrays = PriorWeights.of(net, cfg)
    ok, tab, w, cos, rho, hd = sample_rows(basis, draw_samples(tables[8], 300, seed=4))
    rows = [np.ascontiguousarray(a, np.float32)[None] for a in (tab, rho, w, cos)]
    sig = basis.sigma.astype(np.float32)[None]
    c, b = solve(*rows, sig, CFG.s2, CFG.lam, weight="energy")
    ct, bt = solve(*map(torch.from_numpy, rows), torch.from_numpy(sig), CFG.s2, CFG.lam, weight="energy")
    assert c.dtype == np.float32 and b.dtype == np.float32
    np.testing.assert_allclose(b, bt.numpy(), rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(c, ct.numpy(), rtol=1e-5, atol=1e-5 * np.abs(c).max())
    resid = b - np.einsum("bck,blk->bcl", rows[0][..., 2:], c)
    got = arrays(np.float32(hd)[None], resid, c, sig, int(ok.sum()))
    with torch.no_grad():
        want = net(torch.from_numpy(np.float32(hd)[None]), torch.from_numpy(resid), torch.from_numpy(c),
                   torch.from_numpy(sig), int(ok.sum()))
    assert not np.allclose(got[0], 0)  # a prior mean that is not zero
    for x, y in zip(got, want):
        assert x.dtype == np.float32 and x.shape == tuple(y.shape)
        np.testing.assert_allclose(x, y.numpy(), rtol=1e-5, atol=1e-5 * float(y.abs().max()))
    with pytest.raises(ValueError, match="head.4.weight"):
        PriorWeights(dataclasses.replace(cfg, spread=not spread), arrays.state_dict())


# --- the model file ---------------------------------------------------------------------------

def _same_model(a, b, samples):
    for k in ("cells", "reference", "mean", "components", "sigma"):
        np.testing.assert_array_equal(getattr(a.basis, k), getattr(b.basis, k))
    sa, sb = a.net.state_dict(), b.net.state_dict()
    assert sorted(sa) == sorted(sb)
    for k in sa:
        np.testing.assert_array_equal(np.asarray(sa[k]), np.asarray(sb[k]))
    assert a.cfg == b.cfg
    np.testing.assert_array_equal(a.coefficients(samples), b.coefficients(samples))


def test_save_load_round_trip_inline(noisy, tables, tmp_path):
    samples = draw_samples(tables[8], 200, seed=7)
    path = tmp_path / "prior.safetensors"
    fp = save_prior(path, noisy)
    assert len(fp) == 64 and is_prior_file(path)
    back = load_prior(path)
    assert back.digest == fp
    _same_model(noisy, back, samples)
    assert back.meta == {"materials": noisy.meta["materials"], "steps": 0}
    assert not np.array_equal(back.coefficients(samples), back.coefficients(samples, use_prior=False))
    # Saving the same model again gives the same digest (it names the content).
    assert save_prior(tmp_path / "again.safetensors", noisy) == fp
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".brdfkit-tmp-")]

    # Compact basis storage inside the file: the basis as a compact basis file gives it.
    small = tmp_path / "small.safetensors"
    fp2 = save_prior(small, noisy, half=True, phi_stride=2)
    assert fp2 != fp and small.stat().st_size < 0.4 * path.stat().st_size
    back2 = load_prior(small)
    save_basis(tmp_path / "b.safetensors", noisy.basis, half=True, phi_stride=2)
    stored = load_basis(tmp_path / "b.safetensors")
    _same_model(dataclasses.replace(noisy, basis=stored), back2, samples)
    assert back2.digest == fp2


def test_shared_basis_file(basis, tables, tmp_path):
    samples = draw_samples(tables[8], 200, seed=8)
    a, b = _model(basis, seed=1), _model(basis, seed=2)
    shared = tmp_path / "shared.basis.safetensors"
    fa = save_prior(tmp_path / "a.safetensors", a, basis_file=shared.name)
    assert shared.exists()
    before = shared.read_bytes()
    fb = save_prior(tmp_path / "b.safetensors", b, basis_file=shared.name)
    assert shared.read_bytes() == before  # checked, not rewritten
    assert fa != fb
    for model, name, fp in ((a, "a", fa), (b, "b", fb)):
        back = load_prior(tmp_path / f"{name}.safetensors")
        assert back.digest == fp
        _same_model(model, back, samples)
    # The model file holds no basis tensor of its own.
    from safetensors import safe_open
    with safe_open(str(tmp_path / "a.safetensors"), "numpy") as f:
        assert all(k.startswith("net.") for k in f.keys())
        assert f.metadata()["basis_file"] == shared.name

    # A model on another basis may not share it.
    other = dataclasses.replace(basis, components=-basis.components)
    with pytest.raises(InputError, match="holds another basis"):
        save_prior(tmp_path / "c.safetensors", _model(other, seed=3), basis_file=shared.name)
    assert not (tmp_path / "c.safetensors").exists()
    with pytest.raises(InputError, match="bare file name"):
        save_prior(tmp_path / "d.safetensors", a, basis_file="sub/basis.safetensors")

    # A basis file changed after the models were saved: refused, naming the digest.
    save_basis(shared, other)
    for name in ("a", "b"):
        with pytest.raises(FormatError, match=f"{name}.safetensors: .*shared.basis.safetensors.*digest"):
            load_prior(tmp_path / f"{name}.safetensors")
    shared.unlink()
    with pytest.raises(FormatError, match="a.safetensors: .*missing"):
        load_prior(tmp_path / "a.safetensors")


@pytest.mark.slow
def test_shared_compact_basis_file(basis, tables, tmp_path):
    """A basis shared in compact storage: the file holds it rounded, and the same basis
    given again (as fitted, or as read back) is still the same basis."""
    samples = draw_samples(tables[8], 200, seed=8)
    a, b = _model(basis, seed=1), _model(basis, seed=2)
    store = dict(half=True, phi_stride=2, basis_file="small.basis.safetensors")
    save_prior(tmp_path / "a.safetensors", a, **store)
    save_prior(tmp_path / "b.safetensors", b, **store)
    back_a = load_prior(tmp_path / "a.safetensors")
    save_prior(tmp_path / "c.safetensors", back_a, **store)
    stored = load_basis(tmp_path / "small.basis.safetensors")
    for name, model in (("a", a), ("b", b), ("c", a)):
        _same_model(dataclasses.replace(model, basis=stored), load_prior(tmp_path / f"{name}.safetensors"), samples)
    other = dataclasses.replace(basis, components=-basis.components)
    with pytest.raises(InputError, match="holds another basis"):
        save_prior(tmp_path / "d.safetensors", _model(other, seed=3), **store)


def _tensor_span(path, name):
    """Byte offsets ``(start, end)`` of a tensor's data in a safetensors file."""
    raw = path.read_bytes()
    n = struct.unpack("<Q", raw[:8])[0]
    begin, end = json.loads(raw[8:8 + n])[name]["data_offsets"]
    return 8 + n + begin, 8 + n + end


def test_a_changed_weight_is_refused_by_the_digest(noisy, tmp_path):
    path = tmp_path / "prior.safetensors"
    save_prior(path, noisy)
    good = path.read_bytes()
    for name in ("net.encoder.0.weight", "net.head.4.bias", "basis.components"):
        start, end = _tensor_span(path, name)
        raw = bytearray(good)
        raw[start + 4 * ((end - start) // 8)] ^= 0x01  # the lowest mantissa bit of one float
        path.write_bytes(bytes(raw))
        with pytest.raises(FormatError, match="prior.safetensors: .*digest"):
            load_prior(path)
    path.write_bytes(good)
    load_prior(path)


@pytest.mark.slow
def test_the_digest_covers_the_likelihood_in_the_config(noisy, tmp_path):
    """The config's likelihood changes what the model reconstructs: an edited config is a
    damaged file. A file from before the likelihood options (no ``weight`` in its config,
    a digest of the weights and the basis alone) still loads."""
    import hashlib

    from brdfkit.prior.prior_file import _digest
    from helpers_bad_input import rewrite_header

    path = tmp_path / "prior.safetensors"
    fp = save_prior(path, noisy)
    good = path.read_bytes()

    def edit_config(**change):
        def edit(h):
            cfg = json.loads(h["__metadata__"]["config"])
            cfg.update(change)
            h["__metadata__"]["config"] = json.dumps(cfg, sort_keys=True)
        return edit

    for change in ({"s2": 0.5}, {"weight": "energy" if noisy.cfg.weight == "metric" else "metric"}):
        path.write_bytes(rewrite_header(good, edit_config(**change)))
        with pytest.raises(FormatError, match="prior.safetensors: the weights or the config do not match"):
            load_prior(path)
    # The same model with another likelihood is another model.
    other = dataclasses.replace(noisy, cfg=dataclasses.replace(noisy.cfg, s2=0.5))
    assert save_prior(tmp_path / "other.safetensors", other) != fp

    def legacy(h):
        meta = h["__metadata__"]
        cfg = json.loads(meta["config"])
        del cfg["weight"]
        meta["config"] = json.dumps(cfg, sort_keys=True)
        net = {k: np.asarray(load_prior(path).net.state_dict()[k[4:]]) for k in h if k.startswith("net.")}
        basis = {k: v for k, v in _tensors(path).items() if k.startswith("basis.")}
        meta["fingerprint"] = hashlib.sha256((_digest(net) + _digest(basis)).encode()).hexdigest()

    path.write_bytes(good)
    old = tmp_path / "old.safetensors"
    old.write_bytes(rewrite_header(good, legacy))
    back = load_prior(old)
    assert back.cfg.weight == "metric"
    np.testing.assert_array_equal(back.coefficients(draw_samples(_table_of(back), 200, seed=1)),
                                  load_prior(path).coefficients(draw_samples(_table_of(back), 200, seed=1)))


def _tensors(path):
    from safetensors.numpy import load_file

    return load_file(str(path))


def _table_of(model):
    return model.basis.decode(np.zeros((model.basis.n_components, 3)))


def test_is_prior_file(noisy, basis, tmp_path):
    from helpers_model import make_model

    save_prior(tmp_path / "prior.safetensors", noisy)
    save_basis(tmp_path / "basis.safetensors", basis)
    make_model(tmp_path / "hyper.safetensors")
    (tmp_path / "garbage.safetensors").write_bytes(b"\x00\x01 not a tensor file" * 10)
    (tmp_path / "empty.safetensors").write_bytes(b"")
    assert is_prior_file(tmp_path / "prior.safetensors")
    assert is_prior_file(str(tmp_path / "prior.safetensors"))
    for name in ("basis", "hyper", "garbage", "empty", "missing"):
        assert not is_prior_file(tmp_path / f"{name}.safetensors"), name
    assert not is_prior_file(tmp_path)
    for name, message in (("basis", "not a brdfkit learnt-prior model"), ("hyper", "not a brdfkit learnt-prior"),
                          ("garbage", "garbage.safetensors")):
        with pytest.raises(FormatError, match=message):
            load_prior(tmp_path / f"{name}.safetensors")
    with pytest.raises(InputError, match="no such file"):
        load_prior(tmp_path / "missing.safetensors")


def test_registry_entry(noisy, tables, tmp_path):
    path = tmp_path / "prior.safetensors"
    save_prior(path, noisy)
    method = get_method("prior")
    samples = draw_samples(tables[8], 300, seed=9)
    model = method.load(path, device="cpu")
    np.testing.assert_array_equal(method.reconstruct(samples, model), noisy.reconstruct(samples))
    np.testing.assert_array_equal(method.reconstruct(samples, str(path), use_prior=False),
                                  noisy.reconstruct(samples, use_prior=False))
    assert method.defaults() == {"use_prior": True}
    with pytest.raises(InputError):
        method.reconstruct(samples)  # no model
    with pytest.raises(InputError, match="takes the option"):
        method.make_options(lam=1.0)


# --- extreme input ----------------------------------------------------------------------------

def _set(th, td, pd, rgb, source="x"):
    th, td, pd = (np.asarray(a, np.float64) for a in (th, td, pd))
    return SampleSet(th, td, pd, np.broadcast_to(np.asarray(rgb, np.float64), (th.size, 3)).copy(), source)


def _extreme_sets(tables):
    """Sample sets a model must survive, by name: all black, a 1e4 mirror peak at
    ``theta_h = 0``, one sample, grazing angles only, angles a hair above the horizon,
    NaN values (some, all), huge and infinite values."""
    rng = np.random.default_rng(0)
    n = 400
    th, td, pd = rng.uniform(0, HALF_PI, n), rng.uniform(0, HALF_PI, n), rng.uniform(0, np.pi, n)
    black = draw_samples(np.where(np.isnan(tables[0]), np.nan, 0.0), 300, seed=1)
    peak = np.where(th < np.radians(1.0), 1e4, 1e-3)[:, None] * np.ones(3)
    mirror = _set(np.r_[np.zeros(20), th], np.r_[rng.uniform(0, 1.2, 20), td], np.r_[np.zeros(20), pd],
                  np.r_[np.full((20, 3), 1e4), peak])
    one = draw_samples(tables[3], 1, seed=2)
    gth = rng.uniform(0, np.radians(3), n)
    grazing = _set(gth, rng.uniform(np.radians(86), HALF_PI - 1e-9, n), rng.uniform(0, np.pi, n), 0.5)
    edge = _set([0.0, 0.0, 1e-12], [HALF_PI - 1e-15, HALF_PI - 1e-12, HALF_PI - 1e-7], [0.0, 1.0, 2.0], 3.0)
    some_nan = draw_samples(tables[3], 300, seed=3)
    some_nan.rgb[::3] = np.nan
    all_nan = _set(th, td, pd, np.nan)
    huge = draw_samples(tables[3], 100, seed=4)
    huge.rgb[:5] = 1e30
    inf = draw_samples(tables[3], 100, seed=5)
    inf.rgb[:2] = np.inf
    sets = {"inf": inf, "black": black, "mirror": mirror, "one": one, "grazing": grazing, "edge": edge,
            "some_nan": some_nan, "all_nan": all_nan, "huge": huge}
    for s in sets.values():
        s.source = "x"
    return sets


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore:overflow encountered in cast:RuntimeWarning")  # the infinite values
def test_extreme_input_gives_a_table_or_one_line(fresh, noisy, tables):
    refused = {}
    for name, samples in _extreme_sets(tables).items():
        for model, use_prior in ((fresh, True), (noisy, False), (noisy, True)):
            try:
                c = model.coefficients(samples, use_prior=use_prior)
            except InputError as e:
                assert "\n" not in str(e) and str(e).startswith("x: "), (name, str(e))
                refused[name, use_prior] = str(e)
                continue
            assert np.isfinite(c).all(), (name, c)
            if model is noisy and use_prior:
                vals = _on_basis(model.basis.decode(c), model.basis)
                assert np.isfinite(vals).all() and (vals >= 0).all(), name
    # Infinite values are refused; NaN values are unmeasured samples, left out of the fit
    # (all NaN: nothing to fit).
    assert set(name for name, _ in refused) <= {"inf", "all_nan"}, refused
    assert all("non-NaN" in refused[k] for k in refused if k[0] == "all_nan")
    assert ("all_nan", True) in refused


def test_nan_samples_are_left_out_not_black(noisy, tables):
    """A NaN value says nothing: the fit equals the fit of the other samples, for the
    learnt prior and for IPCA's ridge fit with the same basis."""
    s = draw_samples(tables[3], 300, seed=3)
    holed = draw_samples(tables[3], 300, seed=3)
    holed.rgb[::3, 1] = np.nan
    kept = np.ones(len(s), bool)
    kept[::3] = False
    sub = SampleSet(s.theta_h[kept], s.theta_d[kept], s.phi_d[kept], s.rgb[kept], "x")
    np.testing.assert_allclose(noisy.coefficients(holed), noisy.coefficients(sub), rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(noisy.basis.coefficients(holed), noisy.basis.coefficients(sub), rtol=1e-9)
    assert np.isfinite(noisy.basis.coefficients(holed)).all()


def test_samples_below_the_horizon_or_none(fresh):
    rng = np.random.default_rng(1)
    # theta_h + theta_d > pi / 2 at phi_d = 0: the incoming direction is below the horizon.
    below = _set(rng.uniform(1.3, 1.5, 50), rng.uniform(1.3, 1.5, 50), np.zeros(50), 0.3, source="below.csv")
    with pytest.raises(InputError, match="below.csv: no sample .*above the horizon"):
        fresh.reconstruct(below)
    with pytest.raises(InputError, match="no samples"):
        fresh.reconstruct(_set([], [], [], np.zeros((0, 3))))


# --- training ---------------------------------------------------------------------------------

TINY_FIT = dict(folds=2, steps=3, components=2, latent_dim=4, width=8, query_size=64, batch_materials=2)


@pytest.fixture(scope="module")
def data(make_table, tmp_path_factory):
    """Four tiny training tables as MERL files, and a compact basis fitted to them."""
    from brdfkit.io.merl import write_merl

    d = tmp_path_factory.mktemp("prior-fit")
    (d / "data").mkdir()
    for i, p in enumerate(_params(21, 4)):
        write_merl(d / "data" / f"mat-{i}.binary", make_table(*p))
    return d


@pytest.mark.slow
def test_fit_prior_smoke(data, tables):
    from brdfkit.prior.fit import fit_prior

    out = data / "api.safetensors"
    assert fit_prior([data / "data"], out, progress=False, exclude=["nothing-such"], **TINY_FIT) == out
    from brdfkit.models.parts import file_part
    from brdfkit.training import FITTERS

    assert file_part(out).name == FITTERS["prior"].part  # the recipe's part is its file's
    model = load_prior(out)
    assert model.cfg == PriorConfig(n_components=2, latent_dim=4, width=8)
    assert model.basis.n_components == 2 and model.basis.materials == [f"mat-{i}" for i in range(4)]
    assert model.meta["materials"] == [f"mat-{i}" for i in range(4)] and model.meta["steps"] == 3
    assert model.meta["training"]["folds"] == 2
    samples = draw_samples(tables[8], 200, seed=0)
    vals = _on_basis(model.reconstruct(samples), model.basis)
    assert np.isfinite(vals).all() and (vals >= 0).all()
    assert np.isfinite(model.coefficients(samples, use_prior=False)).all()
    assert not [p for p in data.iterdir() if p.name.startswith(".brdfkit-tmp-")]


@pytest.mark.slow
def test_fit_prior_minutes_choose_steps_that_replay(data):
    """``minutes`` chooses the step count once (issue 28): the model records it, and a run
    of that many ``steps`` gives the same weights."""
    from brdfkit.prior.fit import fit_prior

    tiny = {**TINY_FIT, "steps": None}
    fit_prior([data / "data"], data / "m.safetensors", progress=False, minutes=0.002, **tiny)
    meta = load_prior(data / "m.safetensors").meta
    assert meta["budget"]["steps"] == meta["steps"] >= 1
    fit_prior([data / "data"], data / "s.safetensors", progress=False, **{**tiny, "steps": meta["steps"]})
    a, b = load_prior(data / "m.safetensors"), load_prior(data / "s.safetensors")
    assert "budget" not in b.meta
    for x, y in zip(a.net.state_dict().values(), b.net.state_dict().values()):
        np.testing.assert_array_equal(x, y)


def _tiny_args(data, out, **change):
    opts = {k: v for k, v in TINY_FIT.items() if k not in ("steps", "components", "latent_dim", "batch_materials")}
    opts.update(change)
    args = ["fit", "--method", "prior", data / "data", "-o", out, "--steps", 3, "--components", 2,
            "--latent-dim", 4, "--batch-materials", 2, "-q"]
    for k, v in opts.items():
        args += ["-O", f"{k}={v}"]
    return args


@pytest.mark.slow
def test_cli_fit_prior_with_a_compact_basis(data, capsys):
    """``-O basis=FILE``: the model keeps that basis as the file stores it (float16,
    half phi_d), bit for bit."""
    from brdfkit.basis import fit_basis_files

    basis_file = data / "basis.safetensors"
    fit_basis_files([data / "data"], basis_file, progress=False, components=2, half=True, phi_stride=2)
    out = data / "cli.safetensors"
    code, _, err = run_cli(capsys, _tiny_args(data, out, basis=basis_file))
    assert code == 0, err
    model = load_prior(out)
    stored = load_basis(basis_file)
    for k in ("cells", "reference", "mean", "components", "sigma"):
        np.testing.assert_array_equal(getattr(model.basis, k), getattr(stored, k))
    from safetensors import safe_open
    with safe_open(str(out), "numpy") as f:
        meta = f.metadata()
    assert meta["basis.dtype"] == "float16" and meta["basis.phi_d_stride"] == "2"


def _one_line(err):
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("brdfkit: error: ") and "Traceback" not in err, err
    return lines[0]


@pytest.mark.slow
def test_cli_fit_prior_with_a_learnt_spread_and_a_context_range(data, capsys, tmp_path):
    """``-O spread=true -O context_min=5 -O context_max=20`` train (the spread through the
    closed form), and the file records both."""
    out = tmp_path / "spread.safetensors"
    code, _, err = run_cli(capsys, _tiny_args(data, out, spread="true", context_min=5, context_max=20))
    assert code == 0, err
    model = load_prior(out)
    assert model.cfg.spread is True and model.meta["training"]["context"] == [5, 20]
    assert model.net.state_dict()["head.4.weight"].shape[0] == 6 * model.cfg.n_components


@pytest.mark.parametrize("change,extra,message", [
    ({"folds": 1}, [], "folds = 1 is out of range"),
    ({"mixup": 2}, [], "mixup = 2 is out of range"),
    ({"mixup": "abc"}, [], "mixup = 'abc' is out of range"),
    ({"lr": "fast"}, [], "lr = 'fast' is out of range"),
    ({"width": 0}, [], "width = 0 is out of range"),
    ({"lambda_w": -1}, [], "lambda_w = -1 is out of range"),
    ({"weight": "bright"}, [], "weight = 'bright' is out of range"),
    ({"s2": 0}, [], "s2 = 0 is out of range"),
    ({"spread": "yes"}, [], "spread = 'yes' is out of range"),
    ({"context_min": 0}, [], "context_min = 0 is out of range"),
    ({"context_min": 100, "context_max": 50}, [], "context_max = 50 is out of range"),
    ({"no_such_key": 1}, [], "takes only .*not no_such_key"),
    ({}, ["--resume"], "takes only .*not resume"),
    ({"folds": 3}, [], "needs at least 6 training materials .*got 4"),
])
def test_cli_fit_prior_bad_options(data, capsys, tmp_path, change, extra, message):
    out = tmp_path / "bad.safetensors"
    code, _, err = run_cli(capsys, _tiny_args(data, out, **change) + extra)
    assert code == 2, err
    assert re.search(message, _one_line(err)), err
    assert not out.exists()


def test_cli_fit_prior_refuses_to_overwrite_an_input(data, capsys):
    target = data / "data" / "mat-1.binary"
    before = target.read_bytes()
    code, _, err = run_cli(capsys, _tiny_args(data, target))
    assert code == 2 and "mat-1.binary" in _one_line(err)
    assert target.read_bytes() == before


@pytest.mark.parametrize("weight", ["metric", "energy"])
def test_solve_is_the_weighted_ridge_of_its_docstring(weight):
    """``solve`` against the normal equations written out in NumPy, for both likelihood
    weights: ``q = g^2 / s2 + 1 / lam`` (metric) or ``g / s2 + 1 / lam`` (energy)."""
    import torch

    from brdfkit.basis import EPS
    from brdfkit.prior.model import solve

    rng = np.random.default_rng(3)
    s, k = 50, 3
    tab = np.c_[rng.uniform(0.01, 0.5, s), rng.normal(0, 0.3, s), rng.normal(0, 1, (s, k))]
    rho = rng.uniform(0, 3, (s, 3))
    w, cos = rng.uniform(0.05, 1, s), rng.uniform(0.05, 1, s)
    sigma, mu = np.array([2.0, 1.0, 0.5]), rng.normal(0, 1, (3, k))
    s2, lam = 0.03, 0.1
    T = lambda a: torch.from_numpy(np.asarray(a, np.float64))[None]  # noqa: E731
    c, _ = solve(T(tab), T(rho), T(w), T(cos), T(sigma), s2, lam, mu=T(mu), weight=weight)
    b = np.log((rho * w[:, None] + EPS) / (tab[:, :1] + EPS)) - tab[:, 1:2]
    g = cos[:, None] * (rho + EPS / w[:, None]) / (1 + rho * cos[:, None])
    q = (g if weight == "energy" else g ** 2) / s2 + 1 / lam
    for ch in range(3):
        a = tab[:, 2:]
        want = np.linalg.solve(a.T @ (a * q[:, ch:ch + 1]) + np.diag(sigma ** -2),
                               a.T @ (q[:, ch] * b[:, ch]) + mu[ch] / sigma ** 2)
        np.testing.assert_allclose(c[0, ch].numpy(), want, rtol=1e-4, atol=1e-5)
    other, _ = solve(T(tab), T(rho), T(w), T(cos), T(sigma), s2, lam, mu=T(mu),
                     weight="metric" if weight == "energy" else "energy")
    assert not np.allclose(other.numpy(), c.numpy(), atol=1e-3)


def test_a_config_the_fit_cannot_use_is_refused():
    from brdfkit.prior.model import PriorConfig

    for bad in ({"weight": "bright"}, {"s2": 0.0}, {"lam": -1.0}):
        with pytest.raises(ValueError):
            PriorConfig(**bad)
    assert PriorConfig().weight == "metric"  # model files from before the option read as they were


def test_solve_takes_a_prior_spread_per_channel():
    """A ``(B, 3, K)`` ``sigma`` (the learnt spread) is each channel's own ridge, and one
    that repeats the basis's ``sigma`` is the ``(B, K)`` fit."""
    import torch

    rng = np.random.default_rng(4)
    s, k = 40, 3
    tab = np.c_[rng.uniform(0.01, 0.5, s), rng.normal(0, 0.3, s), rng.normal(0, 1, (s, k))]
    rho, w, cos = rng.uniform(0, 3, (s, 3)), rng.uniform(0.05, 1, s), rng.uniform(0.05, 1, s)
    sigma, mu = np.array([2.0, 1.0, 0.5]), rng.normal(0, 1, (3, k))
    sd = sigma * np.exp(rng.normal(0, 1, (3, k)))
    T = lambda a: torch.from_numpy(np.asarray(a, np.float64))[None]  # noqa: E731
    args = (T(tab), T(rho), T(w), T(cos))
    same, _ = solve(*args, T(np.tile(sigma, (3, 1))), 0.03, 0.1, mu=T(mu), weight="energy")
    flat, _ = solve(*args, T(sigma), 0.03, 0.1, mu=T(mu), weight="energy")
    np.testing.assert_allclose(same.numpy(), flat.numpy(), rtol=1e-6)
    c, _ = solve(*args, T(sd), 0.03, 0.1, mu=T(mu), weight="energy")
    for ch in range(3):
        want, _ = solve(*args, T(sd[ch]), 0.03, 0.1, mu=T(mu), weight="energy")
        np.testing.assert_allclose(c[0, ch].numpy(), want[0, ch].numpy(), rtol=1e-6)
    assert not np.allclose(c.numpy(), flat.numpy(), atol=1e-3)


def test_a_model_with_a_learnt_spread_round_trips_and_starts_as_the_plain_fit(basis, tables, tmp_path):
    """``spread=True``: an untrained head keeps ``sigma`` (the plain fit); a trained one
    changes the fit; the file keeps the option and reconstructs the same to the bit. Files
    without it record no ``spread`` (their digests stay as they were)."""
    import torch
    from safetensors import safe_open

    from brdfkit.prior.model import SPREAD_LOG_BOUND

    cfg = dataclasses.replace(CFG, spread=True)
    net = prior_net(cfg).eval()
    model = PriorModel(basis, net, cfg, {"materials": list(basis.materials)})
    samples = draw_samples(tables[8], 200, seed=2)
    np.testing.assert_array_equal(model.coefficients(samples), model.coefficients(samples, use_prior=False))
    with torch.no_grad():
        net.head[-1].bias[3 * cfg.n_components:] = 2 * SPREAD_LOG_BOUND  # beyond the bound: clipped
    sig = torch.ones(1, cfg.n_components)
    with torch.no_grad():
        _, sd, _, raw = net(torch.zeros(1, 5, 6), torch.zeros(1, 5, 3), torch.zeros(1, 3, cfg.n_components), sig, 5)
    assert raw.shape == (1, 6, cfg.n_components)
    np.testing.assert_allclose(sd.numpy(), np.exp(SPREAD_LOG_BOUND), rtol=1e-6)
    loose = model.coefficients(samples)
    assert not np.allclose(loose, model.coefficients(samples, use_prior=False))
    path = tmp_path / "spread.safetensors"
    save_prior(path, model)
    back = load_prior(path)
    assert back.cfg.spread is True
    np.testing.assert_array_equal(back.coefficients(samples), loose)
    plain = tmp_path / "plain.safetensors"
    save_prior(plain, _model(basis))
    with safe_open(str(plain), "np") as f:
        assert "spread" not in json.loads(f.metadata()["config"])
    with pytest.raises(ValueError):
        PriorConfig(spread="yes")


@pytest.mark.slow
def test_sparse_with_the_default_learnt_prior_imports_no_torch(tmp_path, monkeypatch):
    """``brdfkit sparse samples.csv -o out.binary`` with the shipped default model (its
    learnt prior) runs in a fresh interpreter without importing torch, and writes the
    table the library's reconstruction gives."""
    import os
    import subprocess
    import sys

    from brdfkit.io.merl import read_merl
    from brdfkit.io.samples import write_samples
    from brdfkit.models.builtin import models_folder, read_manifest
    from brdfkit.testing.examples import lambertian_table

    monkeypatch.delenv("BRDFKIT_BUILTIN_MODELS", raising=False)
    monkeypatch.delenv("BRDFKIT_MODEL", raising=False)
    default = next((m for m in read_manifest(models_folder()).installed() if m.default), None)
    if default is None or default.part("prior") is None:
        pytest.skip("no shipped default model with a learnt prior in this checkout")
    samples = draw_samples(lambertian_table(), 40, seed=0)
    write_samples(tmp_path / "s.csv", samples)
    code = ("import sys\nfrom brdfkit.cli import main\n"
            "try:\n    main(['sparse', 's.csv', '-o', 'out.binary'])\nexcept SystemExit as e:\n"
            "    assert not e.code, e.code\n"
            "print('TORCH', 'torch' in sys.modules)")
    r = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=300,
                       env={**os.environ, "OMP_NUM_THREADS": "1"})
    assert r.returncode == 0 and "method prior" in r.stderr, r.stderr[-2000:]
    assert r.stdout.split()[-2:] == ["TORCH", "False"]
    want = get_method("prior").reconstruct(samples, default.name)
    got = read_merl(tmp_path / "out.binary")
    np.testing.assert_array_equal(np.isnan(got), np.isnan(want))
    np.testing.assert_allclose(got[np.isfinite(got)], want[np.isfinite(want)], rtol=1e-5)
