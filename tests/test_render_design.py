"""The ``render`` design of ``brdfkit plan`` (:mod:`brdfkit.acquisition.optimal_design`): the greedy
choice against a brute-force minimum of the expected render error, the metric against
finite differences of the screen render, and plans on a small basis fitted here."""

from __future__ import annotations

import numpy as np
import pytest

from brdfkit.errors import InputError
from brdfkit.acquisition.planning import plan_directions, plan_target
from brdfkit.acquisition.optimal_design import Likelihood, cell_precision, greedy_render, render_metric

from test_planning import small  # noqa: F401  (the module fixture: a 5-component basis of 4 synthetic tables)


def _expected_error(rows, q, metric, chosen):
    k = rows.shape[1]
    prec = np.eye(k) + (rows[chosen] * q[chosen, None]).T @ rows[chosen]
    return float(np.trace(metric @ np.linalg.inv(prec)))


def test_greedy_takes_the_best_next_direction_by_brute_force():
    rng = np.random.default_rng(0)
    rows = rng.normal(size=(60, 5))
    q = rng.uniform(0.5, 20, size=60)
    j = rng.normal(size=(9, 5))
    metric = j.T @ j
    chosen = greedy_render(rows, q, metric, 8)
    assert len(set(chosen.tolist())) == 8
    for step in range(8):
        before = list(chosen[:step])
        errors = [_expected_error(rows, q, metric, before + [i]) if i not in before else np.inf for i in range(60)]
        assert chosen[step] == int(np.argmin(errors)), step
    # and the expected error falls with every direction added
    errs = [_expected_error(rows, q, metric, list(chosen[:s])) for s in range(9)]
    assert all(b < a for a, b in zip(errs, errs[1:]))


def test_greedy_refuses_more_directions_than_candidates():
    with pytest.raises(InputError, match="5 directions asked for, but the basis covers only 4"):
        greedy_render(np.ones((4, 2)), np.ones(4), np.eye(2), 5)


@pytest.mark.slow
def test_metric_is_the_jacobian_of_the_displayed_screen(small):
    """M = J^T J of the screen's displayed image: checked against finite differences of
    the real render of the decoded table, for the mean material (no prior draws)."""
    from brdfkit.basis import load_basis
    from brdfkit.render.display import display_encode
    from brdfkit.render.screen import screen

    basis = load_basis(small["basis"])
    m = render_metric(basis, draws=0, scenes=(0.0,))
    sc = screen()

    def shown(z):
        table = np.nan_to_num(basis.decode(np.repeat((z * basis.sigma)[:, None], 3, 1)))
        img = sc.render_table(table)
        return display_encode(img.numpy() if hasattr(img, "numpy") else np.asarray(img))

    h = 1e-4
    jac = np.stack([(shown(h * e) - shown(-h * e)).reshape(-1) / (2 * h) for e in np.eye(5)], 1)
    fd = jac.T @ jac / (sc.pixels * 3)
    assert np.isfinite(m).all()
    # The metric reads the basis trilinearly at the pairs, the render reads the decoded
    # table: the same to first order, up to the interpolation of exp.
    np.testing.assert_allclose(m, fd, rtol=0.1, atol=0.02 * np.abs(fd).max())


def test_precision_is_the_ridge_alone_for_ipca_and_grows_with_the_metric_term(small):
    from brdfkit.basis import load_basis

    basis = load_basis(small["basis"])
    cells = basis.cells[::5000]
    ridge = cell_precision(basis, cells, Likelihood(None, lam=0.1))
    np.testing.assert_allclose(ridge, 10.0)
    energy = cell_precision(basis, cells, Likelihood("energy", 0.03, 0.1), draws=2)
    assert (energy > ridge).all() and np.isfinite(energy).all()


@pytest.mark.slow
def test_render_plan_is_deterministic_distinct_and_lowers_the_expected_error(small):
    from brdfkit.acquisition.designs import CandidatePool as _Pool

    basis, label, lik = plan_target(small["basis"])
    opts = dict(design="render", draws=2, candidates=20_000)
    a = plan_directions(small["basis"], 12, seed=0, **opts)
    b = plan_directions(small["basis"], 12, seed=0, **opts)
    np.testing.assert_array_equal(a.cells, b.cells)
    assert len(np.unique(a.cells)) == 12 and a.design == "render"
    pool = _Pool.of(basis, lik)
    metric = render_metric(basis, draws=2)
    q = cell_precision(basis, pool.cells, lik, draws=2)
    err = lambda cells: _expected_error(pool.rows.astype(np.float64), q, metric, list(pool.where[cells]))  # noqa
    for other in (plan_directions(small["basis"], 12, seed=0).cells,
                  *(plan_directions(None, 12, design="uniform", seed=s).cells for s in range(3))):
        other = other[pool.where[other] >= 0]
        assert err(a.cells) < err(other)


def test_render_design_options_are_checked(small):
    with pytest.raises(InputError, match="render design: draws must be >= 0 and candidates >= 1"):
        plan_directions(small["basis"], 3, design="render", candidates=0)
    with pytest.raises(InputError, match="design 'render' takes the option"):
        plan_directions(small["basis"], 3, design="render", evaluations=5)


@pytest.mark.slow
def test_plan_render_command(small, tmp_path, capsys):
    from brdfkit.io.directions import read_directions

    from conftest import run_cli

    out = tmp_path / "r.csv"
    code, _, err = run_cli(capsys, ["plan", "-n", "6", "-m", small["basis"], "--design", "render", "--draws", "1",
                                    "--candidates", "5000", "-o", out])
    assert code == 0, err
    d = read_directions(out)
    expected = plan_directions(small["basis"], 6, design="render", draws=1, candidates=5000).directions
    np.testing.assert_array_equal(d.theta_h, expected.theta_h)
