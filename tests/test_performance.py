"""The performance shortcuts (docs/performance.md) compute the same numbers as the plain
definitions they replace."""

from __future__ import annotations

import numpy as np

from brdfkit.geometry import N_CELLS, cell_angles, hd_vectors
from brdfkit.neural import grid_hd


def test_grid_hd_is_the_per_cell_definition_bit_for_bit():
    """grid_hd broadcasts 90 half vectors and 16,200 difference vectors; every one of the
    1,458,000 rows must equal hd_vectors at that cell's own angles, rounded to float32."""
    hd = grid_hd()
    th, td, pd = cell_angles(np.arange(N_CELLS))
    assert hd.shape == (N_CELLS, 6) and hd.dtype == np.float32 and not hd.flags.writeable
    np.testing.assert_array_equal(hd, hd_vectors(th, td, pd).astype(np.float32))


def test_threads_follow_the_idle_cores():
    from brdfkit.threads import threads_for_load

    assert threads_for_load(2, 0.0) == 2
    assert threads_for_load(2, 0.9) == 1
    assert threads_for_load(2, 11.0) == 1
    assert threads_for_load(16, 3.2) == 13


def test_thread_choice_leaves_a_user_setting_alone(monkeypatch):
    from brdfkit import threads

    env = {"OMP_NUM_THREADS": "7"}
    assert threads.set_default_threads(env) is None and env == {"OMP_NUM_THREADS": "7"}
    monkeypatch.setattr(threads.os, "getloadavg", lambda: (50.0, 50.0, 50.0))
    env = {}
    assert threads.set_default_threads(env) == 1 and env == {"OMP_NUM_THREADS": "1"}
    monkeypatch.setattr(threads.os, "getloadavg", lambda: (0.0, 0.0, 0.0))
    env = {}
    assert threads.set_default_threads(env) >= 1 and "OMP_NUM_THREADS" not in env
