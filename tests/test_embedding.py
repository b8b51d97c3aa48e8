"""Embedding files: exact round trip, small self-describing JSON, version 1 files read as the
same embeddings, every bad input refused."""

from __future__ import annotations

import json
import types

import numpy as np
import pytest

from brdfkit.io.embedding import Embedding, read_embedding, write_embedding
from brdfkit.errors import FormatError, ModelMismatchError

from conftest import format_error

FP = "ab" * 32


def _emb(dim=40, seed=0, fp=FP, kind="hypernet"):
    rng = np.random.default_rng(seed)
    # Values across many magnitudes, including ones whose float32 decimal repr is long.
    lat = (rng.normal(size=dim) * 10.0 ** rng.integers(-6, 3, dim)).astype(np.float32)
    return Embedding(lat, kind, fp, "teflon.binary", 1234)


@pytest.mark.parametrize("kind", ["hypernet", "basis"])
def test_round_trip_exact(tmp_path, kind):
    e = _emb(39, kind=kind)
    write_embedding(tmp_path / "a.emb", e)
    r = read_embedding(tmp_path / "a.emb")
    assert r.values.dtype == np.float32 and r.size == 39 and r.kind == kind
    np.testing.assert_array_equal(r.values, e.values)
    assert (r.decoder, r.source, r.sample_count) == (FP, "teflon.binary", 1234)


def test_small_self_describing_json(tmp_path):
    write_embedding(tmp_path / "a.emb", _emb())
    text = (tmp_path / "a.emb").read_text()
    assert len(text) < 4096
    doc = json.loads(text)
    assert doc["format"] == "brdfkit-embedding" and doc["version"] == 2
    assert doc["size"] == 40 == len(doc["values"]) and doc["kind"] == "hypernet" and doc["decoder"] == FP
    assert set(doc) == {"format", "version", "kind", "size", "values", "decoder", "source", "sample_count"}


@pytest.mark.parametrize("basis", [None, "cd" * 32])
def test_version_1_files_read_as_the_same_embedding(tmp_path, basis):
    """A version 1 file: a latent and its model's digest (``model_fingerprint``), or (with
    ``basis``) the coefficients of that basis file."""
    doc = _doc()
    if basis:
        doc["basis"] = basis
    (tmp_path / "v1.emb").write_text(json.dumps(doc))
    r = read_embedding(tmp_path / "v1.emb")
    assert (r.kind, r.decoder, r.size) == (("basis", basis, 3) if basis else ("hypernet", FP, 3))
    assert r.values.tolist() == [0.5, -1.0, 2.0] and (r.source, r.sample_count) == ("x", 3)
    write_embedding(tmp_path / "v2.emb", r)  # written again as version 2, the same values
    again = read_embedding(tmp_path / "v2.emb")
    assert (again.kind, again.decoder, again.values.tolist()) == (r.kind, r.decoder, r.values.tolist())


def test_the_old_kind_name_latent_reads_as_hypernet(tmp_path):
    """``latent``, the name of the ``hypernet`` kind before, in a version 2 file or given to
    :class:`Embedding`, is the same embedding; it is written back as ``hypernet``."""
    write_embedding(tmp_path / "new.emb", _emb())
    doc = json.loads((tmp_path / "new.emb").read_text())
    doc["kind"] = "latent"
    (tmp_path / "old.emb").write_text(json.dumps(doc))
    r = read_embedding(tmp_path / "old.emb")
    new = read_embedding(tmp_path / "new.emb")
    assert r.kind == "hypernet" and (r.decoder, r.source, r.sample_count) == (new.decoder, new.source, new.sample_count)
    np.testing.assert_array_equal(r.values, new.values)
    assert _emb(kind="latent").kind == "hypernet"
    write_embedding(tmp_path / "again.emb", r)
    assert json.loads((tmp_path / "again.emb").read_text())["kind"] == "hypernet"


def test_write_refuses_non_finite(tmp_path):
    e = _emb()
    e.values[3] = np.nan
    with pytest.raises(ValueError):
        write_embedding(tmp_path / "a.emb", e)
    assert not (tmp_path / "a.emb").exists()


def _doc():
    return json.loads(json.dumps({"format": "brdfkit-embedding", "version": 1, "latent_dim": 3,
                                  "latent": [0.5, -1.0, 2.0], "model_fingerprint": FP,
                                  "source": "x", "sample_count": 3}))


BAD_DOCS = {
    "wrong version": (lambda d: d.update(version=3), "version 3 is not supported"),
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
    "fingerprint not hex": (lambda d: d.update(model_fingerprint="x" * 64), "model_fingerprint"),
    "basis not hex": (lambda d: d.update(basis="a" * 63), "'basis' must be the sha256"),
    "basis of 4 values": (lambda d: d.update(basis="a" * 64, latent_dim=4, latent=[1, 2, 3, 4]), "3 coefficients"),
    "negative count": (lambda d: d.update(sample_count=-1), "sample_count"),
    "source not text": (lambda d: d.update(source=5), "'source' must be a string"),
}


def _doc2():
    return {"format": "brdfkit-embedding", "version": 2, "kind": "basis", "size": 3, "values": [0.5, -1.0, 2.0],
            "decoder": FP, "source": "x", "sample_count": 3}


BAD_DOCS_2 = {
    "no kind": (lambda d: d.pop("kind"), "'kind' must be"),
    "kind not a word": (lambda d: d.update(kind="Basis Set"), "'kind' must be"),
    "no decoder": (lambda d: d.pop("decoder"), "'decoder' must be a SHA-256"),
    "short decoder": (lambda d: d.update(decoder="ab" * 31), "'decoder' must be a SHA-256"),
    "short values": (lambda d: d.update(values=[0.5]), "values has 1 values but size is 3"),
    "size zero": (lambda d: d.update(size=0, values=[]), "size must be a positive"),
    "nan text": (lambda d: d["values"].__setitem__(0, "nan"), r"values\[0\] is 'nan'"),
}


@pytest.mark.parametrize("case", sorted(BAD_DOCS) + [f"v2 {c}" for c in sorted(BAD_DOCS_2)])
def test_bad_documents(tmp_path, case):
    edit, message = BAD_DOCS_2[case[3:]] if case.startswith("v2 ") else BAD_DOCS[case]
    d = _doc2() if case.startswith("v2 ") else _doc()
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


def test_write_refuses_a_malformed_kind_or_decoder(tmp_path):
    for e in (_emb(kind="Basis Set"), _emb(fp="x")):
        with pytest.raises(ValueError, match="could not be read back"):
            write_embedding(tmp_path / "a.emb", e)
    assert not (tmp_path / "a.emb").exists()


def test_a_member_option_is_written_and_read_back(tmp_path):
    """A residual's second member is the option ``correction.1`` (what merl80-l40's encode
    chooses for teflon): the reader refused the dot the writer wrote."""
    e = _emb(kind="residual", dim=9)
    e.options = {"correction": 0.0, "correction.1": 1.0}
    write_embedding(tmp_path / "m.emb", e)
    assert read_embedding(tmp_path / "m.emb").options == {"correction": 0.0, "correction.1": 1.0}


@pytest.mark.parametrize("options", [{"Correction": 1.0}, {"correction.0": 1.0}, {"correction.x": 1.0},
                                     {"correction": float("nan")}])
def test_write_refuses_what_read_refuses(tmp_path, options):
    """The writer checks with the reader's schema: what it refuses, the reader refuses too."""
    import json

    from brdfkit.io.embedding import EMBEDDING_FORMAT

    e = _emb(kind="residual", dim=9)
    e.options = options
    with pytest.raises(ValueError, match="could not be read back"):
        write_embedding(tmp_path / "m.emb", e)
    assert not (tmp_path / "m.emb").exists()
    doc = {"format": EMBEDDING_FORMAT, "version": 2, "kind": "residual", "size": 9, "values": [0.0] * 9,
           "decoder": FP, "options": options}
    (tmp_path / "h.emb").write_text(json.dumps(doc))
    with pytest.raises(FormatError, match="options"):
        read_embedding(tmp_path / "h.emb")


def test_a_latent_of_another_model_is_refused():
    from brdfkit.hypernet.neural_brdf import check_latent

    model = types.SimpleNamespace(digest=FP, cfg=types.SimpleNamespace(latent_dim=40))
    check_latent(_emb(), model)
    with pytest.raises(ModelMismatchError) as e:
        check_latent(_emb(fp="cd" * 32), model, "x.emb")
    assert "cdcdcdcdcdcd" in str(e.value) and "abababababab" in str(e.value) and "x.emb" in str(e.value)
    with pytest.raises(ModelMismatchError, match="7 numbers.*latent 40"):
        check_latent(_emb(dim=7), model)
    with pytest.raises(ModelMismatchError, match="basis"):
        check_latent(_emb(kind="basis"), model)


def test_a_blend_takes_a_left_out_option_as_its_kind_default():
    """A residual embedding without options decodes member 0 at gain 1
    (``brdfkit.residual.model.gains``); blended with one of member 1, half of each, not 0."""
    from brdfkit.embeddings.blend import interpolate
    from brdfkit.residual.model import gains

    a = _emb(kind="residual", dim=9)
    b = _emb(kind="residual", dim=9, seed=1)
    b.options = {"correction": 0.0, "correction.1": 1.0}
    mid = interpolate(a, b, 0.5)
    assert mid.options == {"correction": 0.5, "correction.1": 0.5}
    assert gains(mid.options) == {0: 0.5, 1: 0.5}
    assert gains(interpolate(a, b, 0.0).options) == gains(a.options)


def test_any_blend_of_member_embeddings_is_written_read_and_decodes_as_blended(tmp_path):
    """A property over what ``encode`` and ``interpolate`` write: for residual embeddings of
    any members (``gain_options``, as an encode chooses one) blended at any ``t`` in [0, 1],
    ``write_embedding`` writes, ``read_embedding`` reads back the same embedding, and its
    gains are the blend of the two members' gains."""
    hypothesis = pytest.importorskip("hypothesis")
    from hypothesis import strategies as st

    from brdfkit.embeddings.blend import interpolate
    from brdfkit.residual.model import gain_options, gains

    members = st.one_of(st.none(), st.integers(0, 12))

    @hypothesis.given(members, members, st.floats(0.0, 1.0), st.integers(1, 30))
    @hypothesis.settings(max_examples=60, deadline=None)
    def check(ma, mb, t, k):
        a, b = _emb(kind="residual", dim=3 * k), _emb(kind="residual", dim=3 * k, seed=1)
        a.options, b.options = gain_options(ma), gain_options(mb)
        mid = interpolate(a, b, t)
        write_embedding(tmp_path / "p.emb", mid)
        back = read_embedding(tmp_path / "p.emb")
        assert back.options == mid.options and np.array_equal(back.values, mid.values)
        want = {}
        for g, w in ((gains(a.options), 1 - t), (gains(b.options), t)):
            for m, v in g.items():
                want[m] = want.get(m, 0.0) + w * v
        got = gains(back.options)
        assert set(got) == {m for m, v in want.items() if v} and all(abs(got[m] - want[m]) < 1e-12 for m in got)

    check()
