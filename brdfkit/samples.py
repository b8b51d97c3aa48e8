"""Sparse BRDF sample sets: drawing them from a table, reading and writing CSV.

A sample set is N measurements ``(direction pair, RGB BRDF value)``. On disk it is a CSV
file with a header (see ``docs/formats.md``), in one of two column sets:

* ``theta_h,theta_d,phi_d,r,g,b``: Rusinkiewicz angles in radians;
* ``wi_x,wi_y,wi_z,wo_x,wo_y,wo_z,r,g,b``: unit vectors in the local frame (``z`` the
  normal), incident then outgoing.

``r,g,b`` are BRDF values in physical units (1/sr, MERL colour scales applied).
In memory a :class:`SampleSet` always holds the Rusinkiewicz angles.
"""

from __future__ import annotations

import dataclasses
import os
import re

import numpy as np

from .atomic import atomic_open, check_input_file
from .errors import FormatError, InputError
from .geometry import HALF_PI, N_CELLS, cell_angles, cell_index, cos_theta_i, half_diff_from_io, \
    hd_vectors, io_from_half_diff

__all__ = ["SampleSet", "draw_samples", "read_samples", "write_samples", "ANGLE_COLUMNS",
           "VECTOR_COLUMNS", "MAX_ROWS"]

ANGLE_COLUMNS = ("theta_h", "theta_d", "phi_d", "r", "g", "b")
VECTOR_COLUMNS = ("wi_x", "wi_y", "wi_z", "wo_x", "wo_y", "wo_z", "r", "g", "b")
# Four times the cells of a MERL table: enough for any real acquisition, and a clear
# refusal (not minutes of parsing and gigabytes of memory) for a runaway file.
MAX_ROWS = 4 * N_CELLS
UNIT_TOLERANCE = 1e-3
HORIZON_TOLERANCE = 1e-9


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
        ``"cells"``: uniform over the measured cells.

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
    rng = np.random.default_rng(seed)
    if distribution == "cells":
        idx = rng.choice(np.flatnonzero(measured), size=n)
    elif distribution == "angles":
        chunks, have = [], 0
        while have < n:
            m = max(2 * (n - have), 64)
            th = rng.uniform(0, HALF_PI, m)
            td = rng.uniform(0, HALF_PI, m)
            pd = rng.uniform(0, np.pi, m)
            cand = cell_index(th, td, pd)
            cand = cand[measured[cand]]
            chunks.append(cand)
            have += cand.size
        idx = np.concatenate(chunks)[:n]
    else:
        raise InputError(f"unknown distribution {distribution!r}; use 'angles' or 'cells'")
    th, td, pd = cell_angles(idx)
    return SampleSet(th, td, pd, flat[idx].astype(np.float64), source)


def write_samples(path: str | os.PathLike, samples: SampleSet) -> None:
    """Write a sample set as CSV (angle columns, full float64 precision), atomically."""
    data = np.column_stack([samples.theta_h, samples.theta_d, samples.phi_d, samples.rgb])
    with atomic_open(path, "w", newline="") as f:
        f.write(",".join(ANGLE_COLUMNS) + "\n")
        np.savetxt(f, data, fmt="%.17g", delimiter=",")


# Line breaks as editors count them (str.splitlines also splits on form feeds and
# Unicode separators, which would shift the line numbers in messages).
_LINE_BREAK = re.compile(r"\r\n|\r|\n")


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
    path = check_input_file(path)
    try:
        with open(path, "rb") as f:
            raw = f.read()
    except OSError as e:
        raise FormatError(path, f"cannot read: {e.strerror}") from None
    if b"\x00" in raw[:65536]:
        raise FormatError(path, "not a CSV text file (binary content)")
    # A runaway file is refused before it is decoded and split into per-line strings
    # (10^7 rows: 29 s and 2.1 GB before this check; docs/stability.md).
    if raw.count(b"\n") + raw.count(b"\r") > MAX_ROWS:
        _refuse_too_many(path, _count_value_lines(raw) - 1)
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        raise FormatError(path, f"not UTF-8 text (byte {e.start})") from None
    del raw
    lines = _LINE_BREAK.split(text)
    numbered = [(i + 1, ln) for i, ln in enumerate(lines) if ln.strip() and not ln.lstrip().startswith("#")]
    del lines, text
    if not numbered:
        raise FormatError(path, "empty: no header and no sample rows")
    header_line, header = numbered[0]
    columns = tuple(c.strip().lower() for c in header.split(","))
    if all(_is_number(c) for c in columns):
        raise FormatError(path, f"line {header_line}: no header; the first line must name the columns "
                                f"({','.join(ANGLE_COLUMNS)} or {','.join(VECTOR_COLUMNS)})")
    if set(columns) == set(ANGLE_COLUMNS) and len(columns) == len(ANGLE_COLUMNS):
        kind = "angles"
    elif set(columns) == set(VECTOR_COLUMNS) and len(columns) == len(VECTOR_COLUMNS):
        kind = "vectors"
    else:
        known = set(ANGLE_COLUMNS) | set(VECTOR_COLUMNS)
        unknown = [c for c in columns if c not in known]
        what = f"unknown column(s) {', '.join(repr(c) for c in unknown)}" if unknown else \
            f"columns {','.join(columns)} are not a known set"
        raise FormatError(path, f"line {header_line}: {what}; expected {','.join(ANGLE_COLUMNS)} "
                                f"or {','.join(VECTOR_COLUMNS)}")
    rows = numbered[1:]
    if not rows:
        raise FormatError(path, "no sample rows after the header")
    _refuse_too_many(path, len(rows))
    ncol = len(columns)
    linenos = np.fromiter((ln for ln, _ in rows), dtype=np.int64, count=len(rows))
    try:
        data = np.loadtxt([r for _, r in rows], delimiter=",", dtype=np.float64, ndmin=2,
                          comments=None)
    except ValueError as e:
        raise _row_error(path, rows, ncol, e) from None
    if data.shape[1] != ncol:
        raise FormatError(path, f"line {int(linenos[0])}: {data.shape[1]} fields, the header names {ncol}")
    data = data[:, [columns.index(c) for c in (ANGLE_COLUMNS if kind == "angles" else VECTOR_COLUMNS)]]

    def refuse(mask, problem):
        if mask.any():
            i = int(np.flatnonzero(mask)[0])
            raise FormatError(path, f"line {int(linenos[i])}: {problem} "
                                    f"({int(mask.sum())} such row{'s' if mask.sum() > 1 else ''})")

    refuse(~np.isfinite(data).all(axis=1), "NaN or infinite value")
    rgb = data[:, -3:]
    refuse((rgb < 0).any(axis=1), "negative BRDF value")
    if kind == "angles":
        th, td, pd = data[:, 0], data[:, 1], data[:, 2]
        refuse((th < 0) | (th > HALF_PI + 1e-9), "theta_h outside [0, pi/2] radians")
        refuse((td < 0) | (td > HALF_PI + 1e-9), "theta_d outside [0, pi/2] radians")
        wi, wo = io_from_half_diff(th, td, pd)
        refuse((wi[:, 2] < -HORIZON_TOLERANCE) | (wo[:, 2] < -HORIZON_TOLERANCE),
               "direction below the horizon")
    else:
        wi, wo = data[:, 0:3], data[:, 3:6]
        ni, no = np.linalg.norm(wi, axis=1), np.linalg.norm(wo, axis=1)
        refuse((np.abs(ni - 1) > UNIT_TOLERANCE) | (np.abs(no - 1) > UNIT_TOLERANCE),
               f"direction is not a unit vector (|norm - 1| > {UNIT_TOLERANCE})")
        wi, wo = wi / ni[:, None], wo / no[:, None]
        refuse((wi[:, 2] < -HORIZON_TOLERANCE) | (wo[:, 2] < -HORIZON_TOLERANCE),
               "direction below the horizon (z < 0)")
        refuse(np.einsum("ij,ij->i", wi, wo) < -1 + 1e-12, "wi and wo are opposite (no half vector)")
        th, _, td, pd = half_diff_from_io(wi, wo)
    pd = np.asarray(pd, np.float64) % np.pi
    pd[pd >= np.pi] = 0.0  # -1e-17 % pi rounds to pi itself; fold it to 0 as well
    return SampleSet(np.asarray(th, np.float64), np.asarray(td, np.float64), pd,
                     np.ascontiguousarray(rgb), os.path.basename(path))


def _refuse_too_many(path: str, rows: int) -> None:
    if rows > MAX_ROWS:
        raise FormatError(path, f"{rows} sample rows, more than the limit of {MAX_ROWS} "
                                f"(four times the cells of a MERL table)")


# Bytes that cannot start a value: whitespace, line breaks, '#'.
_NOT_VALUE_START = np.zeros(256, dtype=bool)
_NOT_VALUE_START[[9, 10, 11, 12, 13, 32, ord("#")]] = True


def _count_value_lines(raw: bytes, block: int = 1 << 24) -> int:
    """Lines of ``raw`` whose first byte can start a value: a lower bound of the
    non-blank, non-comment lines (an indented line is not counted), in C-speed blocks
    of bounded memory."""
    a = np.frombuffer(raw, dtype=np.uint8)
    n = int(a.size > 0 and not _NOT_VALUE_START[a[0]])
    for s in range(0, a.size - 1, block):
        chunk = a[s:min(a.size - 1, s + block)]
        after_break = np.flatnonzero((chunk == 10) | (chunk == 13)) + (s + 1)
        n += int(np.count_nonzero(~_NOT_VALUE_START[a[after_break]]))
    return n


def _row_error(path: str, rows, ncol: int, error: ValueError) -> FormatError:
    """The first malformed row, located in Python: ``np.loadtxt`` numbers rows from 0 in
    conversion errors but from 1 in field-count errors, and blames the second row when
    the first one has the wrong number of fields."""
    for line, text in rows:
        fields = text.split(",")
        if len(fields) != ncol:
            return FormatError(path, f"line {line}: {len(fields)} fields, the header names {ncol}")
        for field in fields:
            # float() also takes '1_000' and non-ASCII digits, which loadtxt refuses.
            if "_" in field or not field.isascii() or not _is_number(field):
                return FormatError(path, f"line {line}: {field.strip()!r} is not a number")
    return FormatError(path, str(error).split(" at row")[0].split(";")[0])


def _is_number(s: str) -> bool:
    try:
        float(s)
        return True
    except ValueError:
        return False
