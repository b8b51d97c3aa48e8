"""The architecture and training options added to measure issue 12's levers: attention
pooling in the set encoder, encoder dropout, weight decay. Each does what it says, keeps
the encoder a set function, and leaves the files and checkpoints of models trained
before the options existed reading as they did."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from brdfkit import api
from brdfkit.errors import InputError
from brdfkit.hypernet.mapping import to_mapped
from brdfkit.hypernet.network import HyperBRDF, HyperConfig
from brdfkit.acquisition.sampling import draw_samples
from brdfkit.hypernet.training.loop import TrainOptions, fit

from conftest import TINY, TINY_CONFIG, TINY_LATENT
from helpers_model import make_model, material_table
from helpers_training import tiny_library


@pytest.fixture(scope="module")
def attention_model(tmp_path_factory):
    path = tmp_path_factory.mktemp("levers") / "attention.safetensors"
    make_model(path, config=dict(TINY_CONFIG, pooling="attention", encoder_dropout=0.3))
    return api.load_model(path, "cpu")


def _net_latent(model, samples):
    hd = torch.from_numpy(samples.hd()).float()[None]
    ref = model.reference_at(samples.theta_h, samples.theta_d, samples.phi_d)
    mapped = torch.from_numpy(to_mapped(samples.rgb, ref)).float()[None]
    with torch.no_grad():
        return model.net.encode(hd, mapped)[0].double().numpy()


def test_attention_pooling_fused_encode_matches_the_network(attention_model):
    m = attention_model
    assert m.cfg.pooling == "attention" and m.net.encoder.attention is not None
    # 9,000 samples: three chunks of the fused encoder, each rescaled by the running maximum.
    s = draw_samples(material_table(1), 9000, seed=0)
    np.testing.assert_allclose(api.encode(s, m).values, _net_latent(m, s), atol=2e-6)


def test_attention_pooling_is_a_set_function(attention_model):
    m = attention_model
    s = draw_samples(material_table(1), 300, seed=1)
    perm = np.random.default_rng(0).permutation(300)
    from brdfkit.io.samples import SampleSet

    shuffled = SampleSet(s.theta_h[perm], s.theta_d[perm], s.phi_d[perm], s.rgb[perm])
    np.testing.assert_allclose(api.encode(s, m).values, api.encode(shuffled, m).values, atol=1e-6)
    one = SampleSet(s.theta_h[:1], s.theta_d[:1], s.phi_d[:1], s.rgb[:1])
    assert np.isfinite(api.encode(one, m).values).all()
    # Scores far beyond exp's range (a bright peak) stay finite: the running maximum.
    with torch.no_grad():
        m.net.encoder.attention.bias.add_(1e4)
    try:
        m.cache.encoder.clear()
        assert np.isfinite(api.encode(s, m).values).all()
    finally:
        with torch.no_grad():
            m.net.encoder.attention.bias.sub_(1e4)


def test_dropout_only_in_training():
    torch.manual_seed(0)
    net = HyperBRDF(HyperConfig(**dict(TINY_CONFIG, encoder_dropout=0.5)))
    x = torch.randn(1, 50, 6), torch.randn(1, 50, 3)
    net.train()
    assert not torch.equal(net.encode(*x), net.encode(*x))
    net.eval()
    assert torch.equal(net.encode(*x), net.encode(*x))


def test_old_configs_and_checkpoints_read_as_before():
    cfg = HyperConfig(**TINY_CONFIG)
    text = cfg.to_json()
    assert "pooling" not in text and "encoder_dropout" not in text  # as written before the options
    assert HyperConfig.from_json(text) == cfg
    assert "weight_decay" not in TrainOptions().identity_json()
    assert json.loads(HyperConfig(pooling="attention").to_json())["pooling"] == "attention"
    assert "weight_decay" in TrainOptions(weight_decay=0.01).identity_json()
    with pytest.raises(ValueError):
        HyperConfig(pooling="max")


@pytest.mark.slow
def test_weight_decay_shrinks_the_weights(tmp_path_factory, tmp_path):
    lib = tiny_library(tmp_path_factory)
    kw = {**TINY, "latent_dim": TINY_LATENT, "progress": False, "steps": 10}
    norms = {}
    for wd in (0.0, 1.0):
        out = tmp_path / f"wd{wd}.safetensors"
        fit(lib, out, weight_decay=wd, **kw)
        net = api.load_model(out, "cpu").net
        norms[wd] = float(sum(p.detach().double().pow(2).sum() for p in net.parameters()))
    assert norms[1.0] < 0.99 * norms[0.0]


@pytest.mark.parametrize("bad", [{"weight_decay": -1.0}, {"pooling": "max"}, {"encoder_dropout": 1.0}])
def test_bad_lever_options(tmp_path_factory, tmp_path, bad):
    lib = tiny_library(tmp_path_factory)
    with pytest.raises(InputError):
        fit(lib, tmp_path / "x.safetensors", **{**TINY, "latent_dim": TINY_LATENT, "progress": False,
                                                "steps": 1, **bad})


def test_mixup_mixes_two_materials_and_leaves_the_default_batches(tmp_path_factory):
    from brdfkit.hypernet.training.dataset import BatchSampler, TrainingSet

    lib = tiny_library(tmp_path_factory)
    paths = sorted(str(p) for p in lib.glob("*.binary"))
    tset = TrainingSet.load(paths, [p.rsplit("/", 1)[-1] for p in paths])
    args = (tset, torch.device("cpu"), 3, 64, 20, 40, 7)
    plain = BatchSampler(*args).draw(5)
    for a, b in zip(plain, BatchSampler(*args, mixup=0.0).draw(5)):
        assert torch.equal(a, b)
    # Material m set to the constant m + 1 everywhere: a slot of material a mixed with b
    # holds t (a + 1) + (1 - t)(b + 1), one value for all its cells, strictly between
    # (unless b = a) and never a whole number for t in (0, 1).
    samplers = [BatchSampler(*args, mixup=p) for p in (0.0, 1.0)]
    for smp in samplers:
        smp.values = (torch.arange(smp.values.shape[0], dtype=torch.float32)[:, None, None] + 1
                      ).expand_as(smp.values).contiguous()
    own, mixed = samplers[0].draw(5), samplers[1].draw(5)
    assert torch.equal(plain[0], mixed[0]) and torch.equal(plain[2], mixed[2])  # same cells
    m = tset.values.shape[0]
    for b in range(3):
        for k in (1, 3):  # context and query alike
            v = mixed[k][b]
            assert torch.allclose(v, v.flatten()[0].expand_as(v))
            assert 1.0 <= float(v.flatten()[0]) <= m
    assert not torch.equal(own[3], mixed[3])
