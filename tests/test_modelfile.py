"""Model files: round trip, digest, and every way a file can be refused."""

from __future__ import annotations

import json
import os
import pickle
import re

import numpy as np
import pytest
import torch

from brdfkit.errors import FormatError, InputError
from brdfkit.hypernet.network import HyperBRDF, HyperConfig
from brdfkit.hypernet.network_file import MODEL_FORMAT, load_network, save_network, weights_digest

from conftest import TINY_CONFIG, format_error
from helpers_model import make_model, material_table


@pytest.fixture(scope="module")
def model_path(tmp_path_factory):
    path = tmp_path_factory.mktemp("modelfile") / "tiny.safetensors"
    make_model(path)
    return path


def _raw(path):
    from safetensors.torch import load_file
    from safetensors import safe_open

    with safe_open(str(path), framework="pt") as f:
        meta = f.metadata()
    return load_file(str(path)), meta


def _resave(src, dst, edit_tensors=None, edit_meta=None):
    from safetensors.torch import save_file

    tensors, meta = _raw(src)
    if edit_tensors:
        edit_tensors(tensors)
    if edit_meta:
        edit_meta(meta)
    save_file(tensors, str(dst), metadata=meta)
    return dst


def test_round_trip(model_path):
    torch.manual_seed(0)
    net = HyperBRDF(HyperConfig(**TINY_CONFIG))
    m = load_network(model_path, device="cpu")
    assert m.cfg == net.cfg
    assert m.digest == weights_digest(net) == weights_digest(m.net)
    for (k, a), (k2, b) in zip(sorted(net.state_dict().items()), sorted(m.net.state_dict().items())):
        assert k == k2 and torch.equal(a, b)
    ref = material_table(0).astype(np.float32)
    assert m.rho_ref.dtype == np.float32 and m.rho_ref.shape == (90, 90, 180, 3)
    np.testing.assert_array_equal(m.rho_ref, ref)  # NaN in the same places
    assert m.meta == {"materials": ["stiff-white"], "steps": 0}
    assert not m.net.training
    assert all(not p.requires_grad for p in m.net.parameters())
    assert m.device == torch.device("cpu") and m.path == str(model_path)


def test_default_device_and_metadata(model_path):
    m = load_network(model_path)
    assert m.device.type == ("cuda" if torch.cuda.is_available() else "cpu")
    _, meta = _raw(model_path)
    assert meta["format"] == MODEL_FORMAT and meta["version"] == "1"
    assert HyperConfig.from_json(meta["config"]) == HyperConfig(**TINY_CONFIG)
    assert json.loads(meta["meta"])["steps"] == 0


def test_mapping_is_recorded(model_path):
    # The model decodes correctly only with the mapping it was trained with (eq. 1,
    # eps = 0.002): the file says which, and the loaded model carries it.
    from brdfkit.hypernet.mapping import EPS, mapping_record

    _, meta = _raw(model_path)
    rec = json.loads(meta["mapping"])
    assert rec == mapping_record() and rec["eps"] == EPS == 0.002 and rec["name"] == "log-relative"
    assert load_network(model_path, "cpu").mapping == rec


def test_file_without_mapping_loads_as_the_papers(model_path, tmp_path):
    # Files written before the mapping was recorded were all trained with the paper's.
    from brdfkit.hypernet.mapping import mapping_record

    old = _resave(model_path, tmp_path / "old.safetensors", edit_meta=lambda m: m.pop("mapping"))
    _, meta = _raw(old)
    assert "mapping" not in meta
    m = load_network(old, "cpu")
    assert m.mapping == mapping_record()
    assert m.digest == load_network(model_path, "cpu").digest


@pytest.mark.parametrize("mapping, message", [
    ('{"name": "log-relative", "eps": 0.001}', "trained with the 'log-relative' mapping with eps = 0.001; "
                                               "this brdfkit maps with 'log-relative', eps = 0.002"),
    ('{"name": "log", "eps": 0.002}', "trained with the 'log' mapping with eps = 0.002"),
    ('{"name": "log-relative"}', "bad 'mapping' in metadata: not an object with a name and a numeric eps"),
    ("[0.002]", "bad 'mapping' in metadata: not an object with a name and a numeric eps"),
    ("eps=0.002", "bad 'mapping' in metadata: not JSON"),
])
def test_other_mapping_refused(model_path, tmp_path, mapping, message):
    bad = _resave(model_path, tmp_path / "m.safetensors", edit_meta=lambda m: m.update(mapping=mapping))
    with pytest.raises(FormatError, match=re.escape(message)):
        load_network(bad, "cpu")


def test_digest_tracks_weights():
    torch.manual_seed(1)
    net = HyperBRDF(HyperConfig(**TINY_CONFIG))
    a = weights_digest(net)
    assert a == weights_digest(net) and len(a) == 64
    with torch.no_grad():
        next(net.parameters()).view(-1)[0] += 1e-6
    assert weights_digest(net) != a


def test_wrapper_is_unwrapped(tmp_path):
    """A DDP-style wrapper (``.module``) saves the same names and digest as the bare net."""
    torch.manual_seed(2)
    net = HyperBRDF(HyperConfig(**TINY_CONFIG))

    class Wrapper(torch.nn.Module):
        def __init__(self, m):
            super().__init__()
            self.module = m

    fp = save_network(tmp_path / "w.safetensors", Wrapper(net), material_table(0))
    assert fp == weights_digest(net) == load_network(tmp_path / "w.safetensors", "cpu").digest


def test_default_architecture_round_trip(tmp_path):
    fp = make_model(tmp_path / "default.safetensors", config={})
    m = load_network(tmp_path / "default.safetensors", "cpu")
    assert m.digest == fp and m.cfg == HyperConfig()
    # The paper's architecture: hyponet 6 -> 60 x 4 -> 3 (11,583 predicted numbers).
    assert sum(w.numel() + b.numel() for w, b in m.net.hyponet_weights(torch.zeros(1, 40))) == 11583


def test_truncated(model_path, tmp_path):
    data = model_path.read_bytes()
    for n, what in ((len(data) // 2, "truncated"), (len(data) - 1, "truncated"),
                    (100, "truncated"), (5, "too short")):
        format_error(load_network, tmp_path / f"cut{n}.safetensors", what, content=data[:n])


class _Trap:
    """Unpickling this creates a folder: proof that a loader executed the pickle."""

    def __init__(self, marker):
        self.marker = marker

    def __reduce__(self):
        return (os.mkdir, (self.marker,))


@pytest.mark.parametrize("kind", ["pickle", "torch.save"])
def test_pickle_is_never_loaded(tmp_path, kind):
    marker = str(tmp_path / "unpickled")
    bad = tmp_path / "model.safetensors"
    if kind == "pickle":
        bad.write_bytes(pickle.dumps({"net": _Trap(marker)}))
    else:
        torch.save({"net": _Trap(marker)}, bad)
    with pytest.raises(FormatError, match="pickle") as e:
        load_network(bad)
    assert not os.path.exists(marker)
    assert "\n" not in str(e.value)


@pytest.mark.parametrize("content", [b"", b"hello, this is a text file\n", b"\x00" * 64,
                                     b"\x10\x00\x00\x00\x00\x00\x00\x00not json at all!",
                                     os.urandom(4096)])
def test_not_safetensors(tmp_path, content):
    format_error(load_network, tmp_path / "junk.safetensors", content=content)


def test_other_safetensors_refused(tmp_path):
    from brdfkit.hypernet.mapping import save_reference

    path = tmp_path / "ref.safetensors"
    save_reference(path, material_table(0))
    with pytest.raises(FormatError, match="not a brdfkit model file"):
        load_network(path)


def test_wrong_version(model_path, tmp_path):
    bad = _resave(model_path, tmp_path / "v3.safetensors", edit_meta=lambda m: m.update(version="3"))
    with pytest.raises(FormatError, match=r"version '3' is not supported \(this brdfkit reads version 1 or 2\)"):
        load_network(bad)


def test_bad_config(model_path, tmp_path):
    bad = _resave(model_path, tmp_path / "cfg.safetensors",
                  edit_meta=lambda m: m.update(config='{"latent_dim": 7, "colour": 1}'))
    with pytest.raises(FormatError, match="bad model config"):
        load_network(bad)


def test_missing_tensors(model_path, tmp_path):
    bad = _resave(model_path, tmp_path / "noref.safetensors", edit_tensors=lambda t: t.pop("rho_ref"))
    with pytest.raises(FormatError, match="rho_ref"):
        load_network(bad)
    first = sorted(k for k in _raw(model_path)[0] if k.startswith("net."))[0]
    bad = _resave(model_path, tmp_path / "nonet.safetensors", edit_tensors=lambda t: t.pop(first))
    with pytest.raises(FormatError, match="missing tensor"):
        load_network(bad)


def test_misshapen_tensor(model_path, tmp_path):
    name = sorted(k for k in _raw(model_path)[0] if k.startswith("net."))[0]
    bad = _resave(model_path, tmp_path / "shape.safetensors",
                  edit_tensors=lambda t: t.update({name: torch.zeros(3, 3)}))
    with pytest.raises(FormatError, match="has shape"):
        load_network(bad)


def test_altered_weights_refused(model_path, tmp_path):
    name = sorted(k for k in _raw(model_path)[0] if k.startswith("net."))[0]

    def nudge(t):
        t[name] = t[name].clone()
        t[name].view(-1)[0] += 1.0

    bad = _resave(model_path, tmp_path / "altered.safetensors", edit_tensors=nudge)
    with pytest.raises(FormatError, match="digest"):
        load_network(bad)


def test_missing_file(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        load_network(tmp_path / "nope.safetensors")


def test_merl_table_given_as_model(tmp_path):
    from brdfkit.io.merl import write_merl

    path = tmp_path / "teflon.binary"
    write_merl(path, material_table(0))
    with pytest.raises(FormatError, match="is a MERL BRDF table, not a brdfkit model file"):
        load_network(path)
