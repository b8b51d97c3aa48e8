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
