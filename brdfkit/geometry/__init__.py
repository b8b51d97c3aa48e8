"""BRDF geometry: Rusinkiewicz half/difference coordinates, the MERL grid and its lookups.

* :mod:`~brdfkit.geometry.coordinates`: direction pairs <-> ``(theta_h, theta_d, phi_d)``,
  the network's 6-number input (:func:`hd_vectors`); NumPy or torch alike.
* :mod:`~brdfkit.geometry.grid`: the ``(90, 90, 180)`` MERL grid (Matusik et al. 2003):
  cell angles and indices, the measurable cells, per-process caches of the grid's
  directions, and MERL's own nearest-cell lookup.
* :mod:`~brdfkit.geometry.trilinear`: the trilinear lookup of a table between cells
  (NaN-aware), and :class:`~brdfkit.geometry.trilinear.TrilinearTable`, a table
  prepared for the renderers' many lookups.

May import: numpy, and torch inside functions given tensors; nothing else of brdfkit.
The names of ``coordinates`` and ``grid`` are importable from here
(``brdfkit.geometry.hd_vectors``); torch is never imported by this package's import.
"""

from __future__ import annotations

from brdfkit.geometry.coordinates import array_module, as_array, cos_theta_i, half_diff_from_io, hd_vectors, \
    io_from_half_diff
from brdfkit.geometry.grid import GRID_SHAPE, HALF_PI, N_CELLS, N_PHI_D, N_THETA_D, N_THETA_H, TABLE_SHAPE, \
    cell_angles, cell_index, fractional_indices, grid_angles, grid_cosine_weight, grid_directions, grid_hd, \
    lookup_nearest, valid_cells, valid_mask

__all__ = [
    "N_THETA_H", "N_THETA_D", "N_PHI_D", "GRID_SHAPE", "TABLE_SHAPE", "N_CELLS", "HALF_PI",
    "half_diff_from_io", "io_from_half_diff", "hd_vectors", "cos_theta_i", "array_module", "as_array",
    "grid_angles", "cell_angles", "cell_index", "fractional_indices",
    "valid_mask", "valid_cells", "grid_hd", "grid_directions", "grid_cosine_weight",
    "lookup_nearest",
]
