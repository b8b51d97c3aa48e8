"""The log-relative mapping of BRDF values and its reference table.

Nielsen, Jensen and Ramamoorthi 2015, "On Optimal, Minimal BRDF Sampling for Reflectance
Acquisition", and Gokbudak et al. 2024, "Hypernetworks for Generalizable BRDF
Representation", eq. (1)::

    rho' = ln((rho + eps) / (rho_ref + eps) + 1),      eps = 0.002

with ``rho_ref`` the per-cell median of the training materials. The inverse is
``rho = (exp(rho') - 1) (rho_ref + eps) - eps``, clamped at 0 because a BRDF is
non-negative. Values are compressed from the 1e-3 ... 1e4 range of measured BRDFs into
roughly 0 ... 10 while staying exactly invertible.

Reference tables are stored as safetensors (never pickle): one float32 tensor
``rho_ref`` of shape ``(90, 90, 180, 3)`` and metadata naming the materials.
"""

from __future__ import annotations

import json
import os
from typing import Iterable, Sequence

import numpy as np

from .atomic import atomic_path, check_input_file
from .errors import FormatError
from .geometry import N_CELLS, _xp

__all__ = ["EPS", "RHO_MAX", "to_mapped", "from_mapped", "median_reference", "save_reference",
           "load_reference", "REFERENCE_FORMAT"]

EPS = 0.002
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
    xp = _xp(rho)
    rho = xp.clip(rho, 0.0, None) if xp is not np else np.clip(np.asarray(rho, dtype=np.float64), 0.0, None)
    # log1p, not log(x + 1): x is ~1e-8 for a dark cell over a bright reference, where
    # adding 1 first would drop digits that from_mapped needs to recover rho.
    return xp.log1p((rho + EPS) / (rho_ref + EPS))


def from_mapped(mapped, rho_ref):
    """Inverse of :func:`to_mapped`, clamped to ``0 <= rho <= RHO_MAX``; NaN propagates.

    ``expm1`` keeps full precision where ``mapped`` is small (dark materials). The upper
    clamp leaves every value that :func:`to_mapped` can give for ``rho <= RHO_MAX``
    unchanged, and keeps a network's out-of-range prediction finite in float32.
    """
    xp = _xp(mapped)
    if xp is np:
        mapped = np.asarray(mapped, dtype=np.float64)
    rho = xp.expm1(xp.clip(mapped, None, _MAPPED_MAX)) * (rho_ref + EPS) - EPS
    # The mapped value of rho = 0 comes back as a few ulps of EPS either side of 0,
    # depending on the platform's SIMD exp/log; snap that round-off to exactly 0 (a real
    # BRDF value is many orders of magnitude above EPS * 2^-40).
    rho = xp.where(xp.abs(rho) < _SNAP, xp.zeros_like(rho), rho)
    return xp.clip(rho, 0.0, RHO_MAX)


def median_reference(tables: Iterable, chunk: int = 1 << 18) -> np.ndarray:
    """Per-cell median of a set of BRDF tables (NaN cells ignored).

    Parameters
    ----------
    tables
        ``(90, 90, 180, 3)`` arrays, or paths of MERL files (read one at a time).

    Returns
    -------
    numpy.ndarray
        float32 ``(90, 90, 180, 3)``; NaN only where no table has a measurement.
    """
    from .merl import read_merl

    stack = []
    for t in tables:
        arr = read_merl(t) if isinstance(t, (str, os.PathLike)) else np.asarray(t)
        stack.append(arr.astype(np.float32).reshape(N_CELLS * 3))
    if not stack:
        raise ValueError("median_reference needs at least one table")
    data = np.stack(stack)
    out = np.empty(N_CELLS * 3, dtype=np.float32)
    # Chunked so that nanmedian's internal copies stay small.
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN cells below the horizon
        for s in range(0, out.size, chunk):
            out[s:s + chunk] = np.nanmedian(data[:, s:s + chunk], axis=0)
    return out.reshape(90, 90, 180, 3)


def save_reference(path: str | os.PathLike, rho_ref: np.ndarray,
                   materials: Sequence[str] = ()) -> None:
    """Save a reference table as safetensors, atomically."""
    from safetensors.numpy import save_file

    arr = np.ascontiguousarray(rho_ref, dtype=np.float32)
    if arr.shape != (90, 90, 180, 3):
        raise ValueError(f"reference table must have shape (90, 90, 180, 3), not {arr.shape}")
    meta = {"format": REFERENCE_FORMAT, "version": "1", "materials": json.dumps(list(materials))}
    with atomic_path(path) as tmp:
        save_file({"rho_ref": arr}, tmp, metadata=meta)


def load_reference(path: str | os.PathLike) -> np.ndarray:
    """Load a table saved by :func:`save_reference`; float32 ``(90, 90, 180, 3)``."""
    from safetensors import SafetensorError, safe_open

    path = check_input_file(path)
    try:
        with safe_open(path, framework="numpy") as f:
            meta = f.metadata() or {}
            if meta.get("format") != REFERENCE_FORMAT:
                raise FormatError(path, f"not a brdfkit reference table (format {meta.get('format')!r})")
            arr = f.get_tensor("rho_ref")
    except SafetensorError as e:
        raise FormatError(path, f"not a valid safetensors file ({e})") from None
    if arr.shape != (90, 90, 180, 3):
        raise FormatError(path, f"reference table has shape {arr.shape}, expected (90, 90, 180, 3)")
    return arr
