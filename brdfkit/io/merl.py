"""Reading and writing MERL ``.binary`` BRDF tables.

The format (Matusik et al. 2003, "A Data-Driven Reflectance Model"; ``BRDFRead.cpp``):
three little-endian int32 dimensions ``(90, 90, 180)`` for ``(theta_h, theta_d, phi_d)``,
then ``3 * 1,458,000`` little-endian float64 values, channel-major (all red, then green,
then blue), each channel indexed ``phi_d + 180 * (theta_d + 90 * theta_h)``. Stored values
times the colour scales ``(1/1500, 1.15/1500, 1.66/1500)`` give the BRDF in physical units
(1/sr). A negative value marks a cell that was not measured. A file is exactly
34,992,012 bytes.

In memory a table is a float64 array of shape ``(90, 90, 180, 3)`` indexed
``[theta_h, theta_d, phi_d, rgb]``, physical units, NaN where not measured.
"""

from __future__ import annotations

import os
import weakref

import numpy as np

from brdfkit.atomic import atomic_path, check_input_file
from brdfkit.errors import FormatError, InputError
from brdfkit.geometry import GRID_SHAPE, N_CELLS, TABLE_SHAPE

__all__ = ["MERL_SCALE", "MERL_FILE_SIZE", "TABLE_SHAPE", "read_merl", "write_merl", "is_merl_file"]

MERL_SCALE = np.array([1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0])
_HEADER_BYTES = 12
MERL_FILE_SIZE = _HEADER_BYTES + 3 * N_CELLS * 8  # 34,992,012

# Multiplying by the colour scale is not injective in float64: for about 14% of stored
# values (stored / scale) * scale != stored. So that write_merl(read_merl(f)) gives the
# identical bytes, read_merl remembers, per returned array, the few stored values that
# plain division would not recover. Weak references drop them with the array.
_exact: dict[int, tuple[weakref.ref, np.ndarray, np.ndarray]] = {}


def _remember_exact(table: np.ndarray, stored: np.ndarray) -> None:
    physical = table.reshape(-1)
    recovered = (physical.reshape(-1, 3) / MERL_SCALE).reshape(-1)
    bad = np.flatnonzero((recovered != stored) & ~np.isnan(physical))
    key = id(table)
    _exact[key] = (weakref.ref(table, lambda _r, k=key: _exact.pop(k, None)), bad, stored[bad])


def _stored_values(table: np.ndarray) -> np.ndarray:
    """Physical ``(90, 90, 180, 3)`` -> stored values (flat, cell-major), exact for
    arrays returned by :func:`read_merl` and not modified since."""
    stored = (table / MERL_SCALE).reshape(-1)
    entry = _exact.get(id(table))
    if entry is not None and entry[0]() is table:
        _, idx, raw = entry
        scale = np.tile(MERL_SCALE, N_CELLS)[idx]
        unchanged = table.reshape(-1)[idx] == raw * scale
        stored[idx[unchanged]] = raw[unchanged]
    return stored


def is_merl_file(path: str | os.PathLike) -> bool:
    """True if ``path`` has the size and header of a MERL table (content not checked)."""
    try:
        if os.path.getsize(path) != MERL_FILE_SIZE:
            return False
        dims = np.fromfile(path, dtype="<i4", count=3)
    except OSError:
        return False
    return tuple(dims) == GRID_SHAPE


def read_merl(path: str | os.PathLike) -> np.ndarray:
    """Read a MERL ``.binary`` file.

    Parameters
    ----------
    path
        The ``.binary`` file (``DEVELOPERS.md``: the format).

    Returns
    -------
    numpy.ndarray
        float64, shape ``(90, 90, 180, 3)`` indexed ``[theta_h, theta_d, phi_d, rgb]``,
        BRDF in physical units (1/sr), NaN where the file stores a negative value.

    Raises
    ------
    FormatError
        The file is not a MERL table: wrong size, wrong dimensions, truncated, or a NaN
        or infinite value in the payload. The message names the file and the problem.

    Examples
    --------
    >>> import numpy as np
    >>> from brdfkit.testing.examples import lambertian_table
    >>> write_merl("white.binary", lambertian_table((1.0, 1.0, 1.0)))
    >>> table = read_merl("white.binary")
    >>> table.shape, float(np.nanmax(table) * np.pi)
    ((90, 90, 180, 3), 1.0)
    >>> bool(np.isnan(table).any())  # below the horizon: not measured
    True
    """
    stored = _read_stored(path)
    table = stored.reshape(N_CELLS, 3) * MERL_SCALE
    table[stored.reshape(N_CELLS, 3) < 0] = np.nan
    table = table.reshape(TABLE_SHAPE)
    _remember_exact(table, np.where(stored < 0, np.nan, stored))
    return table


def _read_stored(path: str | os.PathLike) -> np.ndarray:
    """A MERL file's stored values, checked (:func:`read_merl`'s every refusal), cell-major
    flat: what :func:`write_merl` reads back of what it wrote (the table itself, and the
    exact values it remembers, are not needed there)."""
    path = check_input_file(path)
    size = os.path.getsize(path)
    if size < _HEADER_BYTES:
        raise FormatError(path, f"not a MERL table: {size} bytes, too short for the 12-byte header")
    dims = tuple(int(d) for d in np.fromfile(path, dtype="<i4", count=3))
    if dims != GRID_SHAPE:
        shown = f"are {dims}" if all(0 <= d < 100000 for d in dims) else "are not plausible"
        raise FormatError(path, f"not a MERL table: header dimensions {shown}, expected {GRID_SHAPE}")
    if size != MERL_FILE_SIZE:
        what = "truncated" if size < MERL_FILE_SIZE else "too long"
        raise FormatError(path, f"{what}: {size} bytes, a MERL table has exactly {MERL_FILE_SIZE}")
    stored = np.fromfile(path, dtype="<f8", offset=_HEADER_BYTES)
    if stored.size != 3 * N_CELLS:  # the file changed size while being read
        raise FormatError(path, "truncated while reading")
    finite = np.isfinite(stored)
    if not finite.all():
        bad = int(np.flatnonzero(~finite)[0])
        kind = "NaN" if np.isnan(stored[bad]) else "infinite"
        raise FormatError(path, f"{kind} value in the payload (channel {'RGB'[bad // N_CELLS]}, "
                                f"cell {bad % N_CELLS}); {int((~finite).sum())} non-finite values in all")
    return stored.reshape(3, N_CELLS).T.reshape(-1)  # channel-major -> cell-major


def write_merl(path: str | os.PathLike, table) -> None:
    """Write a table as a MERL ``.binary`` file, atomically.

    The exact inverse of :func:`read_merl`: an array it returned, written unmodified,
    gives the identical bytes. NaN cells are written as ``-1`` (MERL's "not measured").

    Parameters
    ----------
    path
        Output file; written to a temporary file in the same folder, then renamed.
    table
        Array-like of shape ``(90, 90, 180, 3)``, physical units, finite or NaN,
        non-negative.

    Raises
    ------
    InputError
        Wrong shape, infinite or negative values.

    Examples
    --------
    >>> import os
    >>> from brdfkit.testing.examples import lambertian_table
    >>> write_merl("grey.binary", lambertian_table((0.5, 0.5, 0.5)))
    >>> os.path.getsize("grey.binary")  # 12-byte header, 3 x 1,458,000 float64
    34992012
    """
    arr = table if isinstance(table, np.ndarray) and table.dtype == np.float64 else \
        np.asarray(table, dtype=np.float64)
    if arr.shape != TABLE_SHAPE:
        raise InputError(f"{os.fspath(path)}: cannot write a table of shape {arr.shape}, "
                         f"expected {TABLE_SHAPE}")
    if np.isinf(arr).any():
        raise InputError(f"{os.fspath(path)}: table holds infinite values")
    if (arr < 0).any():
        raise InputError(f"{os.fspath(path)}: table holds negative values (use NaN for 'not measured')")
    stored = _stored_values(table if arr is table else arr)
    stored[np.isnan(stored)] = -1.0
    payload = stored.reshape(N_CELLS, 3).T  # cell-major -> channel-major
    with atomic_path(path, verify=_read_stored) as tmp:
        with open(tmp, "wb") as f:
            # f.write, not ndarray.tofile(f): tofile turns a Ctrl-C that lands while it
            # writes into "TypeError: expected str ... not BufferedWriter".
            f.write(np.array(GRID_SHAPE, dtype="<i4").tobytes())
            f.write(memoryview(np.ascontiguousarray(payload, dtype="<f8").reshape(-1)).cast("B"))
