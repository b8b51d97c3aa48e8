"""Measurement directions: where an instrument measures, without the values.

A set of direction pairs ``(wi, wo)``, as ``brdfkit plan`` writes them and ``brdfkit
sample --at`` reads them (``docs/formats.md``, "Directions CSV"). On disk a CSV file
whose header names the Rusinkiewicz angles ``theta_h,theta_d,phi_d`` (radians, as in a
sample CSV), the unit vectors ``wi_x,wi_y,wi_z,wo_x,wo_y,wo_z`` of the local frame (``z``
the normal; what a gonioreflectometer's light source and detector are set to), or both;
given both, they must describe the same pairs. In memory a :class:`DirectionSet` holds
the Rusinkiewicz angles, like :class:`brdfkit.io.samples.SampleSet`.

The checks of a direction pair (angle ranges, horizon, unit vectors) are those of the
sample CSV, and :mod:`brdfkit.io.samples` takes them from here.
"""

from __future__ import annotations

import dataclasses
import os

import numpy as np

from brdfkit.atomic import atomic_open
from brdfkit.io.csvfile import CsvTable, read_csv_table
from brdfkit.errors import InputError
from brdfkit.geometry import HALF_PI, N_CELLS, half_diff_from_io, io_from_half_diff

__all__ = ["DirectionSet", "read_directions", "write_directions", "ANGLE_COLUMNS", "VECTOR_COLUMNS",
           "AGREEMENT_TOLERANCE", "MAX_ROWS", "checked_angles", "checked_vectors", "fold_phi_d",
           "pair_disagreement"]

ANGLE_COLUMNS = ("theta_h", "theta_d", "phi_d")
VECTOR_COLUMNS = ("wi_x", "wi_y", "wi_z", "wo_x", "wo_y", "wo_z")
UNIT_TOLERANCE = 1e-3
HORIZON_TOLERANCE = 1e-9
AGREEMENT_TOLERANCE = 1e-3
"""Radians (0.057 degrees) by which a row's angles and vectors may disagree
(:func:`pair_disagreement`): far above the rounding of a 6-digit file, far below the
slips it is there to catch (degrees for radians, ``wi`` and ``wo`` columns mixed up)."""
# Four times the cells of a MERL table, as for sample sets: a clear refusal of a
# runaway file rather than minutes of parsing.
MAX_ROWS = 4 * N_CELLS
_EXPECTED = f"{','.join(ANGLE_COLUMNS)} and/or {','.join(VECTOR_COLUMNS)}"


@dataclasses.dataclass
class DirectionSet:
    """N direction pairs.

    Attributes
    ----------
    theta_h, theta_d, phi_d
        float64 ``(N,)``, Rusinkiewicz angles in radians; ``phi_d`` folded into
        ``[0, pi)`` (reciprocity: ``wi`` and ``wo`` swapped is the same pair).
    source
        Where they came from (a file name), for messages.
    lines
        int64 ``(N,)``, the line of each pair in the file read, for messages; ``None``
        for sets made in memory.
    """

    theta_h: np.ndarray
    theta_d: np.ndarray
    phi_d: np.ndarray
    source: str = ""
    lines: np.ndarray | None = None

    def __len__(self) -> int:
        return int(np.shape(self.theta_h)[0])

    def vectors(self) -> tuple[np.ndarray, np.ndarray]:
        """``(wi, wo)``, float64 ``(N, 3)`` each, unit vectors with ``phi_h = 0`` (any
        rotation about the normal measures the same for an isotropic material)."""
        return io_from_half_diff(self.theta_h, self.theta_d, self.phi_d)

    def where(self, i: int) -> str:
        """Row ``i`` for a message: ``"line L"`` of the file read, else ``"direction i"``
        (0-based)."""
        return f"line {int(self.lines[i])}" if self.lines is not None else f"direction {i}"


def fold_phi_d(phi_d) -> np.ndarray:
    """``phi_d`` (radians, any finite value) folded into ``[0, pi)``, float64."""
    pd = np.asarray(phi_d, np.float64) % np.pi
    pd[pd >= np.pi] = 0.0  # -1e-17 % pi rounds to pi itself; fold it to 0 as well
    return pd


def checked_angles(table: CsvTable, th, td, pd) -> tuple[np.ndarray, np.ndarray]:
    """Refuse rows of ``table`` whose Rusinkiewicz angles (radians, ``(N,)``) are out of
    range or put a direction below the horizon; returns their ``(wi, wo)``."""
    table.refuse((th < 0) | (th > HALF_PI + 1e-9), "theta_h outside [0, pi/2] radians")
    table.refuse((td < 0) | (td > HALF_PI + 1e-9), "theta_d outside [0, pi/2] radians")
    wi, wo = io_from_half_diff(th, td, pd)
    table.refuse((wi[:, 2] < -HORIZON_TOLERANCE) | (wo[:, 2] < -HORIZON_TOLERANCE),
                 "direction below the horizon")
    return wi, wo


def checked_vectors(table: CsvTable, wi, wo) -> tuple[np.ndarray, np.ndarray]:
    """Refuse rows of ``table`` whose direction vectors (``(N, 3)`` each) are not unit
    length within :data:`UNIT_TOLERANCE`, below the horizon or opposite; returns them
    normalised."""
    ni, no = np.linalg.norm(wi, axis=1), np.linalg.norm(wo, axis=1)
    table.refuse((np.abs(ni - 1) > UNIT_TOLERANCE) | (np.abs(no - 1) > UNIT_TOLERANCE),
                 f"direction is not a unit vector (|norm - 1| > {UNIT_TOLERANCE})")
    wi, wo = wi / ni[:, None], wo / no[:, None]
    table.refuse((wi[:, 2] < -HORIZON_TOLERANCE) | (wo[:, 2] < -HORIZON_TOLERANCE),
                 "direction below the horizon (z < 0)")
    table.refuse(np.einsum("ij,ij->i", wi, wo) < -1 + 1e-12, "wi and wo are opposite (no half vector)")
    return wi, wo


def _polar(w):
    """Polar angle (atan2: arccos loses half the digits next to the normal) and azimuth."""
    return np.arctan2(np.hypot(w[:, 0], w[:, 1]), w[:, 2]), np.arctan2(w[:, 1], w[:, 0])


def pair_disagreement(wi_a, wo_a, wi_b, wo_b) -> np.ndarray:
    """By how much two sets of direction pairs differ as measurements of an isotropic
    material, radians ``(N,)``.

    Two pairs measure the same when one is the other rotated about the normal, or with
    ``wi`` and ``wo`` swapped (reciprocity). So the polar angles are compared, and the
    azimuth of ``wo`` relative to ``wi`` weighted by the smaller ``sin(theta)`` (an
    azimuth error moves a direction by that much; next to the normal it means
    nothing): ``max(|dtheta_i|, |dtheta_o|) + min(sin theta_i, sin theta_o) |d(phi_o -
    phi_i)|``, the smaller of the value for ``b`` and for ``b`` swapped.
    """
    ti_a, pi_a = _polar(np.asarray(wi_a, np.float64))
    to_a, po_a = _polar(np.asarray(wo_a, np.float64))
    ti_b, pi_b = _polar(np.asarray(wi_b, np.float64))
    to_b, po_b = _polar(np.asarray(wo_b, np.float64))
    weight = np.minimum(np.sin(ti_a), np.sin(to_a))

    def one(ti, to, dphi):
        turn = np.abs(np.angle(np.exp(1j * ((po_a - pi_a) - dphi))))
        return np.maximum(np.abs(ti_a - ti), np.abs(to_a - to)) + weight * turn

    return np.minimum(one(ti_b, to_b, po_b - pi_b), one(to_b, ti_b, pi_b - po_b))


def read_directions(path: str | os.PathLike) -> DirectionSet:
    """Read and check a directions CSV (``docs/formats.md``, "Directions CSV").

    The header names ``theta_h,theta_d,phi_d`` (radians), ``wi_x,wi_y,wi_z,wo_x,wo_y,wo_z``
    (unit vectors, local frame) or both, in any order; the file rules (comments, blank
    lines, line ends, number syntax) are those of the sample CSV. Given both, the angles
    are used and the vectors must agree with them within :data:`AGREEMENT_TOLERANCE`
    (:func:`pair_disagreement`: up to a rotation about the normal and a swap of ``wi``
    and ``wo``).

    Returns
    -------
    DirectionSet
        With the line of every pair.

    Raises
    ------
    FormatError
        Naming the file, the first offending line and how many rows share the problem:
        the CSV errors of :func:`brdfkit.io.csvfile.read_csv_table`, non-finite values,
        angles out of range, vectors not of unit length, directions below the horizon,
        opposite vectors, angles and vectors that disagree.
    """
    t = read_csv_table(path, {"angles": ANGLE_COLUMNS, "vectors": VECTOR_COLUMNS,
                              "both": ANGLE_COLUMNS + VECTOR_COLUMNS},
                       expected=_EXPECTED, noun="direction", max_rows=MAX_ROWS)
    t.refuse(~np.isfinite(t.data).all(axis=1), "NaN or infinite value")
    if t.kind != "vectors":
        th, td, pd = t.data[:, 0], t.data[:, 1], t.data[:, 2]
        wi_a, wo_a = checked_angles(t, th, td, pd)
    if t.kind != "angles":
        v = t.data[:, -6:]
        wi, wo = checked_vectors(t, v[:, 0:3], v[:, 3:6])
        if t.kind == "vectors":
            th, _, td, pd = half_diff_from_io(wi, wo)
        else:
            off = pair_disagreement(wi_a, wo_a, wi, wo)
            t.refuse(off > AGREEMENT_TOLERANCE, f"the wi/wo vectors and theta_h,theta_d,phi_d describe different "
                                                f"directions (by more than {AGREEMENT_TOLERANCE} rad)")
    return DirectionSet(np.asarray(th, np.float64).copy(), np.asarray(td, np.float64).copy(), fold_phi_d(pd),
                        os.path.basename(t.path), t.lines)


def write_directions(path: str | os.PathLike, directions: DirectionSet, comments=()) -> None:
    """Write a directions CSV atomically: ``#`` comment lines (``comments``, one string
    each, e.g. how the set was made), then both column sets, the angles with 17
    significant digits (a write/read round trip gives the same angles) and the vectors
    (``phi_h = 0``) computed from them.

    Raises
    ------
    InputError
        An empty set, or a comment holding a line break (it would end the comment).
    """
    if len(directions) == 0:
        raise InputError(f"{os.fspath(path)}: no directions to write")
    for c in comments:
        if "\n" in c or "\r" in c:
            raise InputError(f"{os.fspath(path)}: a comment line holds a line break")
    wi, wo = directions.vectors()
    data = np.column_stack([directions.theta_h, directions.theta_d, directions.phi_d, wi, wo])
    with atomic_open(path, "w", newline="", verify=read_directions) as f:
        for c in comments:
            f.write(f"# {c}\n")
        f.write(",".join(ANGLE_COLUMNS + VECTOR_COLUMNS) + "\n")
        np.savetxt(f, data, fmt="%.17g", delimiter=",")
