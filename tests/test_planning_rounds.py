"""Measuring in rounds (``brdfkit plan --given``, ``sample --at --given``;
:mod:`brdfkit.acquisition.rounds`): the plan without samples unchanged to the byte, the
greedy started from the posterior after the given samples, the learnt prior's posterior
read from the values measured, a measured cell never planned again, one line for bad
input. A 4-component basis of three synthetic tables, so that every plan takes a second."""

from __future__ import annotations

import dataclasses
import hashlib

import numpy as np
import pytest

from brdfkit.acquisition.designs import CandidatePool
from brdfkit.acquisition.optimal_design import greedy_render
from brdfkit.acquisition.planning import plan_directions, plan_target
from brdfkit.acquisition.rounds import (channel_metric, channel_precision, expected_error, posterior_after,
                                        posterior_draws)
from brdfkit.acquisition.sampling import draw_samples, join_samples, measure_samples
from brdfkit.errors import InputError
from brdfkit.geometry import N_CELLS, cell_index
from brdfkit.io.directions import read_directions
from brdfkit.io.samples import read_samples, write_samples

from conftest import one_error_line, run_cli, tmp_leftovers
from helpers_bad_input import nothing_written
from helpers_model import material_table

FAST = dict(draws=1, candidates=5000)  # a plan in about a second on the tiny basis
FAST_ARGS = ["--draws", "1", "--candidates", "5000"]


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    """The tiny basis's file (named as the recorded plan below names it), a material and
    its first round: four directions of the render design, measured."""
    from brdfkit.testing.examples import tiny_basis_file

    root = tmp_path_factory.mktemp("rounds")
    basis = tiny_basis_file(root / "tiny.safetensors", 4)
    first = plan_directions(basis, 4, **FAST)
    so_far = measure_samples(material_table(1), first.directions, source="s1.csv")
    write_samples(root / "s1.csv", so_far)
    return {"root": root, "basis": basis, "first": first, "s1": root / "s1.csv", "so_far": so_far}


def _cells(directions):
    return cell_index(directions.theta_h, directions.theta_d, directions.phi_d)


# --- a plan without samples is what it was -------------------------------------------------

def _greedy_before_rounds(rows, q, metric, n):
    """greedy_render as it was before it took channels and a start (commit dc93d44)."""
    p, k = rows.shape
    a, m, s = np.asarray(rows, np.float64), np.asarray(metric, np.float64), np.eye(k)
    ua, vu = np.einsum("ij,ij->i", a, a), np.einsum("ij,ij->i", a @ m, a)
    taken, chosen = np.zeros(p, bool), []
    for _ in range(n):
        den = 1.0 + q * ua
        i = int(np.argmax(np.where(taken, -np.inf, q * vu / den)))
        chosen.append(i)
        taken[i] = True
        si = s @ a[i]
        scale = q[i] / den[i]
        msi = m @ si
        au, b = a @ si, a @ (s @ msi)
        vu += scale * au * (scale * au * float(msi @ si) - 2.0 * b)
        ua -= scale * au * au
        s -= scale * np.outer(si, si)
    return np.array(chosen, np.int64)


def test_the_greedy_without_samples_does_the_same_arithmetic():
    rng = np.random.default_rng(4)
    for p, k in ((300, 5), (2000, 30)):
        rows, q = rng.normal(size=(p, k)), rng.uniform(0.5, 20, size=p)
        j = rng.normal(size=(40, k))
        np.testing.assert_array_equal(greedy_render(rows, q, j.T @ j, 12), _greedy_before_rounds(rows, q, j.T @ j, 12))


def test_plan_without_given_is_the_plan_it_was(tiny, tmp_path, capsys):
    """The bytes `brdfkit plan` wrote before plans took samples (recorded at dc93d44 on
    the development machine): a change of the tiny basis's fit or of the screen render
    changes them too, and then this record is made again."""
    out = tiny["root"] / "golden.csv"
    code, _, err = run_cli(capsys, ["plan", "-n", "6", "-m", tiny["basis"], "--draws", "1", "--candidates", "3000",
                                    "-o", out])
    assert code == 0, err
    assert plan_directions(tiny["basis"], 6, draws=1, candidates=3000).cells.tolist() == \
        [550876, 1069224, 16303, 632727, 599426, 42057]
    assert out.read_text().splitlines()[0] == ("# brdfkit plan: design render, N = 6, seed 0; basis of "
                                               "tiny.safetensors: 4 components, condition number 36.4")
    assert hashlib.sha256(out.read_bytes()).hexdigest() == \
        "e3cac607e3f8a0f3fd0881b8eae58afb39282906a5d2606cafb7e0cc38fc2ebc"
    out.unlink()


# --- the greedy from a posterior -------------------------------------------------------------

def test_the_greedy_starts_from_the_posterior_it_is_given():
    """Candidates that each inform one component, the screen most sensitive to the first:
    from the prior the greedy measures the first component; when given samples have
    pinned it, the others."""
    k = 3
    rows = np.vstack([np.eye(k)] * 4) * np.repeat([1.0, 0.9, 0.8, 0.7], k)[:, None]  # 12 candidates
    q = np.ones(rows.shape[0])
    metric = np.diag([10.0, 3.0, 1.0])
    assert [int(np.argmax(np.abs(rows[i]))) for i in greedy_render(rows, q, metric, 1)] == [0]
    pinned = np.diag([1e-6, 1.0, 1.0])[None]  # the first component measured to 1e-3
    chosen = greedy_render(rows, q, metric, 2, start=pinned)
    assert sorted(int(np.argmax(np.abs(rows[i]))) for i in chosen) == [1, 2]
    # three channels: the summed gain; a channel whose posterior is pinned asks for nothing
    start = np.stack([pinned[0], pinned[0], np.eye(k)])
    assert int(np.argmax(np.abs(rows[greedy_render(rows, np.ones((3, 12)), np.stack([metric] * 3), 1,
                                                   start=start)[0]]))) == 0
    errs = [expected_error(rows, np.ones((1, 12)), metric[None], pinned, c) for c in ((), chosen)]
    assert errs[1] < errs[0]


def test_a_given_plan_is_better_for_the_posterior_than_the_plan_that_ignores_it(tiny):
    """The plan given samples, and the plan the same design makes from the prior among the
    same candidates (the given cells left out): under the posterior after the samples the
    first leaves a lower expected error (equal if the samples were ignored), and both
    leave less than the prior alone would."""
    target = plan_target(tiny["basis"])
    post = posterior_after(target, tiny["so_far"])
    plan = plan_directions(tiny["basis"], 4, given=tiny["so_far"], **FAST)
    whole = CandidatePool.of(target[0], target[2])
    pool = whole.restricted(~np.isin(whole.cells, post.cells))
    pick = np.sort(np.random.default_rng(0).choice(pool.cells.size, size=FAST["candidates"], replace=False))
    cs = posterior_draws(target[0], post, FAST["draws"], 0)
    rows, q = pool.rows[pick], channel_precision(target[0], pool.cells[pick], target[2], cs)
    metric = channel_metric(target[0], cs)
    given = np.searchsorted(pool.cells[pick], plan.cells)
    np.testing.assert_array_equal(pool.cells[pick][given], plan.cells)
    blind = greedy_render(rows, q, metric, 4)
    assert not np.array_equal(np.sort(given), np.sort(blind))
    ours, theirs = (expected_error(rows, q, metric, post.covariance, c) for c in (given, blind))
    assert ours < theirs
    assert plan.expected_error == pytest.approx((expected_error(rows, q, metric, post.covariance), ours))
    prior_only = expected_error(rows, q, metric, np.stack([np.eye(4)] * 3))
    assert plan.expected_error[0] < prior_only


def test_the_posterior_of_a_plain_basis_depends_on_where_the_learnt_prior_on_what(tiny):
    """IPCA's posterior covariance is the same for two materials measured at the same
    directions; a learnt prior's (its likelihood at the values, its spread read from
    them) is not. Its estimate is its fit's."""
    from brdfkit.prior.model import PriorConfig, PriorModel, PriorWeights
    from brdfkit.testing.examples import tiny_basis

    basis = tiny_basis(4)
    a = measure_samples(material_table(1), tiny["first"].directions)
    b = measure_samples(material_table(0), tiny["first"].directions)
    plain = [posterior_after(plan_target(basis), s) for s in (a, b)]
    np.testing.assert_array_equal(plain[0].covariance, plain[1].covariance)
    assert not np.allclose(plain[0].estimate, plain[1].estimate)

    cfg = PriorConfig(n_components=4, latent_dim=8, width=16, spread=True)
    dims = {"encoder": (9, 16, 16, 8), "head": (8 + 12 + 1, 16, 16, 24)}
    rng = np.random.default_rng(0)
    state = {f"{part}.{2 * i}.{kind}": rng.normal(scale=0.3, size=(o, i_) if kind == "weight" else (o,))
             for part, d in dims.items() for i, (i_, o) in enumerate(zip(d[:-1], d[1:]))
             for kind in ("weight", "bias")}
    model = PriorModel(basis, PriorWeights(cfg, state), cfg)
    learnt = [posterior_after(plan_target(model), s) for s in (a, b)]
    assert not np.allclose(learnt[0].covariance, learnt[1].covariance)
    np.testing.assert_allclose(learnt[0].estimate, model.fit(a).coefficients)
    plan = plan_directions(model, 3, given=a, **FAST)
    assert not np.isin(plan.cells, _cells(a)).any()


# --- the command ----------------------------------------------------------------------------

def test_plan_given_is_deterministic_and_never_plans_a_measured_cell(tiny, tmp_path, capsys):
    outs = [tmp_path / "p2.csv", tmp_path / "p2-again.csv"]
    for out in outs:
        code, _, err = run_cli(capsys, ["plan", "-n", "4", "-m", tiny["basis"], "--given", tiny["s1"], *FAST_ARGS,
                                        "-o", out])
        assert code == 0, err
    assert outs[0].read_bytes() == outs[1].read_bytes()
    want = plan_directions(tiny["basis"], 4, given=read_samples(tiny["s1"]), **FAST)
    head = outs[0].read_text().splitlines()[0]
    assert head == f"# brdfkit plan: {want.describe()}"
    assert head.startswith("# brdfkit plan: design render, N = 4, seed 0, given 4 samples of s1.csv; basis of "
                           "tiny.safetensors: 4 components, condition number ")
    assert "with the given samples; expected screen error " in head
    cells = _cells(read_directions(outs[0]))
    np.testing.assert_array_equal(cells, want.cells)
    assert np.unique(cells).size == 4 and not np.isin(cells, tiny["first"].cells).any()
    # the plan without the samples would have measured there again: the blind plan of 8
    # begins with the first round
    blind = plan_directions(tiny["basis"], 8, **FAST).cells
    np.testing.assert_array_equal(blind[:4], tiny["first"].cells)
    assert not tmp_leftovers(tmp_path)


def test_within_an_instruments_directions_not_yet_given(tiny, tmp_path, capsys):
    reachable = draw_samples(material_table(1), 40, seed=6, source="reachable.csv")
    write_samples(tmp_path / "reachable.csv", reachable)
    so_far = reachable.subset(np.arange(0, 40, 4))  # ten of them measured
    write_samples(tmp_path / "so-far.csv", so_far)
    own = np.unique(_cells(reachable))
    out = tmp_path / "p.csv"
    code, _, err = run_cli(capsys, ["plan", "-n", "5", "-m", tiny["basis"], "--within", tmp_path / "reachable.csv",
                                    "--given", tmp_path / "so-far.csv", *FAST_ARGS, "-o", out])
    assert code == 0, err
    cells = _cells(read_directions(out))
    assert np.isin(cells, own).all() and not np.isin(cells, _cells(so_far)).any()
    left = np.setdiff1d(own, _cells(so_far)).size
    code, _, err = run_cli(capsys, ["plan", "-n", str(left + 1), "-m", tiny["basis"], "--within",
                                    tmp_path / "reachable.csv", "--given", tmp_path / "so-far.csv", "-o", out])
    assert code == 2
    assert one_error_line(err) == (f"brdfkit: error: {left + 1} directions asked for, but reachable.csv has "
                                   f"directions in only {left} cells the basis covers and not measured yet")


def _off_grid_basis(tiny, tmp_path):
    """The tiny basis on the cells of theta_h index below 45 only."""
    from brdfkit.basis import load_basis, save_basis

    basis = load_basis(tiny["basis"])
    keep = basis.cells // (90 * 180) < 45
    part = dataclasses.replace(basis, cells=basis.cells[keep], reference=basis.reference[keep],
                               mean=basis.mean[keep], components=basis.components[:, keep], _dense=None)
    save_basis(tmp_path / "half.safetensors", part)
    return tmp_path / "half.safetensors"


@pytest.mark.parametrize("case, message", [
    ("empty", "{given}: no sample rows after the header"),
    ("binary", "{given}: not a CSV text file (binary content)"),
    ("missing", "{given}: no such file"),
    ("directions", "{given}: line 3: columns theta_h,theta_d,phi_d,wi_x,wi_y,wi_z,wo_x,wo_y,wo_z are not a known "
                   "set"),
    ("off the basis", "given.csv: no sample lies on a cell the PCA basis covers"),
    ("nielsen", "design 'nielsen' does not plan given samples; the design(s) that do: render"),
    ("uniform", "design 'uniform' does not plan given samples; the design(s) that do: render"),
    ("output", "{given}: output path is also an input"),
])
def test_plan_given_bad_input_one_line(tiny, tmp_path, capsys, case, message):
    given, model, out, extra = tmp_path / "given.csv", tiny["basis"], tmp_path / "plan.csv", []
    if case == "empty":
        given.write_text("theta_h,theta_d,phi_d,r,g,b\n")
    elif case == "binary":
        given.write_bytes(b"\x00\x01\x02 not text")
    elif case == "directions":  # a plan where its measurements belong
        code, _, err = run_cli(capsys, ["plan", "-n", "3", "-m", model, "--design", "nielsen", "-o", given])
        assert code == 0, err
    elif case == "off the basis":  # measured where the basis has no cell
        drawn = draw_samples(material_table(1), 60, seed=2, source="given.csv")
        write_samples(given, drawn.subset(_cells(drawn) // (90 * 180) >= 45))
        model = _off_grid_basis(tiny, tmp_path)
    elif case in ("nielsen", "uniform"):
        given, extra = tiny["s1"], ["--design", case]
    elif case == "output":
        given = tmp_path / "s1.csv"
        given.write_bytes(tiny["s1"].read_bytes())
        out = given
    before = given.read_bytes() if given.exists() else None
    code, _, err = run_cli(capsys, ["plan", "-n", "3", "-m", model, "--given", given, *extra, "-o", out])
    assert code == 2
    line = one_error_line(err)
    assert line.startswith("brdfkit: error: " + message.format(given=given)), line
    if case == "output":
        assert given.read_bytes() == before
    else:
        nothing_written(tmp_path, out)


def test_sample_at_given_writes_the_samples_so_far_then_the_rounds(tiny, tmp_path, capsys):
    plan, out = tmp_path / "p2.csv", tmp_path / "s2.csv"
    code, _, err = run_cli(capsys, ["plan", "-n", "4", "-m", tiny["basis"], "--given", tiny["s1"], *FAST_ARGS,
                                    "-o", plan])
    assert code == 0, err
    table = tmp_path / "m.binary"
    from brdfkit.io.merl import write_merl

    write_merl(table, material_table(1))
    code, _, err = run_cli(capsys, ["sample", table, "--at", plan, "--given", tiny["s1"], "-o", out])
    assert code == 0, err
    assert f"wrote 4 samples of {table} at the directions of {plan} after the 4 samples of {tiny['s1']} to {out}" \
        in " ".join(err.split())
    got, first = read_samples(out), read_samples(tiny["s1"])
    round2 = measure_samples(material_table(1), read_directions(plan))
    want = join_samples(first, round2)
    for k in ("theta_h", "theta_d", "phi_d"):
        np.testing.assert_array_equal(getattr(got, k), getattr(want, k))
    np.testing.assert_array_equal(got.rgb[:4], first.rgb)  # the samples so far, as they were
    np.testing.assert_allclose(got.rgb, want.rgb, rtol=1e-12)  # the table through its MERL file
    np.testing.assert_allclose(got.rgb[4:], material_table(1).reshape(N_CELLS, 3)[_cells(round2)], rtol=1e-12)
    # the refusals: --given with -n, the output over the samples so far
    code, _, err = run_cli(capsys, ["sample", table, "-n", "4", "--given", tiny["s1"], "-o", tmp_path / "x.csv"])
    assert code == 2 and one_error_line(err) == ("brdfkit: error: --given applies to --at (a round measured at "
                                                 "planned directions), not to -n")
    before = out.read_bytes()
    code, _, err = run_cli(capsys, ["sample", table, "--at", plan, "--given", out, "-o", out])
    assert code == 2 and "output path is also an input" in one_error_line(err)
    assert out.read_bytes() == before and not (tmp_path / "x.csv").exists() and not tmp_leftovers(tmp_path)


def test_plan_given_refuses_no_samples_in_the_library(tiny):
    from brdfkit.io.samples import SampleSet

    empty = SampleSet(*(np.zeros(0) for _ in range(3)), np.zeros((0, 3)), "none.csv")
    with pytest.raises(InputError, match="^none.csv: no samples given$"):
        plan_directions(tiny["basis"], 3, given=empty, **FAST)
