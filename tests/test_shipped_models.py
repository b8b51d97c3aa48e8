"""The built-in models as shipped in the package (issue 12's "done when"): listed, intact,
and answering `brdfkit sparse`, `encode`, `decode` and the `ipca` baseline with no `-m`.

Every other test points ``$BRDFKIT_BUILTIN_MODELS`` at an empty folder (conftest); these
read the package's own folder.
"""

from __future__ import annotations

import functools
import json
import os

import numpy as np
import pytest

from brdfkit.models.builtin import models_folder, read_manifest

NAMES = ("merl-rgl-l40", "merl80-l40", "merl-rgl-l7")


@pytest.fixture
def shipped(monkeypatch):
    monkeypatch.delenv("BRDFKIT_BUILTIN_MODELS", raising=False)
    man = read_manifest(models_folder())
    if not man.installed():
        pytest.skip("no built-in model files in this checkout (brdfkit/models)")
    return man


def _run(capsys, monkeypatch, *args, cwd):
    """``brdfkit ARGS`` in this process, in ``cwd``, with neither ``$BRDFKIT_BUILTIN_MODELS``
    (``shipped``) nor ``$BRDFKIT_MODEL`` (conftest): the package's own built-in models."""
    from conftest import run_here

    monkeypatch.chdir(cwd)
    return run_here(capsys, args)


@pytest.mark.slow
def test_the_three_models_are_listed_installed_and_intact(shipped, tmp_path, capsys, monkeypatch):
    assert [m.name for m in shipped.installed()] == list(NAMES)
    assert shipped.default == "merl-rgl-l40"
    r = _run(capsys, monkeypatch, "models", "--json", "--check", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    doc = json.loads(r.stdout)
    by_name = {e["name"]: e for e in doc["bundles"]}
    assert {by_name[n]["latent_dim"] for n in NAMES} == {40, 7}
    for n in ("merl80-l40", "merl-rgl-l40"):
        assert set(by_name[n]["parts"]) >= {"network", "basis", "prior"}
        assert all(p["installed"] for p in by_name[n]["parts"].values())
    assert set(by_name["merl-rgl-l7"]["parts"]) == {"network"}
    # The benchmark's model never saw a test material.
    from brdfkit.hypernet.packing import load_builtin
    test = set(open(os.path.join(os.path.dirname(__file__), "..", "..", "shared", "data", "merl-test.txt")).read().split()) \
        if os.path.exists(os.path.join(os.path.dirname(__file__), "..", "..", "shared", "data", "merl-test.txt")) else set()
    mats = set(load_builtin("merl80-l40", device="cpu").meta.get("materials") or ())
    assert len(mats) == 80 and not (mats & test)


def test_the_package_is_within_its_size_budget(shipped):
    folder = models_folder()
    total = sum(os.path.getsize(os.path.join(folder, f)) for f in os.listdir(folder))
    assert total <= 60e6, f"built-in models take {total / 1e6:.1f} MB, over the 60 MB budget (issue 21)"


@pytest.mark.slow
def test_sparse_encode_decode_without_m(shipped, tmp_path, capsys, monkeypatch):
    from brdfkit.io.merl import write_merl
    from brdfkit.io.samples import write_samples
    from brdfkit.acquisition.sampling import draw_samples
    from brdfkit.materials.synthetic import library, table

    ref = table(library(6, seed=3, stiff=False)[5])
    write_merl(tmp_path / "ref.binary", ref)
    write_samples(tmp_path / "s.csv", draw_samples(ref, 400, seed=0))
    r = _run(capsys, monkeypatch, "sparse", "s.csv", "-o", "out.binary", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "prior" in r.stderr and "merl-rgl-l40" in r.stderr
    # The projection alone: the refinement of a basis embedding is the next test's
    r = _run(capsys, monkeypatch, "encode", "ref.binary", "-o", "emb", "--steps", "0", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    embs = [f for f in os.listdir(tmp_path / "emb") if f.endswith(".emb")]
    assert len(embs) == 1
    assert json.loads((tmp_path / "emb" / embs[0]).read_text())["kind"] == "residual"  # the default
    r = _run(capsys, monkeypatch, "decode", os.path.join("emb", embs[0]), "-o", "dec.binary", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    from brdfkit.io.merl import read_merl
    from brdfkit.evaluation.metrics import brdf_log_rmse
    out = read_merl(tmp_path / "out.binary")
    assert np.isfinite(out[np.isfinite(ref)]).all()
    # The learnt prior from 400 samples is a useful reconstruction of an unseen material.
    assert brdf_log_rmse(out, ref) < 0.5


@pytest.mark.slow
def test_builtin_basis_gives_the_prior_32_components_and_ipca_nielsens_8(shipped):
    """Each learnt prior fits a 30-component basis of its model's training materials with
    the mapping's floor at grazing angles (issue 22); `--method ipca` with a built-in's
    name takes its leading 8, Nielsen et al.'s count."""
    from brdfkit.methods import get_method
    from brdfkit.models.builtin import read_manifest

    bases = {}
    for name, count in (("merl80-l40", 80), ("merl-rgl-l40", 151)):
        prior = get_method("prior").load(name, "cpu")
        ipca = get_method("ipca").load(name, "cpu")
        assert prior.basis.n_components == 30 and ipca.n_components == 8
        assert prior.basis.w_floor == 0.005 and len(prior.basis.materials) == count
        np.testing.assert_array_equal(ipca.sigma, prior.basis.sigma[:8])
        bases[name] = prior.basis
    # merl80-l40's basis was fitted on its model's 80 training materials: no test material
    model = set(get_method("hypernet").load("merl80-l40", "cpu").meta.get("materials") or ())
    assert set(bases["merl80-l40"].materials) == model and len(model) == 80
    assert next(m for m in read_manifest().bundles if m.name == "merl80-l40").materials == 80


@pytest.mark.slow
def test_default_encode_is_a_residual_embedding_with_the_same_bytes_on_any_thread_count(shipped, tmp_path):
    """Issues 29 and 45: the default built-in encodes a table into its basis's coefficients
    and its residual's correction (39 numbers), the same bytes on two torch threads and on
    one (the command line's encode and decode of one: test_sparse_encode_decode_without_m)."""
    import torch

    from brdfkit.api import encode, load_model
    from brdfkit.io.embedding import write_embedding
    from brdfkit.materials.synthetic import library, table

    ref = table(library(6, seed=3, stiff=False)[2])
    model = load_model("merl-rgl-l40", device="cpu")  # its bundle's residual encodes, at 39 numbers
    before, got = torch.get_num_threads(), []
    try:
        for threads in (2, 1):
            torch.set_num_threads(threads)
            # 3 steps: another thread count's other sums show in the first step's bytes
            write_embedding(tmp_path / f"t{threads}.emb", encode(ref, model, source="m.binary", steps=3))
            got.append((tmp_path / f"t{threads}.emb").read_bytes())
    finally:
        torch.set_num_threads(before)
    assert got[0] == got[1]
    doc = json.loads(got[0])
    assert doc["size"] == 39 and doc["kind"] == "residual" and len(doc["decoder"]) == 64
    assert doc["refinement"]["steps"] <= 3


def test_merl80_l40_encodes_a_residual_embedding_at_the_sizes_offered(shipped):
    """Issue 40: a built-in that ships a basis residual encodes residual embeddings by
    default at the sizes its file offers (where it won on held-out materials), and basis
    embeddings at the others; the residual corrects the bundle's own basis."""
    from brdfkit.embeddings import choose_decoder
    from brdfkit.models.builtin import resolve_part

    dec = choose_decoder(None, "merl80-l40", "cpu")
    assert (dec.kind, dec.sizes, dec.default_size) == ("residual", (9, 21, 39), 39)
    assert dec.obj.basis_digest == next(m for m in shipped.bundles if m.name == "merl80-l40").part("basis").digest
    assert choose_decoder(None, "merl80-l40", "cpu", 12).kind == "basis"
    assert choose_decoder(None, "merl-rgl-l40", "cpu").kind == "residual"  # the default's too (issue 45)
    assert choose_decoder(None, "merl-rgl-l40", "cpu", 12).kind == "basis"
    assert resolve_part("merl80-l40", "residual").endswith("merl80-residual.safetensors")


# (material, route) -> (lowest, highest) median grazing ratio where the default built-in
# misses [0.5, 2], as measured with the built-ins of 2026-11-29 (issue 50), so that the
# test fails if they get worse: chrome-steel's NBRDF fit is about 0 at most grazing cells
# (a ratio to nearly nothing; 22.5 and 30.7 with the bases before); blue-metallic-paint
# from 400 samples (2.35 before); violet-rubber's encode (1.01 before: the one that lost).
GRAZING_MISSES = {("chrome-steel", "encode"): (0.5, 5.0), ("chrome-steel", "sparse"): (0.5, 4.5),
                  ("blue-metallic-paint", "sparse"): (0.5, 2.6), ("violet-rubber", "encode"): (0.4, 2.0)}


@functools.lru_cache(maxsize=None)
def _material(name: str):
    """``material_table(name)``, read-only, decoded once a module (two tests take the four
    shipped materials: 4 NBRDF decodes fewer)."""
    from brdfkit.materials.nbrdf_networks import material_table

    table = material_table(name)
    table.setflags(write=False)
    return table


@pytest.mark.slow
def test_the_shipped_materials_decode_with_their_grazing_rows_and_nothing_black(shipped):
    """Issue 50: on the four real materials `brdfkit material` ships, the default `encode`
    (39 numbers) and the default `sparse` from 400 samples decode no cell of the material
    below 1% of its value in more than 0.01% of the cells, none of at least 1 /sr to 0, and
    grazing rows (theta_h >= 80 deg) whose median ratio to the material lies in [0.5, 2]
    but where :data:`GRAZING_MISSES` pins the measured miss (`benchmarks/black_cells.py`
    measures the same on the MERL test materials)."""
    import brdfkit
    from brdfkit.acquisition.sampling import draw_samples
    from brdfkit.evaluation.metrics import grazing_ratio
    from brdfkit.materials.nbrdf_networks import material_names

    for name in material_names():
        ref = _material(name)
        ok = np.isfinite(ref) & (ref > 0)
        for route, pred in (("encode", brdfkit.decode(brdfkit.encode(ref, source=name))),
                            ("sparse", brdfkit.sparse(draw_samples(ref, 400, seed=0))[0])):
            below = float(np.mean(pred[ok] < 0.01 * ref[ok]))
            assert below <= 1e-4, f"{name} {route}: {100 * below:.4f}% of the cells below 1% of the material"
            assert not np.any(pred[ok & (ref >= 1.0)] < 1e-6 * ref[ok & (ref >= 1.0)]), f"{name} {route}: black cells"
            low, high = GRAZING_MISSES.get((name, route), (0.5, 2.0))
            assert low <= grazing_ratio(pred, ref) <= high, f"{name} {route}: grazing rows {grazing_ratio(pred, ref):.2f}"


# The share of the positive cells that merl-rgl-l7's encode -> decode puts below 1% of the
# material, per shipped material, at most (issue 58): measured with the retrained model on
# 2026-12-01, 0 for blue-metallic-paint, teflon and violet-rubber and 0.0243% for
# chrome-steel (dark cells at theta_h 30-80 deg, theta_d > 62 deg, ~1e-3 /sr under a
# median of ~0.04); the pins leave room for a few cells of another CPU's rounding. The
# model before decoded blue-metallic-paint's corner theta_h < 2, theta_d > 75 deg black
# (4.19% of its cells).
L7_BELOW = {"blue-metallic-paint": 1e-5, "teflon": 1e-5, "violet-rubber": 1e-5, "chrome-steel": 3e-4}


@pytest.mark.slow
def test_the_7d_latent_decodes_nothing_black(shipped):
    """Issue 58: `merl-rgl-l7`'s encode and decode of the four shipped materials decode no
    cell of at least 1 /sr below a millionth of it, and no more of their positive cells
    below 1% of the material than :data:`L7_BELOW` pins (`benchmarks/black_cells.py`
    measures the same on the MERL test materials)."""
    import brdfkit
    from brdfkit.embeddings import choose_decoder
    from brdfkit.materials.nbrdf_networks import material_names

    dec = choose_decoder("hypernet", "merl-rgl-l7")
    assert set(L7_BELOW) == set(material_names())
    for name in material_names():
        ref = _material(name)
        pred = brdfkit.decode(brdfkit.encode(ref, dec, source=name), dec)
        ok = np.isfinite(ref) & (ref > 0)
        bright = ok & (ref >= 1.0)
        assert not np.any(pred[bright] < 1e-6 * ref[bright]), f"{name}: cells of >= 1 /sr decode to 0"
        below = float(np.mean(pred[ok] < 0.01 * ref[ok]))
        assert below <= L7_BELOW[name], f"{name}: {100 * below:.4f}% of the cells below 1% of the material"

