"""The log-relative mapping of BRDF values and its reference table.

Nielsen, Jensen and Ramamoorthi 2015, "On Optimal, Minimal BRDF Sampling for Reflectance
Acquisition", and Gokbudak et al. 2024, "Hypernetworks for Generalizable BRDF
Representation", eq. (1)::

    rho' = ln((rho + eps) / (rho_ref + eps) + 1),      eps = 0.002

with ``rho_ref`` the per-cell median of the training materials. The inverse is
``rho = (exp(rho') - 1) (rho_ref + eps) - eps``, bounded below by a small share
:data:`FLOOR` of ``rho_ref`` (at most :data:`CAP`) (a network's output can say "below ``eps``", where the
mapping resolves nothing: clamped at 0, that decoded exact zeros where the material is not
black; ``docs/notes/compression.md``). Values are compressed from the 1e-3 ... 1e4 range
of measured BRDFs into roughly 0 ... 10 while staying invertible.

Reference tables are stored as safetensors (never pickle): one float32 tensor
``rho_ref`` of shape ``(90, 90, 180, 3)`` and metadata naming the materials.
"""

from __future__ import annotations

import json
import os
import warnings
from typing import Sequence

import numpy as np

from brdfkit.atomic import atomic_path
from brdfkit.errors import FormatError
from brdfkit.geometry import N_CELLS, TABLE_SHAPE, array_module
from brdfkit.io.tensorfile import open_safetensors

__all__ = ["EPS", "FLOOR", "CAP", "RHO_MAX", "to_mapped", "from_mapped", "mapping_record", "median_reference",
           "save_reference", "load_reference", "REFERENCE_FORMAT"]

EPS = 0.002
FLOOR = 0.001
"""The decoded value's lower bound as a share of ``rho_ref`` (as the basis's,
:data:`brdfkit.basis.mapping.FLOOR`), at most :data:`CAP`."""
CAP = 0.005 * EPS
"""The largest lower bound (1/sr): true values above it map and come back exactly."""
_TINY = 1e-6 * EPS  # keeps the bound positive where rho_ref is 0
# The largest BRDF value from_mapped returns (1/sr): 150 times the brightest cell of a GGX
# mirror with alpha = 0.002 on the MERL grid (6.5e7), 3e6 times that of MERL's
# chrome-steel. Without it an extrapolated embedding decodes to float32 infinity
# (docs/stability.md), which no table, renderer or metric can use.
RHO_MAX = 1e10
# Mapped values above this give rho >= RHO_MAX for every reference (rho_ref >= 0);
# clamping them first keeps expm1 from overflowing.
_MAPPED_MAX = float(np.log1p((RHO_MAX + EPS) / EPS))
REFERENCE_FORMAT = "brdfkit-reference"
_SNAP = EPS * 2.0 ** -40


def mapping_record() -> dict:
    """This mapping as network files record it (JSON): ``{"name": "log-relative",
    "formula": ..., "eps": 0.002}``. A model decodes correctly only with the mapping it
    was trained with."""
    return {"name": "log-relative", "formula": "ln((rho + eps) / (rho_ref + eps) + 1)", "eps": EPS}


def to_mapped(rho, rho_ref):
    """Log-relative mapping ``ln((rho + eps) / (rho_ref + eps) + 1)``.

    Parameters
    ----------
    rho
        BRDF values, physical units (1/sr), any shape; NaN propagates. Values below
        ``-eps`` (impossible for a BRDF) are clamped to 0 first so the log stays defined.
    rho_ref
        Reference values broadcastable to ``rho``, non-negative.

    Returns
    -------
    array
        Mapped values, same shape and kind (NumPy or torch) as ``rho``.
    """
    xp = array_module(rho)
    rho = xp.clip(rho, 0.0, None) if xp is not np else np.clip(np.asarray(rho, dtype=np.float64), 0.0, None)
    # log1p, not log(x + 1): x is ~1e-8 for a dark cell over a bright reference, where
    # adding 1 first would drop digits that from_mapped needs to recover rho.
    return xp.log1p((rho + EPS) / (rho_ref + EPS))


def from_mapped(mapped, rho_ref, floor: float = FLOOR):
    """Inverse of :func:`to_mapped`, bounded to ``0 < rho <= RHO_MAX``; NaN propagates.

    ``expm1`` keeps full precision where ``mapped`` is small (dark materials). Below, the
    value is bounded by ``min(floor rho_ref, CAP)`` (``floor=0``: clamped at 0, the
    paper's): unchanged wherever it is above that bound. The upper clamp leaves every
    value that :func:`to_mapped` can give for ``rho <= RHO_MAX`` unchanged, and keeps a
    network's out-of-range prediction finite in float32.
    """
    xp = array_module(mapped)
    if xp is np:
        mapped = np.asarray(mapped, dtype=np.float64)
    rho = xp.expm1(xp.clip(mapped, None, _MAPPED_MAX)) * (rho_ref + EPS) - EPS
    # The mapped value of rho = 0 comes back as a few ulps of EPS either side of 0,
    # depending on the platform's SIMD exp/log; snap that round-off to exactly 0 (a real
    # BRDF value is many orders of magnitude above EPS * 2^-40).
    rho = xp.where(xp.abs(rho) < _SNAP, xp.zeros_like(rho), rho)
    if floor:
        bound = xp.clip(floor * (rho_ref if xp is not np else np.asarray(rho_ref, np.float64)), None, CAP) + _TINY
        rho = xp.maximum(rho, bound if xp is np else xp.as_tensor(bound, dtype=rho.dtype))
    return xp.clip(rho, 0.0, RHO_MAX)


def median_reference(tables) -> np.ndarray:
    """Per-cell median of a set of BRDF tables (NaN cells ignored): the reference table
    ``rho_ref`` of the mapping (Gokbudak et al. 2024, eq. 1).

    ``np.nanmedian`` is slow; cells measured in every table (almost all of them) take a
    sort along the material axis instead, and only the rest go through ``nanmedian``:
    the same numbers, about 5x faster.

    Parameters
    ----------
    tables
        ``(90, 90, 180, 3)`` arrays, or paths of MERL files (read one at a time), or the
        tables already stacked: float32 ``(M, 90 * 90 * 180 * 3)``, NaN where not
        measured (used as it is, not copied).

    Returns
    -------
    numpy.ndarray
        float32 ``(90, 90, 180, 3)``; NaN only where no table has a measurement.

    Raises
    ------
    ValueError
        No table.
    """
    if isinstance(tables, np.ndarray) and tables.ndim == 2:
        stack = tables
    else:
        from brdfkit.io.merl import read_merl

        rows = [(read_merl(t) if isinstance(t, (str, os.PathLike)) else np.asarray(t))
                .astype(np.float32).reshape(N_CELLS * 3) for t in tables]
        stack = np.stack(rows) if rows else np.empty((0, N_CELLS * 3), np.float32)
    if stack.shape[0] == 0:
        raise ValueError("median_reference needs at least one table")
    m = stack.shape[0]
    finite = np.isfinite(stack)
    full = finite.all(axis=0)
    out = np.full(stack.shape[1], np.nan, dtype=np.float32)
    chunk = 1 << 19
    for s in range(0, stack.shape[1], chunk):
        sel = np.flatnonzero(full[s:s + chunk]) + s
        if sel.size:
            srt = np.sort(np.ascontiguousarray(stack[:, sel].T), axis=1)
            # np.median's own rule: the mean of the two middle values for an even count.
            out[sel] = srt[:, m // 2] if m % 2 else (srt[:, m // 2 - 1] + srt[:, m // 2]) / np.float32(2)
    part = np.flatnonzero(~full & finite.any(axis=0))
    if part.size:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            out[part] = np.nanmedian(stack[:, part], axis=0)
    return out.reshape(TABLE_SHAPE)


def save_reference(path: str | os.PathLike, rho_ref: np.ndarray,
                   materials: Sequence[str] = ()) -> None:
    """Save a reference table as safetensors, atomically."""
    from brdfkit.io.tensorfile import write_safetensors

    arr = np.ascontiguousarray(rho_ref, dtype=np.float32)
    if arr.shape != TABLE_SHAPE:
        raise ValueError(f"reference table must have shape {TABLE_SHAPE}, not {arr.shape}")
    meta = {"format": REFERENCE_FORMAT, "version": "1", "materials": json.dumps(list(materials))}
    with atomic_path(path, verify=load_reference) as tmp:
        write_safetensors(tmp, {"rho_ref": arr}, meta)


def load_reference(path: str | os.PathLike) -> np.ndarray:
    """Load a table saved by :func:`save_reference`; float32 ``(90, 90, 180, 3)``."""
    path = os.fspath(path)
    with open_safetensors(path, framework="numpy") as f:
        meta = f.metadata() or {}
        if meta.get("format") != REFERENCE_FORMAT:
            raise FormatError(path, f"not a brdfkit reference table (format {meta.get('format')!r})")
        arr = f.get_tensor("rho_ref")
    if arr.shape != TABLE_SHAPE:
        raise FormatError(path, f"reference table has shape {arr.shape}, expected {TABLE_SHAPE}")
    return arr
