"""Embedding files: exact round trip, small self-describing JSON, every bad input refused."""

from __future__ import annotations

import json
import types

import numpy as np
import pytest

from brdfkit.io.embedding import Embedding, check_compatible, read_embedding, write_embedding
from brdfkit.errors import FormatError, ModelMismatchError

from conftest import format_error

FP = "ab" * 32


def _emb(dim=40, seed=0, fp=FP):
    rng = np.random.default_rng(seed)
    # Values across many magnitudes, including ones whose float32 decimal repr is long.
    lat = (rng.normal(size=dim) * 10.0 ** rng.integers(-6, 3, dim)).astype(np.float32)
    return Embedding(lat, fp, "teflon.binary", 1234)


def test_round_trip_exact(tmp_path):
    e = _emb()
    write_embedding(tmp_path / "a.emb", e)
    r = read_embedding(tmp_path / "a.emb")
    assert r.latent.dtype == np.float32 and r.latent_dim == 40
    np.testing.assert_array_equal(r.latent, e.latent)
    assert (r.model_fingerprint, r.source, r.sample_count) == (FP, "teflon.binary", 1234)


def test_small_self_describing_json(tmp_path):
    write_embedding(tmp_path / "a.emb", _emb())
    text = (tmp_path / "a.emb").read_text()
    assert len(text) < 4096
    doc = json.loads(text)
    assert doc["format"] == "brdfkit-embedding" and doc["version"] == 1
    assert doc["latent_dim"] == 40 == len(doc["latent"])
    assert set(doc) == {"format", "version", "latent_dim", "latent", "model_fingerprint", "source",
                        "sample_count"}


def test_write_refuses_non_finite(tmp_path):
    e = _emb()
    e.latent[3] = np.nan
    with pytest.raises(ValueError):
        write_embedding(tmp_path / "a.emb", e)
    assert not (tmp_path / "a.emb").exists()


def _doc():
    return json.loads(json.dumps({"format": "brdfkit-embedding", "version": 1, "latent_dim": 3,
                                  "latent": [0.5, -1.0, 2.0], "model_fingerprint": FP,
                                  "source": "x", "sample_count": 3}))


BAD_DOCS = {
    "wrong version": (lambda d: d.update(version=2), "version 2 is not supported"),
    "version as text": (lambda d: d.update(version="1"), "version '1' is not supported"),
    "version as float": (lambda d: d.update(version=1.0), "version 1.0 is not supported"),
    "wrong format": (lambda d: d.update(format="something-else"), "not a brdfkit embedding"),
    "no format": (lambda d: d.pop("format"), "not a brdfkit embedding"),
    "short latent": (lambda d: d.update(latent=[0.5, 1.0]), "latent has 2 values but latent_dim is 3"),
    "long latent": (lambda d: d.update(latent=[0.5] * 4), "latent has 4 values but latent_dim is 3"),
    "latent_dim zero": (lambda d: d.update(latent_dim=0, latent=[]), "latent_dim must be a positive"),
    "latent not a list": (lambda d: d.update(latent="0.5,1,2"), "must be a list"),
    "text in latent": (lambda d: d["latent"].__setitem__(1, "x"), r"latent\[1\] is 'x', not a number"),
    "bool in latent": (lambda d: d["latent"].__setitem__(0, True), r"latent\[0\] is True"),
    "huge value": (lambda d: d["latent"].__setitem__(2, 1e300), "not a finite float32"),
    "no fingerprint": (lambda d: d.pop("model_fingerprint"), "model_fingerprint"),
    "negative count": (lambda d: d.update(sample_count=-1), "sample_count"),
    "source not text": (lambda d: d.update(source=5), "'source' must be a string"),
}


@pytest.mark.parametrize("case", sorted(BAD_DOCS))
def test_bad_documents(tmp_path, case):
    edit, message = BAD_DOCS[case]
    d = _doc()
    edit(d)
    path = tmp_path / "bad.emb"
    path.write_text(json.dumps(d))
    format_error(read_embedding, path, message)


@pytest.mark.parametrize("raw", [b"", b"not json", b"[1, 2, 3]", b'"a string"', b"\xff\xfe\x00binary",
                                 b'{"format": "brdfkit-embedding", "version": 1, "latent_dim": 1, '
                                 b'"latent": [NaN], "model_fingerprint": "x"}'])
def test_not_an_embedding(tmp_path, raw):
    format_error(read_embedding, tmp_path / "bad.emb", content=raw)


def test_huge_file_refused_quickly(tmp_path):
    path = tmp_path / "big.emb"
    path.write_bytes(b" " * (2 << 20))
    with pytest.raises(FormatError, match="a few kB"):
        read_embedding(path)


def test_merl_file_is_not_an_embedding(tmp_path):
    path = tmp_path / "x.emb"
    path.write_bytes(np.array([90, 90, 180], "<i4").tobytes() + b"\x00" * 800)
    with pytest.raises(FormatError, match="not JSON"):
        read_embedding(path)


def test_check_compatible():
    model = types.SimpleNamespace(fingerprint=FP, cfg=types.SimpleNamespace(latent_dim=40),
                                  path="/m/model.safetensors")
    check_compatible(_emb(), model)
    other = _emb(fp="cd" * 32)
    with pytest.raises(ModelMismatchError) as e:
        check_compatible(other, model, "x.emb")
    msg = str(e.value)
    assert "cdcdcdcdcdcd" in msg and "abababababab" in msg and "x.emb" in msg and "model.safetensors" in msg
    with pytest.raises(ModelMismatchError, match="latent 7.*latent 40"):
        check_compatible(_emb(dim=7), model)
