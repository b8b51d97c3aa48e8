"""Basis embeddings: a table as the coefficients of a PCA basis, refined on renders of the
objective scenes; the refinement's render model against the renderer's own, its guard and
its bytes; sizes; the embedding file, interpolation and decode; the kinds' registry."""

from __future__ import annotations

import json

import numpy as np
import pytest

from brdfkit.errors import FormatError, InputError, ModelMismatchError
from brdfkit.geometry import N_CELLS
from brdfkit.geometry.trilinear import lookup_trilinear
from brdfkit.render.objective import ObjectiveConfig
from brdfkit.io.embedding import Embedding, read_embedding, write_embedding
from brdfkit.materials import synthetic
from brdfkit.basis import fit_basis
from brdfkit.basis.coefficients import BasisBRDF, basis_sizes, check_coefficients, encode_coefficients
from brdfkit.basis.refine_on_screen import cell_map, refine_coefficients

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
    return fit_basis(train, n_components=4, names=[f"m{i}" for i in range(6)]), held


def test_the_refinement_renders_what_the_renderer_renders(basis_and_table):
    """The refinement's sparse render of coefficients (a cell map of all a screen's pairs,
    its corners renormalised over the basis's cells) is the objective scene's render of the
    decoded table (float32 lookups in the latter)."""
    from brdfkit.render.scene_suite import scene_env
    from brdfkit.render.screen import screen

    basis, held = basis_and_table
    c = basis.project(held)
    sc = screen(None, 12, env=scene_env("studio-1"))
    m = cell_map(basis, sc, np.arange(sc.pix.shape[0]))
    got = m.render(c)
    want = sc.render_table(basis.decode(c))[m.pixels]
    assert np.abs(got - want).max() <= 1e-5 * np.abs(want).max()
    assert m.cells.size < N_CELLS // 10  # only the cells the pairs reach


def test_refinement_is_guarded_records_its_solver_and_gives_the_same_bytes(basis_and_table):
    basis, held = basis_and_table
    c0 = basis.project(held)
    cfg = ObjectiveConfig(steps=6, resolution=12)
    a, rec = refine_coefficients(basis, held, c0, cfg)
    b, again = refine_coefficients(basis, held, c0, cfg)
    assert a.tobytes() == b.tobytes() and rec == again
    assert rec["solver"] == "levenberg-marquardt" and 1 <= rec["steps"] <= 6 and len(rec["heldout"]) == rec["steps"] + 1
    assert rec["heldout"][rec["best_step"]] == min(rec["heldout"]) <= rec["heldout"][0]
    if rec["best_step"] == 0:  # the projection is kept when no iteration helps the held-out pixels
        np.testing.assert_array_equal(a, c0)
    else:
        assert rec["heldout"][rec["best_step"]] < rec["heldout"][0] and not np.array_equal(a, c0)
    zero, _ = refine_coefficients(basis, held, c0, ObjectiveConfig(steps=0))
    np.testing.assert_array_equal(zero, c0)


def test_encode_coefficients_decodes_through_the_basis_and_round_trips(basis_and_table, tmp_path):
    basis, held = basis_and_table
    emb = encode_coefficients(basis, held, digest=FP, size=9, source="held", steps=0)
    assert (emb.kind, emb.size, emb.decoder, emb.refinement) == ("basis", 9, FP, None)
    np.testing.assert_allclose(emb.values.reshape(3, 3), basis.leading(3).project(held), rtol=1e-6)
    write_embedding(tmp_path / "h.emb", emb)
    back = read_embedding(tmp_path / "h.emb")
    assert back.decoder == FP and back.kind == "basis" and back.values.tobytes() == emb.values.tobytes()
    coeffs = check_coefficients(back, basis, FP)
    table = BasisBRDF(basis, coeffs).to_table()
    np.testing.assert_array_equal(table, basis.leading(3).decode(coeffs))
    with pytest.raises(ModelMismatchError, match="basis abababab"):
        check_coefficients(back, basis, "ef" * 32)
    big = Embedding(np.zeros(15, np.float32), "basis", FP)
    with pytest.raises(ModelMismatchError, match="15 numbers; a basis of 4 components decodes 3, 6, ... 12"):
        check_coefficients(big, basis, FP)


def test_every_size_of_the_basis_and_no_other(basis_and_table):
    basis, held = basis_and_table
    assert list(basis_sizes(basis)) == [3, 6, 9, 12]
    for size in basis_sizes(basis):
        emb = encode_coefficients(basis, held, digest=FP, size=size, steps=0)
        assert emb.size == size
    assert encode_coefficients(basis, held, digest=FP, steps=0).size == 12  # 39 by default, at most the basis's
    for size in (2, 15, 7):
        with pytest.raises(InputError, match=f"of {size} numbers"):
            encode_coefficients(basis, held, digest=FP, size=size, steps=0)


def test_interpolation_keeps_the_kind_and_refuses_mixing_kinds():
    from brdfkit.api import interpolate

    a = Embedding(np.zeros(6, np.float32), "basis", FP, "a")
    b = Embedding(np.ones(6, np.float32), "basis", FP, "b")
    mid = interpolate(a, b, 0.5)
    assert (mid.kind, mid.decoder, mid.values.tolist()) == ("basis", FP, [0.5] * 6)
    latent = Embedding(np.ones(6, np.float32), "hypernet", FP, "c")
    with pytest.raises(ModelMismatchError, match="basis embedding .* hypernet one"):
        interpolate(a, latent, 0.5)
    old = Embedding(np.ones(6, np.float32), "latent", FP, "c")  # the kind's old name: the same kind
    with pytest.raises(ModelMismatchError, match="basis embedding .* hypernet one"):
        interpolate(a, old, 0.5)


def test_basis_files_encode_and_decode_through_the_library_and_the_registry(basis_and_table, tmp_path):
    """A basis file of one's own is a decoder: ``encode(table, basis_file)`` makes a basis
    embedding that names the file's SHA-256, and ``decode`` refuses another basis."""
    from brdfkit.api import decode, encode
    from brdfkit.basis import save_basis
    from brdfkit.io.digest import file_digest
    from brdfkit.embeddings import KINDS, choose_decoder, get_kind

    basis, held = basis_and_table
    save_basis(tmp_path / "b.safetensors", basis)
    emb = encode(held, tmp_path / "b.safetensors", size=6, steps=0)
    assert emb.kind == "basis" and emb.decoder == file_digest(tmp_path / "b.safetensors")
    np.testing.assert_array_equal(decode(emb, tmp_path / "b.safetensors"), basis.leading(2).decode(emb.values.reshape(2, 3)))
    save_basis(tmp_path / "other.safetensors", basis.leading(3))
    with pytest.raises(ModelMismatchError, match="encode the material again"):
        decode(emb, tmp_path / "other.safetensors")
    with pytest.raises(InputError, match="is not among the installed built-in"):
        decode(emb)  # no -m, and no built-in has this digest
    assert set(KINDS) == {"basis", "hypernet", "residual"}
    assert choose_decoder(None, tmp_path / "b.safetensors").kind == "basis"
    with pytest.raises(InputError, match="a basis file, not the network a hypernet embedding needs"):
        choose_decoder("hypernet", tmp_path / "b.safetensors")
    with pytest.raises(InputError, match="a basis file, not the network a hypernet embedding needs"):
        choose_decoder("latent", tmp_path / "b.safetensors")  # the old name of the kind
    assert get_kind("latent") is get_kind("hypernet") is KINDS["hypernet"]
    with pytest.raises(InputError, match="unknown embedding kind 'pca'"):
        get_kind("pca")


@pytest.mark.slow
def test_a_model_without_a_basis_makes_latents_and_refuses_basis(tmp_path):
    from brdfkit.api import decode, encode, load_model
    from brdfkit.testing.examples import lambertian_table, tiny_model

    model = load_model(tiny_model(tmp_path / "tiny.safetensors"), device="cpu")
    emb = encode(lambertian_table(), model, refine=False)
    assert emb.kind == "hypernet" and emb.size == 7
    old = encode(lambertian_table(), model, kind="latent", refine=False)  # the kind's old name
    assert old.kind == "hypernet" and old.values.tobytes() == emb.values.tobytes()
    with pytest.raises(InputError, match="is a hypernetwork of no installed built-in: it encodes hypernet "
                                         "embeddings only"):
        encode(lambertian_table(), model, kind="basis")
    with pytest.raises(InputError, match="kind 'pca'"):
        encode(lambertian_table(), tmp_path / "tiny.safetensors", kind="pca")
    foreign = Embedding(np.zeros(6, np.float32), "basis", model.digest, "x")
    with pytest.raises(InputError, match="is a hypernetwork of no installed built-in: it encodes hypernet "
                                         "embeddings only"):
        decode(foreign, model)


def test_bench_takes_model_kind_size_entries(tmp_path, basis_and_table):
    from brdfkit.basis import save_basis
    from brdfkit.bench.config import BenchConfig, compression_entry
    from brdfkit.bench.worker import Worker
    from brdfkit.testing.examples import tiny_model

    assert compression_entry("m.safetensors:hypernet") == ("m.safetensors", "hypernet", None)
    assert compression_entry("m.safetensors:latent") == ("m.safetensors", "latent", None)  # the old name
    assert compression_entry("merl80-l40") == ("merl80-l40", None, None)
    assert compression_entry("b.safetensors:basis-21") == ("b.safetensors", "basis", 21)
    with pytest.raises(InputError, match="unknown embedding kind"):
        compression_entry("m:pca")
    model = str(tiny_model(tmp_path / "t.safetensors"))
    basis = str(tmp_path / "b.safetensors")
    save_basis(basis, basis_and_table[0])
    cfg = BenchConfig(output=str(tmp_path / "o"), data=None, compression_models=(f"{model}:hypernet", model,
                      f"{basis}:basis-6", basis, f"{model}:latent"), compression_data=str(tmp_path), resolution=8)
    cfg.validate()
    resolved = cfg.resolved()
    assert resolved.compression_models == (f"{model}:hypernet-7", f"{model}:hypernet-7", f"{basis}:basis-6",
                                           f"{basis}:basis-12", f"{model}:hypernet-7")
    labels = [label for label, _, _ in Worker(resolved).compressors]
    assert labels == ["hypernet-7 (t)", "hypernet-7 (t)", "basis-6 (b)", "basis-12 (b)", "hypernet-7 (t)"]
    with pytest.raises(InputError, match="--size 9: hypernet embeddings of t.safetensors hold 7 numbers"):
        BenchConfig(output=str(tmp_path / "o"), compression_models=(f"{model}:hypernet-9",),
                    compression_data=str(tmp_path)).resolved()


def test_one_levenberg_marquardt_converges_stops_by_its_rule_and_never_raises_the_cost():
    """The one solver every kind's encode uses (``brdfkit.basis.least_squares``): it reaches
    Rosenbrock's minimum, solves a linear problem as least squares does with the cost
    falling at every step taken, and at a minimum takes no step (``TRIES`` trials, then
    done)."""
    from brdfkit.basis.least_squares import TRIES, LevenbergMarquardt, levenberg_marquardt

    def rosenbrock(x):
        return np.array([10.0 * (x[1] - x[0] ** 2), 1.0 - x[0]]), None

    x = levenberg_marquardt(rosenbrock, lambda x, _: np.array([[-20.0 * x[0], 10.0], [-1.0, 0.0]]),
                            np.array([-1.2, 1.0]), steps=200)
    np.testing.assert_allclose(x, [1.0, 1.0], atol=1e-6)
    rng = np.random.default_rng(0)
    a, b = rng.standard_normal((40, 5)), rng.standard_normal(40)
    calls = []

    def linear(x):
        calls.append(1)
        return a @ x - b, None

    lm = LevenbergMarquardt(linear, lambda x, _: a, np.zeros(5))
    costs = [lm.cost]
    while not lm.step():
        costs.append(lm.cost)
    costs.append(lm.cost)
    assert all(later <= before for before, later in zip(costs, costs[1:])) and lm.iterations <= 10
    np.testing.assert_allclose(lm.x, np.linalg.lstsq(a, b, rcond=None)[0], atol=1e-6)
    xs = rng.standard_normal(5)
    b[:] = a @ xs  # a zero residual at xs: no trial can lower the cost there
    at_min = LevenbergMarquardt(linear, lambda x, _: a, xs)
    calls.clear()
    assert at_min.cost == 0.0 and at_min.step() and at_min.iterations == 0 and len(calls) == TRIES
    assert at_min.step() and len(calls) == TRIES  # done: nothing more evaluated


def test_the_refinement_and_the_decode_give_the_same_bytes_on_one_thread_or_two(basis_and_table):
    """The channels, scenes and cells are fixed pieces of work: the refinement's
    coefficients and record, and the dense decode, do not depend on how many threads run
    them."""
    from brdfkit.runtime import set_cpu_threads
    from brdfkit import runtime

    basis, held = basis_and_table
    c0 = basis.project(held)
    cfg = ObjectiveConfig(steps=4, resolution=12)
    out = []
    try:
        for threads in (1, 2):
            set_cpu_threads(threads)
            c, rec = refine_coefficients(basis, held, c0, cfg)
            out.append((c.tobytes(), rec, basis.decode(c).tobytes()))
    finally:
        runtime._CPU_THREADS.clear()
    assert out[0] == out[1]
