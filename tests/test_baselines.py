"""The sparse-reconstruction baselines: Nielsen et al. 2015 PCA (``ipca``) and NBRDF
(Sztrajman et al. 2021) fitted to the samples alone, and their common registry."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from brdfkit.materials import synthetic
from brdfkit.methods import METHODS, get_method
from brdfkit.basis import fit_basis, load_basis, save_basis
from brdfkit.errors import FormatError, InputError
from brdfkit.geometry import HALF_PI, io_from_half_diff, valid_mask
from brdfkit.evaluation.metrics import brdf_log_rmse
from brdfkit.io.samples import SampleSet
from brdfkit.acquisition.sampling import draw_samples

from conftest import one_error_line, run_cli

ALPHAS = (0.05, 0.15, 0.4)


@pytest.fixture(scope="module")
def lobes():
    """GGX dielectric lobes (no diffuse part) on the MERL grid, one per roughness.

    Evaluating a synthetic table costs about a second, so the library below is built
    from these three evaluations instead of one per material."""
    return [synthetic.table(synthetic.Material(f"lobe-{a}", "dielectric", a)) for a in ALPHAS]


def _material(lobes, albedo, ks, mix):
    """``albedo / pi + ks * sum_j mix_j lobe_j``: a Lambertian + GGX synthetic material."""
    spec = sum(m * lobe for m, lobe in zip(mix, lobes))
    return np.asarray(albedo)[None, None, None, :] / np.pi + ks * spec


@pytest.fixture(scope="module")
def library(lobes):
    """12 training materials (3 roughnesses, random albedo and specular strength) and one
    held-out material mixing two lobes with an albedo outside the training draws."""
    rng = np.random.default_rng(7)
    train = []
    for i in range(12):
        mix = np.eye(3)[i % 3]
        train.append(_material(lobes, rng.uniform(0.02, 0.8, 3), rng.uniform(0.3, 1.5), mix))
    held = _material(lobes, (0.6, 0.25, 0.05), 0.8, (0.0, 0.5, 0.5))
    return train, held


@pytest.fixture(scope="module")
def basis(library):
    train, _ = library
    return fit_basis(train, n_components=4, names=[f"m{i}" for i in range(len(train))])


# --- IPCA -------------------------------------------------------------------------------------

@pytest.mark.slow
def test_ipca_leading_components_are_the_smaller_fit(library):
    """A basis's leading components are the basis a smaller fit to the same tables gives
    (what the IPCA baseline takes from a built-in basis of 32 components)."""
    train = library[0][:6]
    small = fit_basis(train, n_components=4, names=[f"m{i}" for i in range(len(train))])
    big = fit_basis(train, n_components=5, names=[f"m{i}" for i in range(len(train))]).leading(4)
    np.testing.assert_allclose(big.sigma, small.sigma, rtol=1e-5)
    cos = np.sum(big.components * small.components, axis=1) / (
        np.linalg.norm(big.components, axis=1) * np.linalg.norm(small.components, axis=1))
    assert big.n_components == 4 and np.all(np.abs(cos) > 1 - 1e-4), cos
    with pytest.raises(InputError, match="no 6 leading"):
        small.leading(6)


@pytest.mark.slow
def test_ipca_basis_shapes_and_orthonormality(basis):
    assert basis.n_components == 4
    assert basis.materials == [f"m{i}" for i in range(12)]
    p = basis.cells.size
    assert basis.components.shape == (4, p) and basis.mean.shape == basis.reference.shape == (p,)
    # The basis covers exactly the cells the training tables measure.
    assert p == int(valid_mask().sum())
    gram = basis.components.astype(np.float64) @ basis.components.T.astype(np.float64)
    np.testing.assert_allclose(gram, np.eye(4), atol=1e-4)
    assert np.all(np.diff(basis.sigma) <= 0) and basis.sigma[-1] > 0


@pytest.mark.slow
def test_ipca_reconstructs_a_training_material_from_2000_samples(basis, library):
    train, _ = library
    table = train[4]
    rec = basis.reconstruct(draw_samples(table, 2000, seed=3))
    assert rec.shape == (90, 90, 180, 3) and rec.dtype == np.float64
    measured = np.isfinite(table).all(axis=-1)
    assert np.isfinite(rec[measured]).all() and (rec[measured] >= 0).all()
    assert np.isnan(rec[~measured]).all()
    err = brdf_log_rmse(rec, table)
    best = brdf_log_rmse(basis.decode(basis.project(table)), table)
    # The training material lies (almost) in the span: close to the best the basis can do.
    assert err < 0.02, err
    assert err < best + 0.01, (err, best)


def test_ipca_held_out_material_beats_the_mean(basis, library):
    _, held = library
    rec = basis.reconstruct(draw_samples(held, 2000, seed=4))
    err = brdf_log_rmse(rec, held)
    mean_only = brdf_log_rmse(basis.decode(np.zeros((4, 3))), held)
    assert err < 0.6 * mean_only, (err, mean_only)


@pytest.mark.slow
def test_ipca_arbitrary_angles_and_tiny_sample_sets(basis, lobes, library):
    # Off-grid angles read the basis trilinearly; the fit must still match the material.
    rng = np.random.default_rng(0)
    th, td, pd = rng.uniform(0, HALF_PI, 4000), rng.uniform(0, HALF_PI, 4000), rng.uniform(0, np.pi, 4000)
    wi, wo = io_from_half_diff(th, td, pd)
    keep = (wi[:, 2] > 0) & (wo[:, 2] > 0)
    albedo = np.array([0.3, 0.5, 0.2])
    spec = synthetic.evaluate(synthetic.Material("x", "dielectric", ALPHAS[1]), wi[keep], wo[keep])
    off = SampleSet(th[keep], td[keep], pd[keep], albedo / np.pi + spec)
    table = _material(lobes, albedo, 1.0, (0.0, 1.0, 0.0))
    err = brdf_log_rmse(basis.reconstruct(off), table)
    assert err < 0.03, err
    # One sample is enough for a finite, non-negative table (the ridge keeps it posed).
    one = draw_samples(library[0][0], 1, seed=0)
    rec1 = basis.reconstruct(one)
    assert np.isfinite(rec1[valid_mask()]).all() and (rec1[valid_mask()] >= 0).all()
    with pytest.raises(InputError, match="lambda"):
        basis.reconstruct(one, lam=-1)


def test_ipca_save_load_round_trip(basis, library, tmp_path):
    path = tmp_path / "basis.safetensors"
    save_basis(path, basis)
    back = load_basis(path)
    for k in ("cells", "reference", "mean", "components", "sigma"):
        np.testing.assert_array_equal(getattr(back, k), getattr(basis, k))
    assert back.materials == basis.materials
    samples = draw_samples(library[1], 300, seed=1)
    np.testing.assert_array_equal(back.reconstruct(samples), basis.reconstruct(samples))
    assert not [p for p in os.listdir(tmp_path) if p.startswith(".brdfkit-tmp-")]


def test_ipca_load_refuses_other_files(basis, tmp_path):
    text = tmp_path / "notes.safetensors"
    text.write_text("not a safetensors file\n")
    with pytest.raises(FormatError, match="notes.safetensors"):
        load_basis(text)
    good = tmp_path / "b.safetensors"
    save_basis(good, basis)
    cut = tmp_path / "cut.safetensors"
    cut.write_bytes(good.read_bytes()[:100000])
    with pytest.raises(FormatError, match="cut.safetensors"):
        load_basis(cut)
    from brdfkit.hypernet.mapping import save_reference
    ref = tmp_path / "ref.safetensors"
    save_reference(ref, np.zeros((90, 90, 180, 3), np.float32))
    with pytest.raises(FormatError, match="not a brdfkit PCA basis"):
        load_basis(ref)
    with pytest.raises(InputError, match="no such file"):
        load_basis(tmp_path / "missing.safetensors")


def test_ipca_fit_refuses_too_many_components(library):
    with pytest.raises(InputError, match="components"):
        fit_basis(library[0][:2], n_components=8)
    with pytest.raises(InputError, match="shape"):
        fit_basis([np.zeros((3, 3))], n_components=1)


# --- NBRDF ------------------------------------------------------------------------------------

def _analytic_samples(material, n, seed=0):
    """``n`` samples of an analytic material at random angles above the horizon."""
    rng = np.random.default_rng(seed)
    th, td, pd = rng.uniform(0, HALF_PI, 4 * n), rng.uniform(0, HALF_PI, 4 * n), rng.uniform(0, np.pi, 4 * n)
    wi, wo = io_from_half_diff(th, td, pd)
    keep = np.flatnonzero((wi[:, 2] > 0) & (wo[:, 2] > 0))[:n]
    return SampleSet(th[keep], td[keep], pd[keep], synthetic.evaluate(material, wi[keep], wo[keep]))


@pytest.mark.slow
def test_nbrdf_fits_a_smooth_material(library):
    from brdfkit.methods.nbrdf import fit_nbrdf

    table = library[0][2]  # alpha 0.4: broad lobe plus a diffuse part
    samples = draw_samples(table, 400, seed=0)
    untrained = fit_nbrdf(samples, steps=1, lr=1e-12, seed=0).to_table()
    model = fit_nbrdf(samples, steps=1500, seed=0)
    fitted = model.to_table()
    assert np.isnan(fitted[~valid_mask()]).all()
    err, err0 = brdf_log_rmse(fitted, table), brdf_log_rmse(untrained, table)
    assert err < 0.3 * err0, (err, err0)
    assert err < 0.1, err
    # eval_hd agrees with the table at the sampled cells.
    at = model.eval_hd(samples.hd())
    from brdfkit.geometry import cell_index
    np.testing.assert_allclose(at, fitted.reshape(-1, 3)[cell_index(samples.theta_h, samples.theta_d,
                                                                    samples.phi_d)], rtol=1e-5, atol=1e-6)


@pytest.mark.slow
def test_nbrdf_is_deterministic_by_seed():
    from brdfkit.methods.nbrdf import fit_nbrdf

    mat = synthetic.Material("d", "dielectric", 0.2, albedo=(0.4, 0.3, 0.2))
    samples = _analytic_samples(mat, 200)
    a = fit_nbrdf(samples, steps=200, seed=5)
    b = fit_nbrdf(samples, steps=200, seed=5)
    c = fit_nbrdf(samples, steps=200, seed=6)
    sa, sb, sc = a.net.state_dict(), b.net.state_dict(), c.net.state_dict()
    assert all(np.array_equal(sa[k].numpy(), sb[k].numpy()) for k in sa)
    assert not all(np.array_equal(sa[k].numpy(), sc[k].numpy()) for k in sa)
    assert a.loss == b.loss


@pytest.mark.slow
@pytest.mark.parametrize("case", ["one-sample", "stiff-mirror", "stiff-black"])
def test_nbrdf_stays_finite_on_stiff_input(case):
    from brdfkit.methods.nbrdf import fit_nbrdf

    stiff = {m.name: m for m in synthetic.STIFF}
    if case == "one-sample":
        samples = _analytic_samples(stiff["stiff-white"], 1)
    else:
        samples = _analytic_samples(stiff[case], 400)
        if case == "stiff-mirror":  # make sure the peak (values above 1e3) is in the set
            peak = SampleSet(np.array([0.0]), np.array([0.3]), np.array([1.0]),
                             synthetic.evaluate(stiff[case], *io_from_half_diff(0.0, 0.3, 1.0))[None])
            assert peak.rgb.max() > 1e3
            samples = SampleSet(*(np.concatenate([getattr(samples, k), getattr(peak, k)])
                                  for k in ("theta_h", "theta_d", "phi_d", "rgb")))
    model = fit_nbrdf(samples, steps=300, seed=0)
    table = model.to_table()
    ok = valid_mask()
    assert np.isfinite(table[ok]).all() and (table[ok] >= 0).all()
    assert np.isfinite(model.loss)


def test_nbrdf_refuses_bad_parameters():
    from brdfkit.methods.nbrdf import fit_nbrdf

    samples = _analytic_samples(synthetic.STIFF[2], 10)
    with pytest.raises(InputError, match="steps"):
        fit_nbrdf(samples, steps=0)
    with pytest.raises(InputError, match="learning rate"):
        fit_nbrdf(samples, lr=float("nan"))


# --- registry ---------------------------------------------------------------------------------

@pytest.mark.slow
def test_registry_names_and_uniform_interface(basis, library, tmp_path):
    assert set(METHODS) == {"hypernet", "ipca", "nbrdf", "prior"}
    with pytest.raises(InputError, match="unknown method 'pca'.*ipca"):
        get_method("pca")
    ipca = get_method("ipca")
    path = tmp_path / "basis.safetensors"
    save_basis(path, basis)
    samples = draw_samples(library[1], 500, seed=2)
    np.testing.assert_array_equal(ipca.reconstruct(samples, str(path)), basis.reconstruct(samples, floor=0.0))  # as published
    np.testing.assert_array_equal(ipca.reconstruct(samples, ipca.load(path), lam=0.5),
                                  basis.reconstruct(samples, lam=0.5, floor=0.0))
    with pytest.raises(InputError, match="needs a PCA basis"):
        ipca.reconstruct(samples)
    nbrdf = get_method("nbrdf")
    with pytest.raises(InputError, match="takes no model"):
        nbrdf.reconstruct(samples, str(path))
    table = nbrdf.reconstruct(samples, steps=20)
    assert table.shape == (90, 90, 180, 3) and np.isfinite(table[valid_mask()]).all()


def test_baselines_import_no_torch():
    code = ("import sys, brdfkit.methods, brdfkit.methods.ipca; "
            "sys.exit(1 if 'torch' in sys.modules else 0)")
    assert subprocess.run([sys.executable, "-c", code]).returncode == 0


# --- command line -----------------------------------------------------------------------------


@pytest.fixture(scope="module")
def cli_files(tmp_path_factory, library):
    from brdfkit.io.merl import write_merl
    from brdfkit.io.samples import write_samples

    train, held = library
    d = tmp_path_factory.mktemp("baselines-cli")
    data = d / "data"
    data.mkdir()
    for i in range(4):
        write_merl(data / f"mat-{i}.binary", train[i])
    (d / "exclude.txt").write_text("# held out\nmat-3\n")
    write_samples(d / "samples.csv", draw_samples(held, 300, seed=0, source="held"))
    return d


@pytest.mark.slow
def test_cli_fit_basis_then_sparse(cli_files, capsys, monkeypatch):
    from brdfkit.io.merl import read_merl
    from brdfkit.io.samples import read_samples

    monkeypatch.delenv("BRDFKIT_MODEL", raising=False)
    d = cli_files
    code, _, err = run_cli(capsys, ["fit", "--method", "basis", d / "data", "--exclude-list", d / "exclude.txt",
                                    "--components", 5, "-o", d / "basis.safetensors"])
    assert code == 0, err
    assert "note:" not in err
    basis = load_basis(d / "basis.safetensors")
    assert basis.materials == ["mat-0", "mat-1", "mat-2"] and basis.n_components == 5
    from brdfkit.models.parts import file_part
    from brdfkit.training import FITTERS

    assert file_part(d / "basis.safetensors").name == FITTERS["basis"].part  # the recipe's part is its file's
    # `fit --method ipca`, the old name, still trains the same basis, with a one-line note.
    code, _, err = run_cli(capsys, ["fit", "--method", "ipca", d / "data", "--exclude-list", d / "exclude.txt",
                                    "--components", 5, "-o", d / "basis-ipca.safetensors"])
    assert code == 0, err
    notes = [line for line in err.splitlines() if line.startswith("note:")]
    assert notes == ["note: fit --method ipca is now fit --method basis"] and "wrote PCA basis" in err
    again = load_basis(d / "basis-ipca.safetensors")
    assert (again.materials, again.n_components, again.w_floor) == (basis.materials, 5, basis.w_floor)
    for field in ("cells", "reference", "mean", "components", "sigma"):
        np.testing.assert_array_equal(getattr(again, field), getattr(basis, field))

    code, _, err = run_cli(capsys, ["sparse", d / "samples.csv", "--method", "ipca", "-m", d / "basis.safetensors",
                                    "-o", d / "ipca.binary"])
    assert code == 0, err
    want = basis.reconstruct(read_samples(d / "samples.csv"), floor=0.0)  # IPCA as published
    got = read_merl(d / "ipca.binary")
    np.testing.assert_array_equal(np.isnan(got), np.isnan(want))
    np.testing.assert_allclose(got[~np.isnan(want)], want[~np.isnan(want)], rtol=1e-12)

    # Without a basis, or with --components for the hypernetwork: one line, exit 2.
    code, _, err = run_cli(capsys, ["sparse", d / "samples.csv", "--method", "ipca", "-o", d / "x.binary"])
    assert code == 2 and "needs a PCA basis" in one_error_line(err)
    code, _, err = run_cli(capsys, ["fit", d / "data", "--components", 3, "-o", d / "y.safetensors"])
    assert code == 2 and "--components" in one_error_line(err)
    code, _, err = run_cli(capsys, ["fit", "--method", "basis", d / "data", "--components", 99,
                                    "-o", d / "y.safetensors"])
    assert code == 2 and "components" in one_error_line(err)
    assert not (d / "x.binary").exists() and not (d / "y.safetensors").exists()


@pytest.mark.slow
def test_cli_sparse_nbrdf_needs_no_model(cli_files, capsys, monkeypatch, library):
    from brdfkit.io.merl import read_merl

    d = cli_files
    # $BRDFKIT_MODEL (a hypernetwork) is not meant for nbrdf and must not get in the way.
    monkeypatch.setenv("BRDFKIT_MODEL", str(d / "exclude.txt"))
    code, _, err = run_cli(capsys, ["sparse", d / "samples.csv", "--method", "nbrdf", "-o", d / "nbrdf.binary"])
    assert code == 0, err
    table = read_merl(d / "nbrdf.binary")
    ok = valid_mask()
    assert np.isfinite(table[ok]).all() and np.isnan(table[~ok]).all()
    assert brdf_log_rmse(table, library[1]) < 0.3
    code, _, err = run_cli(capsys, ["sparse", d / "samples.csv", "--method", "nbrdf", "-m", d / "exclude.txt",
                                    "-o", d / "z.binary"])
    assert code == 2 and "takes no model" in one_error_line(err)


@pytest.mark.slow
def test_registry_hypernet_is_api_sparse(library, tmp_path):
    """The registry's ``hypernet`` entry is exactly ``brdfkit.api.sparse`` with that
    method, refined or not, and refined it is :func:`brdfkit.hypernet.refine_on_samples.refine` (an
    untrained tiny model is enough to check the plumbing)."""
    from brdfkit import api

    from helpers_model import make_model

    make_model(tmp_path / "model.safetensors", seed=0)
    method = get_method("hypernet")
    model = method.load(tmp_path / "model.safetensors", device="cpu")
    samples = draw_samples(library[1], 100, seed=0)
    np.testing.assert_array_equal(method.reconstruct(samples, model, refine=False),
                                  api.sparse(samples, model, refine=False)[0])
    np.testing.assert_array_equal(method.reconstruct(samples, model), api.sparse(samples, model)[0])
    from brdfkit.hypernet.refine_on_samples import RefineConfig, refine

    np.testing.assert_array_equal(method.reconstruct(samples, model),
                                  refine(model, samples, config=RefineConfig(target="weights")).brdf.to_table())
    with pytest.raises(InputError, match="needs a hypernetwork model"):
        method.reconstruct(samples)


def test_registry_options_and_one_call(basis, library, tmp_path):
    """Each method's options dataclass holds its defaults and refuses what it does not
    take; ``reconstruct(samples, method=...)`` is the method's own call."""
    from brdfkit.methods import reconstruct
    from brdfkit.basis import DEFAULT_LAMBDA
    from brdfkit.methods.nbrdf import DEFAULT_STEPS

    assert get_method("ipca").defaults() == {"lam": DEFAULT_LAMBDA}
    assert get_method("nbrdf").defaults()["steps"] == DEFAULT_STEPS
    from brdfkit.hypernet.refine_on_samples import RefineConfig
    from brdfkit.methods.hypernet import DEFAULT_REFINE_STEPS

    assert DEFAULT_REFINE_STEPS == RefineConfig().max_steps
    assert get_method("hypernet").defaults() == {"refine": True, "refine_target": "weights",
                                                  "steps": DEFAULT_REFINE_STEPS}
    assert get_method("hypernet").make_options(steps=20).quick().steps == 10
    for bad in (0, 2.5, True, "many"):
        with pytest.raises(InputError, match="hypernet option steps must be a whole number"):
            get_method("hypernet").make_options(steps=bad)
    assert get_method("nbrdf").make_options(steps=None, lr=0.01).steps == DEFAULT_STEPS
    with pytest.raises(InputError, match="'ipca' takes the option.*lam, got lr"):
        get_method("ipca").make_options(lr=1.0)
    with pytest.raises(InputError, match="'hypernet' takes the option.*refine, refine_target, steps, got lam"):
        get_method("hypernet").make_options(lam=1.0)
    with pytest.raises(InputError, match="refine_target"):
        get_method("hypernet").make_options(refine_target="bias")
    with pytest.raises(InputError, match="lam"):
        get_method("ipca").make_options(lam=-1.0)
    path = tmp_path / "basis.safetensors"
    save_basis(path, basis)
    samples = draw_samples(library[1], 300, seed=4)
    np.testing.assert_array_equal(reconstruct(samples, method="ipca", model=path, lam=0.5),
                                  basis.reconstruct(samples, lam=0.5, floor=0.0))
    with pytest.raises(InputError, match="unknown method"):
        reconstruct(samples, method="pca")
    # What `brdfkit fit` trains is its own registry; a reconstruction method has no fit.
    from brdfkit.training import FITTERS, get_fitter

    assert list(FITTERS) == ["hypernet", "basis", "prior", "residual"]
    assert get_fitter("ipca") is FITTERS["basis"]  # the old name of the basis recipe
    assert not any(hasattr(m, "fit") or hasattr(m, "fit_fn") for m in METHODS.values())
    with pytest.raises(InputError, match="unknown --method 'nbrdf' for fit"):
        get_fitter("nbrdf")


@pytest.mark.slow
def test_ipca_weight_floor(library, tmp_path):
    """A basis whose mapping weight is bounded below (``w_floor``, issue 22's grazing
    angles): the weight it maps with, its file, and a held-out material's grazing cells
    reconstructed no darker than Nielsen's mapping leaves them."""
    from brdfkit.evaluation.metrics import dark_at_grazing

    train, held = library
    floor = fit_basis(train, n_components=4, w_floor=0.1)
    plain = fit_basis(train, n_components=4)
    th = np.array([0.0, 1.45, 1.6])  # the last below the horizon
    np.testing.assert_allclose(floor.weight(th, 0 * th, 0 * th), [1.0, 0.1, 0.0], atol=1e-12)
    np.testing.assert_allclose(plain.weight(th[:2], 0 * th[:2], 0 * th[:2]), [1.0, np.cos(1.45) ** 2])
    path = tmp_path / "floor.safetensors"
    save_basis(path, floor, half=True, phi_stride=2)
    assert load_basis(path).w_floor == 0.1 and load_basis(tmp_path / "floor.safetensors").n_components == 4
    save_basis(tmp_path / "plain.safetensors", plain)
    assert load_basis(tmp_path / "plain.safetensors").w_floor == 0.0
    samples = draw_samples(held, 2000, seed=0)
    dark_floor = dark_at_grazing(floor.reconstruct(samples), held)
    dark_plain = dark_at_grazing(plain.reconstruct(samples), held)
    assert dark_floor <= dark_plain and dark_floor < 0.01, (dark_floor, dark_plain)
    with pytest.raises(InputError, match=r"w_floor must be in \[0, 1\)"):
        fit_basis(train, n_components=2, w_floor=1.0)
