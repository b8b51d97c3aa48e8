"""Sparse BRDF sample sets (:class:`SampleSet`) and their CSV files.

A sample set is N measurements ``(direction pair, RGB BRDF value)``. On disk it is a CSV
file with a header (see ``docs/formats.md``), in one of two column sets:

* ``theta_h,theta_d,phi_d,r,g,b``: Rusinkiewicz angles in radians;
* ``wi_x,wi_y,wi_z,wo_x,wo_y,wo_z,r,g,b``: unit vectors in the local frame (``z`` the
  normal), incident then outgoing.

``r,g,b`` are BRDF values in physical units (1/sr, MERL colour scales applied).
In memory a :class:`SampleSet` always holds the Rusinkiewicz angles. The CSV reading
is :mod:`brdfkit.io.csvfile`'s and the checks of a direction pair
:mod:`brdfkit.io.directions`', shared with the directions files of ``brdfkit plan``.
Drawing a sample set from a table, or measuring one at given directions, is
acquisition's (:mod:`brdfkit.acquisition.sampling`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import os

import numpy as np

from brdfkit.atomic import atomic_open
from brdfkit.io.csvfile import read_csv_table
from brdfkit.io.directions import HORIZON_TOLERANCE, UNIT_TOLERANCE, checked_angles, checked_vectors, \
    fold_phi_d
from brdfkit.geometry import N_CELLS, cos_theta_i, half_diff_from_io, hd_vectors, io_from_half_diff

__all__ = ["SampleSet", "read_samples", "write_samples",
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
    note
        What reading them did that a user should know (a spectral file's conversion to
        RGB), for messages; empty for an RGB sample CSV.
    """

    theta_h: np.ndarray
    theta_d: np.ndarray
    phi_d: np.ndarray
    rgb: np.ndarray
    source: str = ""
    note: str = ""

    def __len__(self) -> int:
        return int(self.rgb.shape[0])

    def hd(self) -> np.ndarray:
        """Network input ``(N, 6)``: half and difference vectors (``phi_h = 0``), with
        ``phi_d`` folded into ``[0, pi)`` by reciprocity as on the MERL grid the model
        learnt from (unfolded, ``phi_d = pi`` encoded unlike the same pair at ``0``)."""
        pd = np.mod(np.asarray(self.phi_d, dtype=np.float64), np.pi)
        pd[pd >= np.pi] = 0.0  # -1e-17 % pi rounds to pi itself
        return hd_vectors(self.theta_h, self.theta_d, pd)

    def subset(self, keep) -> "SampleSet":
        """The samples where the boolean mask ``keep (N,)`` is true (or at the indices
        ``keep``), in order, with the same source and note."""
        return SampleSet(self.theta_h[keep], self.theta_d[keep], self.phi_d[keep], self.rgb[keep], self.source,
                         self.note)

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


def write_samples(path: str | os.PathLike, samples: SampleSet) -> None:
    """Write a sample set as CSV (angle columns, full float64 precision), atomically."""
    data = np.column_stack([samples.theta_h, samples.theta_d, samples.phi_d, samples.rgb])
    with atomic_open(path, "w", newline="", verify=read_samples) as f:
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
