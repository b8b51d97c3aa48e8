"""Sparse BRDF sample sets: drawing them from a table or measuring it at given
directions, reading and writing CSV.

A sample set is N measurements ``(direction pair, RGB BRDF value)``. On disk it is a CSV
file with a header (see ``docs/formats.md``), in one of two column sets:

* ``theta_h,theta_d,phi_d,r,g,b``: Rusinkiewicz angles in radians;
* ``wi_x,wi_y,wi_z,wo_x,wo_y,wo_z,r,g,b``: unit vectors in the local frame (``z`` the
  normal), incident then outgoing.

``r,g,b`` are BRDF values in physical units (1/sr, MERL colour scales applied).
In memory a :class:`SampleSet` always holds the Rusinkiewicz angles. The CSV reading
is :mod:`brdfkit.csvfile`'s and the checks of a direction pair
:mod:`brdfkit.directions`', shared with the directions files of ``brdfkit plan``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import os

import numpy as np

from .atomic import atomic_open
from .csvfile import read_csv_table
from .directions import HORIZON_TOLERANCE, UNIT_TOLERANCE, DirectionSet, checked_angles, checked_vectors, \
    fold_phi_d
from .errors import InputError
from .geometry import GRID_SHAPE, HALF_PI, N_CELLS, cell_angles, cell_index, cos_theta_i, half_diff_from_io, \
    hd_vectors, io_from_half_diff
from .trilinear import lookup_trilinear

__all__ = ["SampleSet", "draw_samples", "draw_cells", "measure_samples", "read_samples", "write_samples",
           "ANGLE_COLUMNS", "VECTOR_COLUMNS", "MAX_ROWS", "UNIT_TOLERANCE", "HORIZON_TOLERANCE"]

ANGLE_COLUMNS = ("theta_h", "theta_d", "phi_d", "r", "g", "b")
VECTOR_COLUMNS = ("wi_x", "wi_y", "wi_z", "wo_x", "wo_y", "wo_z", "r", "g", "b")
_EXPECTED = f"{','.join(ANGLE_COLUMNS)} or {','.join(VECTOR_COLUMNS)}"
# Four times the cells of a MERL table: enough for any real acquisition, and a clear
# refusal (not minutes of parsing and gigabytes of memory) for a runaway file.
MAX_ROWS = 4 * N_CELLS


@dataclasses.dataclass
class SampleSet:
    """N BRDF measurements.

    Attributes
    ----------
    theta_h, theta_d, phi_d
        float64 ``(N,)``, radians.
    rgb
        float64 ``(N, 3)``, BRDF in physical units (1/sr), non-negative.
    source
        Where the samples came from (a file name), for provenance in outputs.
    """

    theta_h: np.ndarray
    theta_d: np.ndarray
    phi_d: np.ndarray
    rgb: np.ndarray
    source: str = ""

    def __len__(self) -> int:
        return int(self.rgb.shape[0])

    def hd(self) -> np.ndarray:
        """Network input ``(N, 6)``: half and difference vectors (``phi_h = 0``), with
        ``phi_d`` folded into ``[0, pi)`` by reciprocity as on the MERL grid the model
        learnt from (unfolded, ``phi_d = pi`` encoded unlike the same pair at ``0``)."""
        pd = np.mod(np.asarray(self.phi_d, dtype=np.float64), np.pi)
        pd[pd >= np.pi] = 0.0  # -1e-17 % pi rounds to pi itself
        return hd_vectors(self.theta_h, self.theta_d, pd)

    def measured(self) -> np.ndarray:
        """``(N,)`` bool: the samples with a value. A NaN value is an unmeasured sample
        (MERL's convention), not a black one, and the fits leave it out."""
        return ~np.isnan(np.asarray(self.rgb, np.float64)).any(axis=1)

    def cos_i(self) -> np.ndarray:
        """``cos(theta_i)`` ``(N,)``, clamped to ``>= 0``."""
        return np.clip(cos_theta_i(self.theta_h, self.theta_d, self.phi_d), 0.0, None)

    def directions(self):
        """``(wi, wo)``, each ``(N, 3)``, with ``phi_h = 0``."""
        return io_from_half_diff(self.theta_h, self.theta_d, self.phi_d)

    def digest(self) -> str:
        """sha256 hex of the angles and values (float64, little-endian, in that order):
        two sets with the same digest hold the same measurements bit for bit (the
        benchmarks record it to show which samples a figure came from)."""
        h = hashlib.sha256()
        for a in (self.theta_h, self.theta_d, self.phi_d, self.rgb):
            h.update(np.ascontiguousarray(a, dtype="<f8").tobytes())
        return h.hexdigest()


def draw_samples(table: np.ndarray, n: int, seed: int | None = 0,
                 distribution: str = "angles", source: str = "") -> SampleSet:
    """Draw ``n`` measurements of a dense table, only from measured cells.

    Parameters
    ----------
    table
        ``(90, 90, 180, 3)`` in physical units, NaN where not measured.
    n
        Number of samples (cells may repeat, as they would in a real acquisition that
        revisits a direction).
    seed
        Seed of the NumPy generator; the same seed gives the same samples.
    distribution
        ``"angles"``: uniform over the Rusinkiewicz angles ``(theta_h, theta_d, phi_d)``
        in ``[0, pi/2]^2 x [0, pi)``, each draw taking the value of its cell;
        ``"cells"``: uniform over the measured cells (:func:`draw_cells`).

    Returns
    -------
    SampleSet
        Angles of the chosen cells (the grid's own angles) and their values.
    """
    if n < 1:
        raise InputError(f"number of samples must be at least 1, got {n}")
    flat = np.asarray(table).reshape(N_CELLS, 3)
    measured = np.isfinite(flat).all(axis=1)
    if not measured.any():
        raise InputError(f"{source or 'table'}: no measured cells to sample from")
    idx = draw_cells(measured, n, seed, distribution)
    th, td, pd = cell_angles(idx)
    return SampleSet(th, td, pd, flat[idx].astype(np.float64), source)


def draw_cells(allowed: np.ndarray, n: int, seed: int | None = 0, distribution: str = "angles") -> np.ndarray:
    """Flat indices of ``n`` cells drawn among the ``allowed`` ones (bool ``(N_CELLS,)``,
    at least one set), as :func:`draw_samples` draws them (the same seed, the same cells).

    ``"angles"`` draws uniformly over ``(theta_h, theta_d, phi_d)`` in ``[0, pi/2]^2 x
    [0, pi)`` and keeps the draws that land in an allowed cell (so a cell's chance is
    its angular volume: the square-root spacing of ``theta_h`` makes the cells next to
    the specular peak small); ``"cells"`` draws uniformly over the allowed cells. Cells
    may repeat. int64 ``(n,)``.
    """
    rng = np.random.default_rng(seed)
    if distribution == "cells":
        return rng.choice(np.flatnonzero(allowed), size=n)
    if distribution != "angles":
        raise InputError(f"unknown distribution {distribution!r}; use 'angles' or 'cells'")
    chunks, have = [], 0
    while have < n:
        m = max(2 * (n - have), 64)
        th = rng.uniform(0, HALF_PI, m)
        td = rng.uniform(0, HALF_PI, m)
        pd = rng.uniform(0, np.pi, m)
        cand = cell_index(th, td, pd)
        cand = cand[allowed[cand]]
        chunks.append(cand)
        have += cand.size
    return np.concatenate(chunks)[:n]


def measure_samples(table: np.ndarray, directions: DirectionSet, source: str = "") -> SampleSet:
    """A dense table measured at given directions: what an instrument set to them would
    read, were the table the material.

    The value at a direction is the table's trilinear interpolation there
    (:func:`brdfkit.trilinear.lookup_trilinear`, the lookup the renderers and the PCA
    fits use, in the grid's own coordinates, unmeasured corners left out). A real
    measurement reads the material's BRDF at the direction itself, which the table
    knows only at its cells: between them, the interpolation is the table's best
    statement of it, continuous in the direction (the nearest cell would jump from one
    value to the next, and MERL's own lookup takes the cell *below*, not the nearest).
    At a cell's own angles, as :func:`brdfkit.planning.plan_directions` and
    ``brdfkit sample -n`` give them, the weight of every other corner is zero (or a
    rounding error of ``1e-15``) and the value is the cell's.

    Parameters
    ----------
    table
        ``(90, 90, 180, 3)`` in physical units (1/sr), NaN where not measured.
    directions
        :class:`brdfkit.directions.DirectionSet`.
    source
        The material's name, for the sample set and messages.

    Returns
    -------
    SampleSet
        The directions' own angles and the values, float64, 1/sr.

    Raises
    ------
    InputError
        A direction with no measured cell among the eight around it (named by its line).
    """
    table = np.asarray(table, np.float64)
    if table.shape != GRID_SHAPE + (3,):
        raise InputError(f"{source or 'table'}: expected a (90, 90, 180, 3) table, got shape {table.shape}")
    if len(directions) == 0:
        raise InputError(f"{directions.source or 'directions'}: no directions to measure at")
    rgb = lookup_trilinear(table, directions.theta_h, directions.theta_d, directions.phi_d)
    bad = ~np.isfinite(rgb).all(axis=1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise InputError(f"{directions.source or 'directions'}: {directions.where(i)}: {source or 'the table'} "
                         f"has no measured cell around this direction ({int(bad.sum())} such direction"
                         f"{'s' if bad.sum() > 1 else ''})")
    return SampleSet(np.array(directions.theta_h, np.float64), np.array(directions.theta_d, np.float64),
                     np.array(directions.phi_d, np.float64), np.clip(rgb, 0.0, None), source)


def write_samples(path: str | os.PathLike, samples: SampleSet) -> None:
    """Write a sample set as CSV (angle columns, full float64 precision), atomically."""
    data = np.column_stack([samples.theta_h, samples.theta_d, samples.phi_d, samples.rgb])
    with atomic_open(path, "w", newline="") as f:
        f.write(",".join(ANGLE_COLUMNS) + "\n")
        np.savetxt(f, data, fmt="%.17g", delimiter=",")


def read_samples(path: str | os.PathLike) -> SampleSet:
    """Read and validate a CSV sample set.

    Blank lines and lines starting with ``#`` are ignored. Every malformed row is refused
    with its line number: wrong number of fields, text in a number field, NaN or
    infinite values, negative BRDF values, angles out of range, non-unit direction
    vectors, and directions below the horizon.

    Returns
    -------
    SampleSet

    Raises
    ------
    FormatError
        Naming the file, the line and the problem.
    """
    t = read_csv_table(path, {"angles": ANGLE_COLUMNS, "vectors": VECTOR_COLUMNS}, expected=_EXPECTED,
                       noun="sample", max_rows=MAX_ROWS)
    t.refuse(~np.isfinite(t.data).all(axis=1), "NaN or infinite value")
    rgb = t.data[:, -3:]
    t.refuse((rgb < 0).any(axis=1), "negative BRDF value")
    if t.kind == "angles":
        th, td, pd = t.data[:, 0], t.data[:, 1], t.data[:, 2]
        checked_angles(t, th, td, pd)
    else:
        wi, wo = checked_vectors(t, t.data[:, 0:3], t.data[:, 3:6])
        th, _, td, pd = half_diff_from_io(wi, wo)
    return SampleSet(np.asarray(th, np.float64), np.asarray(td, np.float64), fold_phi_d(pd),
                     np.ascontiguousarray(rgb), os.path.basename(t.path))
