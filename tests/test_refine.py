"""Test-time refinement of a hypernetwork's reconstruction (:mod:`brdfkit.hypernet.refine_on_samples`)
and ``brdfkit sparse --refine``: it fits the samples, declines when the held-out samples
say so, is deterministic, leaves the model untouched, and its CLI refuses what makes no
sense with a one-line error."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from brdfkit import api
from brdfkit.cli import main
from brdfkit.errors import InputError
from brdfkit.io.embedding import read_embedding
from brdfkit.io.merl import read_merl
from brdfkit.evaluation.metrics import brdf_log_rmse
from brdfkit.hypernet.refine_on_samples import RefineConfig, refine
from brdfkit.io.samples import SampleSet, write_samples
from brdfkit.acquisition.sampling import draw_samples

from helpers_model import make_model, material_table


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    d = tmp_path_factory.mktemp("refine")
    make_model(d / "model.safetensors", seed=0)
    model = api.load_model(d / "model.safetensors", "cpu")
    samples = draw_samples(material_table(1), 400, seed=0)
    write_samples(d / "samples.csv", samples)
    return d, model, samples


def _sample_mse(model, brdf, samples):
    hd = torch.from_numpy(samples.hd()).float()
    rho = brdf.eval_hd(hd).double().numpy()
    c = samples.cos_i()[:, None]
    return float(np.mean((np.log1p(rho * c) - np.log1p(samples.rgb * c)) ** 2))


@pytest.mark.slow
def test_latent_refinement_fits_the_samples_and_the_material(setup):
    _, model, samples = setup
    emb = api.encode(samples, model)
    before = api.decode(emb, model)
    r = refine(model, samples, emb, config=RefineConfig(max_steps=200))
    assert 0 < r.steps["latent"] <= 200 and r.steps["latent"] % 10 == 0
    held_before, held_after = r.heldout["latent"]
    assert held_after < held_before
    # The samples' own error must fall (an untrained tiny decoder moves little with its
    # latent: the margin is small but real; the weights stage below has the freedom).
    from brdfkit.hypernet.neural_brdf import NeuralBRDF

    assert _sample_mse(model, r.brdf, samples) < _sample_mse(model, NeuralBRDF.from_embedding(model, emb), samples)
    assert np.isfinite(before).any()
    # The embedding is the refined latent: decoding it gives the refined material.
    np.testing.assert_allclose(api.decode(r.embedding, model), r.brdf.to_table(), rtol=1e-6, equal_nan=True)
    assert r.embedding.sample_count == 400 and r.embedding.decoder == model.digest


@pytest.mark.slow
def test_weights_stage_and_model_untouched(setup):
    _, model, samples = setup
    params = [p.detach().clone() for p in model.net.parameters()]
    flags = [p.requires_grad for p in model.net.parameters()]
    r1 = refine(model, samples, config=RefineConfig(target="weights", max_steps=60, lr_weights=0.01), seed=3)
    r2 = refine(model, samples, config=RefineConfig(target="weights", max_steps=60, lr_weights=0.01), seed=3)
    assert set(r1.steps) == {"latent", "weights"} and r1.steps["weights"] > 0
    assert r1.heldout["weights"][1] < r1.heldout["weights"][0]
    latent_only = refine(model, samples, config=RefineConfig(max_steps=60), seed=3)
    # The hyponet's own weights reach what no latent decodes to, on the samples and on
    # the whole material.
    assert _sample_mse(model, r1.brdf, samples) < 0.9 * _sample_mse(model, latent_only.brdf, samples)
    truth = material_table(1)
    assert brdf_log_rmse(r1.brdf.to_table(), truth) < brdf_log_rmse(latent_only.brdf.to_table(), truth)
    np.testing.assert_array_equal(r1.brdf.to_table(), r2.brdf.to_table())  # deterministic
    for p, q, f in zip(model.net.parameters(), params, flags):
        assert torch.equal(p, q) and p.requires_grad == f


@pytest.mark.slow
def test_declined_when_too_few_samples_or_no_gain(setup):
    _, model, samples = setup
    few = draw_samples(material_table(1), 5, seed=1)
    emb = api.encode(few, model)
    r = refine(model, few, emb)
    assert r.steps == {"latent": 0}
    np.testing.assert_array_equal(r.brdf.to_table(), api.decode(emb, model))
    # A learning rate of zero cannot improve the held-out samples: 0 steps are chosen
    # and the encoder's answer comes back unchanged.
    emb = api.encode(samples, model)
    r = refine(model, samples, emb, config=RefineConfig(lr_latent=0.0, max_steps=30))
    assert r.steps["latent"] == 0
    np.testing.assert_array_equal(r.embedding.values, emb.values)


def test_nan_samples_are_left_out(setup):
    _, model, samples = setup
    rgb = samples.rgb.copy()
    rgb[7] = np.nan
    with_nan = SampleSet(samples.theta_h, samples.theta_d, samples.phi_d, rgb)
    keep = np.arange(len(samples)) != 7
    without = SampleSet(samples.theta_h[keep], samples.theta_d[keep], samples.phi_d[keep], samples.rgb[keep])
    emb = api.encode(without, model)
    cfg = RefineConfig(max_steps=30)
    a = refine(model, with_nan, emb, config=cfg).brdf.to_table()
    b = refine(model, without, emb, config=cfg).brdf.to_table()
    np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("bad", [dict(target="bias"), dict(holdout=1.0), dict(max_steps=0)])
def test_bad_config(bad):
    with pytest.raises(InputError):
        RefineConfig(**bad)


def _cli(capsys, args):
    with pytest.raises(SystemExit) as e:
        main([str(a) for a in args])
    return e.value.code, capsys.readouterr().err


@pytest.mark.slow
def test_cli_refine(setup, tmp_path, capsys):
    d, model, samples = setup
    args = ["sparse", d / "samples.csv", "-m", d / "model.safetensors", "--method", "hypernet"]
    code, err = _cli(capsys, args + ["-o", tmp_path / "r.binary", "--refine", "--emb", tmp_path / "r.emb"])
    assert code == 0, err
    code, err = _cli(capsys, args + ["-o", tmp_path / "p.binary", "--no-refine"])
    assert code == 0, err
    refined, plain = read_merl(tmp_path / "r.binary"), read_merl(tmp_path / "p.binary")
    from brdfkit.methods import get_method
    from brdfkit.io.samples import read_samples

    table, emb = get_method("hypernet").sparse(read_samples(d / "samples.csv"), model, refine_target="latent")
    np.testing.assert_allclose(refined, table, rtol=1e-12, equal_nan=True)
    np.testing.assert_array_equal(read_embedding(tmp_path / "r.emb").values, emb.values)
    assert not np.allclose(refined, plain, equal_nan=True)
    code, err = _cli(capsys, args + ["-o", tmp_path / "w.binary"])  # the default: weights
    assert code == 0 and "refined on the samples (weights)" in err, err
    np.testing.assert_allclose(read_merl(tmp_path / "w.binary"),
                               get_method("hypernet").reconstruct(read_samples(d / "samples.csv"), model),
                               rtol=1e-12, equal_nan=True)


@pytest.mark.parametrize("extra, message", [
    (["--refine-target", "weights", "--emb", "x.emb"], "have no embedding"),
    (["--no-refine", "--refine-target", "latent"], "needs --refine"),
    (["--method", "ipca", "--refine"], "apply to --method hypernet"),
])
def test_cli_refine_refusals(setup, tmp_path, capsys, extra, message):
    d, _, _ = setup
    extra = [str(tmp_path / e) if e.endswith(".emb") else e for e in extra]
    code, err = _cli(capsys, ["sparse", d / "samples.csv", "-m", d / "model.safetensors",
                              "-o", tmp_path / "o.binary", *extra])
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert code == 2 and len(lines) == 1 and message in lines[0], err
    assert not (tmp_path / "o.binary").exists()
