"""Basis embeddings (issue 29): a table as the coefficients of a PCA basis, refined on
renders of the objective scenes; the refinement's render model against the renderer's
own, its guard and its bytes; the embedding file, interpolation and decode."""

from __future__ import annotations

import json

import numpy as np
import pytest

from brdfkit.errors import FormatError, InputError, ModelMismatchError
from brdfkit.geometry import N_CELLS
from brdfkit.geometry.trilinear import lookup_trilinear
from brdfkit.hypernet.refine_on_screen import CompressConfig
from brdfkit.io.embedding import Embedding, read_embedding, write_embedding
from brdfkit.materials import synthetic
from brdfkit.methods.ipca import fit_ipca
from brdfkit.methods.ipca.embedding import (
    BasisBRDF,
    basis_coefficients,
    components_for,
    encode_basis,
)
from brdfkit.methods.ipca.refine_on_screen import (
    _prepare,
    refine_coefficients,
    trilinear_corners,
)

FP = "ab" * 32


@pytest.fixture(scope="module")
def basis_and_table():
    """A 4-component basis of 6 Lambertian + GGX materials (one lobe, evaluated once) and
    one material outside them."""
    lobe = synthetic.table(synthetic.Material("lobe", "dielectric", 0.15))
    rng = np.random.default_rng(3)
    train = [np.asarray(rng.uniform(0.02, 0.8, 3))[None, None, None, :] / np.pi + rng.uniform(0.3, 1.5) * lobe
             for i in range(6)]
    held = np.array([0.5, 0.3, 0.1])[None, None, None, :] / np.pi + 0.7 * lobe
    return fit_ipca(train, n_components=4, names=[f"m{i}" for i in range(6)]), held


def test_trilinear_corners_give_the_lookup():
    rng = np.random.default_rng(0)
    table = rng.uniform(0, 2, (90, 90, 180, 3))
    table[rng.uniform(size=(90, 90, 180)) < 0.1] = np.nan
    th, td, pd = rng.uniform(0, np.pi / 2, 500), rng.uniform(0, np.pi / 2, 500), rng.uniform(0, 2 * np.pi, 500)
    measured = np.isfinite(table.reshape(N_CELLS, 3)).all(axis=1)
    cells, w = trilinear_corners(th, td, pd, measured)
    flat = np.nan_to_num(table.reshape(N_CELLS, 3))
    got = (w[..., None] * flat[cells]).sum(axis=0)
    want = np.nan_to_num(lookup_trilinear(table, th, td, pd, fill=0.0))
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)


def test_the_refinement_renders_what_the_renderer_renders(basis_and_table):
    """The refinement's sparse render of coefficients is the objective scene's render of the
    decoded table (float32 lookups in the latter)."""
    import torch

    from brdfkit.render.scene_suite import scene_env
    from brdfkit.render.screen import screen

    basis, held = basis_and_table
    c = basis.project(held)
    sc = screen("cpu", 12, env=scene_env("studio-1"))
    measured = np.zeros(N_CELLS, bool)
    measured[basis.cells] = True
    pairs = _prepare(basis, sc, measured, torch.arange(sc.pix.shape[0]), None)
    got = pairs.render(torch.tensor(c)).numpy()
    want = sc.render_table(basis.decode(c)).numpy()
    assert np.abs(got - want).max() <= 1e-5 * np.abs(want).max()


def test_refinement_is_guarded_and_gives_the_same_bytes_on_any_thread_count(basis_and_table):
    import torch

    basis, held = basis_and_table
    c0 = basis.project(held)
    cfg = CompressConfig(steps=10, lr=0.06, resolution=12, check_every=2)
    before = torch.get_num_threads()
    try:
        torch.set_num_threads(2)
        a, rec = refine_coefficients(basis, held, c0, cfg)
        torch.set_num_threads(1)
        b, _ = refine_coefficients(basis, held, c0, cfg)
    finally:
        torch.set_num_threads(before)
    assert a.tobytes() == b.tobytes()
    assert rec["steps"] == 10 and rec["heldout"][1] <= rec["heldout"][0]
    if rec["best_step"] == 0:  # the projection is kept when no step helps the held-out pixels
        np.testing.assert_array_equal(a, c0)
    zero, _ = refine_coefficients(basis, held, c0, CompressConfig(steps=0))
    np.testing.assert_array_equal(zero, c0)


def test_encode_basis_decodes_through_the_basis_and_round_trips(basis_and_table, tmp_path):
    basis, held = basis_and_table
    emb = encode_basis(basis, held, fingerprint=FP, model_fingerprint="cd" * 32, components=3, source="held",
                       steps=0)
    assert emb.latent_dim == 9 and emb.basis == FP and emb.refinement is None
    np.testing.assert_allclose(emb.latent.reshape(3, 3), basis.leading(3).project(held), rtol=1e-6)
    write_embedding(tmp_path / "h.emb", emb)
    back = read_embedding(tmp_path / "h.emb")
    assert back.basis == FP and back.latent.tobytes() == emb.latent.tobytes()
    coeffs = basis_coefficients(back, basis, FP)
    table = BasisBRDF(basis, coeffs).to_table()
    np.testing.assert_array_equal(table, basis.leading(3).decode(coeffs))
    with pytest.raises(ModelMismatchError, match="basis abababab"):
        basis_coefficients(back, basis, "ef" * 32)
    big = Embedding(np.zeros(15, np.float32), "cd" * 32, basis=FP)
    with pytest.raises(ModelMismatchError, match="5 components a channel; the basis has 4"):
        basis_coefficients(big, basis, FP)
    assert components_for(40) == 13 and components_for(7) == 2


def test_embedding_files_of_a_basis_are_checked(tmp_path):
    good = Embedding(np.arange(6, dtype=np.float32), "cd" * 32, "x", 0, basis=FP)
    write_embedding(tmp_path / "g.emb", good)
    doc = json.loads((tmp_path / "g.emb").read_text())
    assert doc["basis"] == FP
    for value, msg in (("xyz", "sha256 hex"), (5, "sha256 hex")):
        (tmp_path / "b.emb").write_text(json.dumps(dict(doc, basis=value)))
        with pytest.raises(FormatError, match=msg):
            read_embedding(tmp_path / "b.emb")
    (tmp_path / "b.emb").write_text(json.dumps(dict(doc, latent=[0.0] * 5, latent_dim=5)))
    with pytest.raises(FormatError, match="3 coefficients a component"):
        read_embedding(tmp_path / "b.emb")
    plain = json.loads(json.dumps(doc))
    del plain["basis"]
    (tmp_path / "p.emb").write_text(json.dumps(plain))
    assert read_embedding(tmp_path / "p.emb").basis is None


def test_interpolation_keeps_the_basis_and_refuses_mixing_kinds():
    from brdfkit.api import interpolate

    a = Embedding(np.zeros(6, np.float32), "cd" * 32, "a", basis=FP)
    b = Embedding(np.ones(6, np.float32), "cd" * 32, "b", basis=FP)
    mid = interpolate(a, b, 0.5)
    assert mid.basis == FP and mid.latent.tolist() == [0.5] * 6
    latent = Embedding(np.ones(6, np.float32), "cd" * 32, "c")
    with pytest.raises(ModelMismatchError, match="basis embedding"):
        interpolate(a, latent, 0.5)


def test_a_model_without_a_basis_makes_latents_and_refuses_basis(tmp_path):
    from brdfkit.api import decode, encode, load_model
    from brdfkit.testing.examples import lambertian_table, tiny_model

    model = load_model(tiny_model(tmp_path / "tiny.safetensors"), device="cpu")
    emb = encode(model, lambertian_table(), refine=False)
    assert emb.basis is None and emb.latent_dim == 7
    with pytest.raises(InputError, match="ships no PCA basis"):
        encode(model, lambertian_table(), kind="basis")
    with pytest.raises(InputError, match="kind 'pca'"):
        encode(model, lambertian_table(), kind="pca")
    foreign = Embedding(np.zeros(6, np.float32), model.fingerprint, "x", basis=FP)
    with pytest.raises(ModelMismatchError, match="ships no basis"):
        decode(model, foreign)


def test_bench_takes_model_latent_entries(tmp_path):
    from brdfkit.bench.config import BenchConfig, latent_spec
    from brdfkit.bench.worker import Worker
    from brdfkit.testing.examples import tiny_model

    assert latent_spec("m.safetensors:latent") == ("m.safetensors", True)
    assert latent_spec("merl80-l40") == ("merl80-l40", False)
    model = str(tiny_model(tmp_path / "t.safetensors"))
    cfg = BenchConfig(output=str(tmp_path / "o"), data=None, compression_models=(f"{model}:latent", model),
                      compression_data=str(tmp_path), resolution=8)
    cfg.validate()
    assert [(path, kind) for _, path, kind in cfg.compressors()] == [(model, "latent"), (model, None)]
    assert cfg.resolved().compression_models == (f"{model}:latent", model)
    labels = [label for label, _, _, _ in Worker(cfg).compressors]
    # a model without a basis compresses into its latent either way
    assert labels == ["hypernet 7-D (t)", "hypernet 7-D (t)"]
