"""``brdfkit plan`` and ``brdfkit.acquisition.planning``: measurement directions chosen for a PCA
basis (Nielsen et al. 2015) or drawn uniformly; a plan measured (``sample --at``) and
reconstructed (``sparse``); bad inputs refused in one line. Real files throughout: a
small basis fitted here on synthetic tables, and the basis the package ships."""

from __future__ import annotations

import os

import numpy as np
import pytest

import brdfkit
import brdfkit.basis
from brdfkit.io.directions import read_directions
from brdfkit.errors import InputError
from brdfkit.geometry import N_CELLS, cell_angles, grid_cosine_weight, valid_cells
from brdfkit.io.merl import read_merl, write_merl
from brdfkit.acquisition.planning import condition_number, design_rows, plan_directions
from brdfkit.acquisition.designs import DESIGNS
from brdfkit.io.samples import read_samples
from brdfkit.acquisition.sampling import draw_samples

from conftest import tmp_leftovers
from conftest import one_error_line, run_cli
from helpers_bad_input import nothing_written
from helpers_model import material_table

SHIPPED_BASIS = os.path.join(os.path.dirname(brdfkit.__file__), "models", "merl80-basis.safetensors")


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    """Four synthetic GGX tables and a 5-component basis fitted to them."""
    from brdfkit.basis import fit_basis, save_basis

    from helpers_training import synthetic_library

    root = tmp_path_factory.mktemp("planning")
    tables = sorted(synthetic_library(tmp_path_factory, 4, seed=5).glob("*.binary"))
    save_basis(root / "basis.safetensors", fit_basis(tables, n_components=5))
    return {"root": root, "tables": tables, "basis": root / "basis.safetensors"}


@pytest.fixture(scope="module")
def shipped():
    if not os.path.isfile(SHIPPED_BASIS):
        pytest.skip("no built-in basis in this checkout (brdfkit/models)")
    from brdfkit.basis import load_basis

    return load_basis(SHIPPED_BASIS)


# --- the designs ----------------------------------------------------------------------------

def test_registry_names():
    assert list(DESIGNS) == ["nielsen", "render", "uniform"]
    assert DESIGNS["nielsen"].needs_basis and DESIGNS["render"].needs_basis and not DESIGNS["uniform"].needs_basis


@pytest.mark.slow
@pytest.mark.parametrize("n", [3, 12])  # fewer and more directions than the 5 components
def test_nielsen_plan_is_deterministic_distinct_and_measurable(small, n):
    a = plan_directions(small["basis"], n, design="nielsen", seed=0)
    b = plan_directions(small["basis"], n, design="nielsen", seed=0)
    c = plan_directions(small["basis"], n, design="nielsen", seed=1)
    np.testing.assert_array_equal(a.cells, b.cells)
    assert not np.array_equal(a.cells, c.cells)
    assert len(a) == n and np.unique(a.cells).size == n
    assert np.isin(a.cells, valid_cells()).all() and (grid_cosine_weight()[a.cells] > 0).all()
    th, td, pd = cell_angles(a.cells)
    np.testing.assert_array_equal(a.directions.theta_h, th)
    np.testing.assert_array_equal(a.directions.phi_d, pd)
    wi, wo = a.directions.vectors()
    assert (wi[:, 2] > 0).all() and (wo[:, 2] > 0).all()
    assert a.design == "nielsen" and a.components == 5 and a.basis == "basis.safetensors"
    assert np.isfinite(a.condition_number) and a.condition_number >= 1
    assert a.condition_number == condition_number(design_rows(brdfkit.basis.load_basis(small["basis"]),
                                                               a.directions))


@pytest.mark.slow
def test_refinement_only_lowers_the_condition_number(small):
    for n in (4, 10, 30):
        greedy = plan_directions(small["basis"], n, design="nielsen", seed=2, refine=False)
        refined = plan_directions(small["basis"], n, design="nielsen", seed=2, refine=True)
        assert refined.condition_number <= greedy.condition_number * (1 + 1e-9)


@pytest.mark.slow
def test_nielsen_beats_uniform_draws_on_the_small_basis(small):
    for n in (10, 20, 40):
        planned = plan_directions(small["basis"], n, design="nielsen", seed=0).condition_number
        for seed in range(3):
            assert planned < plan_directions(small["basis"], n, design="uniform", seed=seed).condition_number


@pytest.mark.slow
def test_nielsen_beats_uniform_draws_on_the_shipped_basis(shipped):
    """The claim of docs/planning.md, on the basis of merl80-l40 (and of merl-rgl-l40)."""
    for n in (10, 20, 40):
        planned = plan_directions(shipped, n, design="nielsen", seed=0)
        uniform = [plan_directions(shipped, n, design="uniform", seed=s).condition_number for s in range(5)]
        assert planned.condition_number < min(uniform), (n, planned.condition_number, uniform)


def test_uniform_plan_is_what_sample_n_draws():
    table = material_table(1)  # measured exactly at the measurable cells
    plan = plan_directions(None, 200, design="uniform", seed=3)
    drawn = draw_samples(table, 200, seed=3)
    for k in ("theta_h", "theta_d", "phi_d"):
        np.testing.assert_array_equal(getattr(plan.directions, k), getattr(drawn, k))
    assert plan.basis is None and plan.condition_number is None


def test_condition_number_of_fewer_rows_than_components():
    # Two rows in four components: the two non-zero singular values, 3 and 1.
    rows = np.array([[3.0, 0, 0, 0], [0, 1.0, 0, 0]]) @ np.linalg.qr(np.random.default_rng(0).normal(size=(4, 4)))[0]
    assert condition_number(rows) == pytest.approx(3.0)
    assert condition_number(rows[:1]) == 1.0
    assert condition_number(np.vstack([rows[0], 2 * rows[0]])) == float("inf")  # dependent rows
    assert condition_number(np.zeros((0, 4))) == float("inf")


@pytest.mark.slow
def test_design_rows_leave_out_what_the_fit_leaves_out(small):
    from brdfkit.io.directions import DirectionSet
    from brdfkit.basis import load_basis

    basis = load_basis(small["basis"])
    cells = valid_cells()[:: 100_000]
    th, td, pd = cell_angles(cells)
    rows = design_rows(basis, DirectionSet(np.append(th, 1.2), np.append(td, 1.2), np.append(pd, 0.0)))
    assert rows.shape == (cells.size, 5)  # the pair below the horizon has no weight
    pos = np.searchsorted(basis.cells, cells)
    np.testing.assert_allclose(rows, basis.components[:, pos].T * basis.sigma, rtol=1e-6)


@pytest.mark.parametrize("call, message", [
    (dict(design="sobol"), "unknown design 'sobol'; known: nielsen, render, uniform"),
    (dict(n=0), "number of directions must be at least 1, got 0"),
    (dict(design="uniform", evaluations=3), "design 'uniform' takes no options, got evaluations"),
    (dict(tries=3), "design 'render' takes the option(s) draws, candidates, got tries"),
    (dict(design="nielsen", tries=3), "design 'nielsen' takes the option(s) evaluations, refine, got tries"),
])
def test_plan_directions_refuses(small, call, message):
    call = {"n": 5, **call}
    with pytest.raises(InputError) as e:
        plan_directions(small["basis"], call.pop("n"), **call)
    assert str(e.value) == message


def test_no_basis_and_no_default_built_in():
    # conftest points $BRDFKIT_BUILTIN_MODELS at an empty folder
    with pytest.raises(InputError, match="no PCA basis given: pass -m NAME"):
        plan_directions(None, 5)


# --- the command ----------------------------------------------------------------------------

@pytest.mark.slow
def test_plan_sample_sparse_round_trip(small, tmp_path, capsys):
    """What a lab does: plan, measure there, reconstruct (docs/planning.md)."""
    plan, samples, out = tmp_path / "plan.csv", tmp_path / "s.csv", tmp_path / "r.binary"
    code, _, err = run_cli(capsys, ["plan", "-n", "12", "-m", small["basis"], "--seed", "4", "--draws", "1",
                                    "--candidates", "5000", "-o", plan])
    assert code == 0, err
    said = " ".join(err.split())
    want = plan_directions(small["basis"], 12, seed=4, draws=1, candidates=5000)
    assert f"wrote 12 directions to {plan} (design render, N = 12, seed 4; basis of basis.safetensors: " \
           f"5 components, condition number {want.condition_number:.4g})" in said
    text = plan.read_text().splitlines()
    assert text[0] == f"# brdfkit plan: {want.describe()}" and text[1].startswith("# ")
    assert text[2] == "theta_h,theta_d,phi_d,wi_x,wi_y,wi_z,wo_x,wo_y,wo_z"
    got = read_directions(plan)
    np.testing.assert_array_equal(got.theta_h, want.directions.theta_h)

    material = small["tables"][1]
    code, _, err = run_cli(capsys, ["sample", material, "--at", plan, "-o", samples])
    assert code == 0, err
    measured = read_samples(samples)
    np.testing.assert_allclose(measured.rgb, read_merl(material).reshape(N_CELLS, 3)[want.cells],
                               rtol=1e-12, atol=0)
    code, _, err = run_cli(capsys, ["sparse", samples, "--method", "ipca", "-m", small["basis"], "-o", out])
    assert code == 0, err
    table = read_merl(out)
    assert np.isfinite(table.reshape(N_CELLS, 3)[valid_cells()]).all()
    assert not tmp_leftovers(tmp_path)


def test_plan_uniform_without_a_basis(tmp_path, capsys):
    code, _, err = run_cli(capsys, ["plan", "-n", "7", "--design", "uniform", "--seed", "2", "-o", tmp_path / "u.csv"])
    assert code == 0, err
    np.testing.assert_array_equal(read_directions(tmp_path / "u.csv").theta_d,
                                  plan_directions(None, 7, design="uniform", seed=2).directions.theta_d)


@pytest.mark.parametrize("args, message", [
    (["-n", "0"], "Invalid value for '-n' / '--count': 0 is not in the range x>=1. (see 'brdfkit plan --help')"),
    (["-n", "5", "--design", "sobol"], "Invalid value for '--design': 'sobol' is not one of 'nielsen', 'render', 'uniform'. "
                                       "(see 'brdfkit plan --help')"),
    (["-n", "5", "--design", "uniform", "--evaluations", "9"], "--evaluations do not apply to --design uniform"),
    (["-n", "5", "--design", "uniform", "--no-refine"], "--refine do not apply to --design uniform"),
    (["-n", "5", "--design", "nielsen", "--draws", "3"], "--draws do not apply to --design nielsen"),
    (["-n", "5", "-m", "no-such-model"], "unknown model 'no-such-model'"),
    (["-n", "5", "-m", "{missing}"], "{missing}: no such file"),
    (["-n", "5", "-m", "{table}"], "{table}: not a PCA basis or a learnt-prior model file; planning needs a basis"),
    (["-n", "5"], "no PCA basis given: pass -m NAME"),
    (["-n", "9999999", "-m", "{basis}"], "9999999 directions asked for, but the basis covers only"),
])
def test_plan_bad_input_one_line(small, tmp_path, capsys, args, message):
    table = tmp_path / "t.binary"
    write_merl(table, material_table(1))
    subs = {"missing": tmp_path / "missing.safetensors", "table": table, "basis": small["basis"]}
    out = tmp_path / "plan.csv"
    code, _, err = run_cli(capsys, ["plan", *[a.format(**subs) for a in args], "-o", out])
    assert code == 2
    assert one_error_line(err).startswith("brdfkit: error: " + message.format(**subs)), err
    nothing_written(tmp_path, out)


def test_plan_refuses_to_overwrite_its_basis(small, tmp_path, capsys):
    import shutil

    basis = tmp_path / "basis.safetensors"
    shutil.copy(small["basis"], basis)
    before = basis.read_bytes()
    code, _, err = run_cli(capsys, ["plan", "-n", "5", "-m", basis, "--design", "nielsen", "-o", basis])
    assert code == 2 and "output path is also an input" in one_error_line(err)
    assert basis.read_bytes() == before


def test_plan_output_is_atomic(small, tmp_path, capsys):
    # An existing output is replaced whole, never left half-written, and no temporary
    # file stays behind.
    out = tmp_path / "plan.csv"
    out.write_text("old\n")
    code, _, err = run_cli(capsys, ["plan", "-n", "6", "-m", small["basis"], "--design", "nielsen", "-o", out])
    assert code == 0, err
    assert len(read_directions(out)) == 6 and not tmp_leftovers(tmp_path)
    code, _, err = run_cli(capsys, ["plan", "-n", "6", "-m", small["basis"], "--design", "nielsen", "-o",
                                    tmp_path / "nope" / "p.csv"])
    assert code == 2 and "does not exist" in one_error_line(err)
    assert len(read_directions(out)) == 6 and not tmp_leftovers(tmp_path)


@pytest.mark.slow
def test_plan_with_a_built_in_name(shipped, tmp_path, monkeypatch, capsys):
    from brdfkit.models.builtin import models_folder, read_manifest

    monkeypatch.delenv("BRDFKIT_BUILTIN_MODELS", raising=False)
    if not any(m.name == "merl80-l40" for m in read_manifest(models_folder()).installed()):
        pytest.skip("merl80-l40 is not installed in this checkout")
    code, _, err = run_cli(capsys, ["plan", "-n", "20", "-m", "merl80-l40", "--design", "nielsen", "-o",
                                    tmp_path / "p.csv"])
    assert code == 0, err
    np.testing.assert_array_equal(read_directions(tmp_path / "p.csv").theta_h,
                                  plan_directions(shipped, 20, design="nielsen").directions.theta_h)


@pytest.mark.slow
def test_plan_for_a_learnt_prior_file_is_the_plan_for_its_basis(small, tmp_path, capsys):
    """-m a learnt-prior file (`brdfkit fit --method prior`): its basis, as inside it."""
    # The small basis's four tables: two folds of two, the fewest the prior's fit takes.
    basis, prior = small["basis"], tmp_path / "p.safetensors"
    code, _, err = run_cli(capsys, ["fit", "--method", "prior", small["tables"][0].parent, "-O", f"basis={basis}",
                                    "-O", "folds=2", "--steps", "3", "-o", prior])
    assert code == 0, err
    code, _, err = run_cli(capsys, ["plan", "-n", "6", "-m", prior, "--design", "nielsen", "-o", tmp_path / "p.csv"])
    assert code == 0, err
    assert "basis of p.safetensors: 5 components" in " ".join(err.split())
    np.testing.assert_array_equal(read_directions(tmp_path / "p.csv").theta_h,
                                  plan_directions(basis, 6, design="nielsen").directions.theta_h)
