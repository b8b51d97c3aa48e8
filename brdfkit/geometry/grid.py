"""The MERL grid: its cells, their angles and directions, and the nearest-cell lookup.

Conventions (Matusik et al. 2003, the MERL ``BRDFRead.cpp`` reader): the grid is
``(90, 90, 180)`` over ``(theta_h, theta_d, phi_d)``. Cell ``i`` of ``theta_h`` sits at
``(i / 90)**2 * pi / 2`` (the square-root spacing that puts more cells near the specular
peak); ``theta_d`` and ``phi_d`` are uniform, cell ``j`` at ``j / 90 * pi / 2`` and cell
``k`` at ``k / 180 * pi``. The flat index is ``phi_d + 180 * (theta_d + 90 * theta_h)``.
The Rusinkiewicz coordinates themselves are :mod:`brdfkit.geometry.coordinates`'.

Examples
--------
>>> int(cell_index(*cell_angles(12345)))
12345
>>> TABLE_SHAPE, N_CELLS
((90, 90, 180, 3), 1458000)
"""

from __future__ import annotations

import functools
import math

import numpy as np

from brdfkit.geometry.coordinates import array_module, as_array, hd_vectors, io_from_half_diff

__all__ = [
    "N_THETA_H", "N_THETA_D", "N_PHI_D", "GRID_SHAPE", "TABLE_SHAPE", "N_CELLS", "HALF_PI",
    "grid_angles", "cell_angles", "cell_index", "fractional_indices",
    "valid_mask", "valid_cells", "grid_hd", "grid_directions", "grid_cosine_weight",
    "lookup_nearest",
]

N_THETA_H, N_THETA_D, N_PHI_D = 90, 90, 180
GRID_SHAPE = (N_THETA_H, N_THETA_D, N_PHI_D)
# A BRDF table in memory: [theta_h, theta_d, phi_d, rgb] (brdfkit.io.merl.read_merl).
TABLE_SHAPE = GRID_SHAPE + (3,)
N_CELLS = N_THETA_H * N_THETA_D * N_PHI_D
HALF_PI = math.pi / 2


def grid_angles():
    """Angles of the MERL grid cells: ``(theta_h (90,), theta_d (90,), phi_d (180,))``,
    radians, float64."""
    i = np.arange(N_THETA_H, dtype=np.float64)
    theta_h = (i / N_THETA_H) ** 2 * HALF_PI
    theta_d = np.arange(N_THETA_D, dtype=np.float64) / N_THETA_D * HALF_PI
    phi_d = np.arange(N_PHI_D, dtype=np.float64) / N_PHI_D * math.pi
    return theta_h, theta_d, phi_d


def cell_angles(index):
    """Angles ``(theta_h, theta_d, phi_d)`` of flat MERL cell indices (any shape)."""
    index = index if array_module(index) is not np else np.asarray(index)
    xp = array_module(index)
    k = index % N_PHI_D
    j = (index // N_PHI_D) % N_THETA_D
    i = index // (N_PHI_D * N_THETA_D)
    if xp is np:
        i, j, k = (a.astype(np.float64) for a in (i, j, k))
    else:
        i, j, k = (a.to(xp.get_default_dtype()) for a in (i, j, k))
    return (i / N_THETA_H) ** 2 * HALF_PI, j / N_THETA_D * HALF_PI, k / N_PHI_D * math.pi


def fractional_indices(theta_h, theta_d, phi_d):
    """Continuous grid coordinates ``(u_h, u_d, u_p)``: cell ``i`` sits at ``u = i``.

    ``theta_h`` and ``theta_d`` are clamped to ``[0, pi/2]``; ``phi_d`` is folded into
    ``[0, pi)`` (reciprocity), so ``u_p`` lies in ``[0, 180)``.
    """
    theta_h, theta_d, phi_d = as_array(theta_h), as_array(theta_d), as_array(phi_d)
    xp = array_module(theta_h)
    u_h = xp.sqrt(xp.clip(theta_h, 0.0, HALF_PI) / HALF_PI) * N_THETA_H
    u_d = xp.clip(theta_d, 0.0, HALF_PI) / HALF_PI * N_THETA_D
    u_p = (phi_d % math.pi) / math.pi * N_PHI_D
    # phi_d just below a multiple of pi can round up to exactly 180.
    u_p = xp.where(u_p >= N_PHI_D - 1e-9, u_p - N_PHI_D, u_p)
    u_p = xp.clip(u_p, 0.0, None)
    return u_h, u_d, u_p


def cell_index(theta_h, theta_d, phi_d):
    """Flat MERL index of the cell containing each direction, as MERL's own reader
    computes it (floor of the continuous coordinate, clamped; ``phi_d`` folded)."""
    u_h, u_d, u_p = fractional_indices(theta_h, theta_d, phi_d)
    xp = array_module(u_h)
    # The tolerance keeps a cell's own angles, recomputed in floating point (sqrt of a
    # square), in that cell rather than one below.
    tol = 1e-9
    fl = (lambda a, n: np.clip(np.floor(a + tol), 0, n - 1).astype(np.int64)) if xp is np else \
        (lambda a, n: xp.clip(xp.floor(a + tol), 0, n - 1).long())
    return fl(u_p, N_PHI_D) + N_PHI_D * (fl(u_d, N_THETA_D) + N_THETA_D * fl(u_h, N_THETA_H))


@functools.lru_cache(maxsize=1)
def valid_mask() -> np.ndarray:
    """Boolean ``(90, 90, 180)``: cells whose ``wi`` and ``wo`` are both above the horizon
    (the cells a MERL file can hold a measurement for); read-only, computed once per
    process (0.3 s of directions each time otherwise)."""
    th, td, pd = np.meshgrid(*grid_angles(), indexing="ij")
    wi, wo = io_from_half_diff(th, td, pd)
    mask = (wi[..., 2] > 0) & (wo[..., 2] > 0)
    mask.setflags(write=False)
    return mask


@functools.lru_cache(maxsize=1)
def valid_cells() -> np.ndarray:
    """Flat indices of the cells of :func:`valid_mask`, int64, sorted, read-only; computed
    once per process."""
    cells = np.flatnonzero(valid_mask().reshape(-1))
    cells.setflags(write=False)
    return cells


@functools.lru_cache(maxsize=1)
def grid_hd() -> np.ndarray:
    """HD vectors of all MERL grid cells, float32 ``(1458000, 6)`` in flat-index order,
    read-only.

    Computed once per process (float64, then rounded) and shared: decoding every table
    and encoding every dense file reuse it. With ``phi_h = 0`` the half vector depends on
    ``theta_h`` alone and the difference vector on ``(theta_d, phi_d)`` alone, so the
    90 + 16,200 distinct vectors are computed and broadcast: the same numbers bit for bit
    as ``hd_vectors(*cell_angles(index))`` for every cell, in a tenth of the time (0.05 s
    against 0.49 s; it is part of every ``brdfkit decode`` / ``sparse`` process,
    ``docs/notes/performance.md``).
    """
    n_dp = N_THETA_D * N_PHI_D
    th = cell_angles(np.arange(N_THETA_H) * n_dp)[0]
    _, td, pd = cell_angles(np.arange(n_dp))
    hd = np.empty((N_THETA_H, n_dp, 6), dtype=np.float32)
    zeros_h = np.zeros(N_THETA_H)
    hd[:, :, :3] = hd_vectors(th, zeros_h, zeros_h)[:, None, :3]
    hd[:, :, 3:] = hd_vectors(np.zeros(n_dp), td, pd)[None, :, 3:]
    hd = hd.reshape(N_CELLS, 6)
    hd.setflags(write=False)
    return hd


@functools.lru_cache(maxsize=1)
def grid_directions() -> tuple[np.ndarray, np.ndarray]:
    """``(wi, wo)`` of every MERL cell (``phi_h = 0``), float64 ``(90, 90, 180, 3)`` each,
    read-only; computed once per process (a synthetic table spends ~40% of its time on
    them otherwise)."""
    th, td, pd = np.meshgrid(*grid_angles(), indexing="ij")
    wi, wo = io_from_half_diff(th, td, pd)
    wi.setflags(write=False)
    wo.setflags(write=False)
    return wi, wo


@functools.lru_cache(maxsize=1)
def grid_cosine_weight() -> np.ndarray:
    """``max(cos theta_i, 0) * max(cos theta_o, 0)`` at every MERL cell, float64 flat
    ``(N_CELLS,)``, read-only; computed once per process (the cosine weight of Nielsen
    et al. 2015, which every PCA decode needs).

    In closed form, ``cos theta_{i,o} = cos theta_h cos theta_d -+ sin theta_h sin theta_d
    cos phi_d`` (``phi_h = 0``), broadcast over the grid's axes: 0.05 s against the 1.9 s of
    the directions themselves (:func:`grid_directions`), the same cells positive and below
    every threshold the bases use, the values within 1e-15."""
    th, td, pd = grid_angles()
    a = np.cos(th)[:, None, None] * np.cos(td)[None, :, None]
    b = np.sin(th)[:, None, None] * np.sin(td)[None, :, None] * np.cos(pd)[None, None, :]
    w = (np.clip(a - b, 0.0, None) * np.clip(a + b, 0.0, None)).reshape(N_CELLS)
    w.setflags(write=False)
    return w


def lookup_nearest(table, theta_h, theta_d, phi_d):
    """MERL's own lookup: the value of the cell containing each direction.

    ``table`` has shape ``(90, 90, 180, C)``; the result ``(..., C)``.
    """
    idx = cell_index(theta_h, theta_d, phi_d)
    return table.reshape(N_CELLS, -1)[idx]
