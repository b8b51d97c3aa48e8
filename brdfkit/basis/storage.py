"""Compact storage of a PCA basis on the MERL grid: every other ``phi_d`` cell.

A basis of ``K`` components over the 1.1 million measured MERL cells is ``(K + 2) * 4.4``
MB in float32 (44 MB for ``K = 8``), too much to ship several models inside the package.
The log-mapped BRDFs it spans vary slowly along ``phi_d`` (the specular peak sits at
``theta_h = 0``, where ``phi_d`` does not matter, and the Fresnel and shadowing terms
depend on ``theta_d``), so the basis is stored at the even ``phi_d`` indices only and
the odd ones are restored as the mean of their two neighbours (or the one neighbour
stored, next to cells the basis does not cover). ``phi_d`` is periodic
with period pi on the MERL grid (the table stores ``[0, pi)`` and folds ``phi_d + pi``
onto ``phi_d``), so index 179 takes the mean of 178 and 0. The error this costs is
measured in ``docs/models.md`` (``benchmarks/basis_storage.py``).
"""

from __future__ import annotations

import os

import numpy as np

from brdfkit.errors import InputError
from brdfkit.geometry import N_PHI_D, N_THETA_D, N_THETA_H, grid_cosine_weight

__all__ = ["compact", "expand", "check_half", "quantize", "dequantize", "INT8_BLOCK"]

_HALF_MAX = 65504.0
INT8_BLOCK = 256
"""Cells per scale of the int8 storage of a basis's components (:func:`quantize`)."""


def compact(cells: np.ndarray, arrays: list, stride: int) -> tuple[np.ndarray, list]:
    """The cells (sorted flat MERL indices) and per-cell arrays (last axis over the
    cells) kept for storage: all of them for ``stride = 1``, the even ``phi_d`` indices
    for ``stride = 2``."""
    if stride not in (1, 2):
        raise ValueError(f"phi_d stride must be 1 or 2, got {stride!r}")
    if stride == 1:
        return cells, list(arrays)
    keep = (np.asarray(cells) % N_PHI_D) % 2 == 0
    return cells[keep], [np.asarray(a)[..., keep] for a in arrays]


def expand(cells: np.ndarray, arrays: list) -> tuple[np.ndarray, list]:
    """Inverse of :func:`compact` with ``stride = 2``: the even ``phi_d`` cells as
    stored, each odd one the mean of its two even neighbours (wrapping at pi), or the
    one of them that is stored (cells where the cosine weight ``cos_i cos_o`` is 0 are
    left out, as :func:`~.fit.fit_basis` leaves them out); float32 arrays
    over the returned sorted cells."""
    cells = np.asarray(cells, np.int64)
    if ((cells % N_PHI_D) % 2).any():
        raise ValueError("a half-phi_d basis holds only cells of even phi_d index")
    rows = N_THETA_H * N_THETA_D
    half = N_PHI_D // 2
    slot = (cells // N_PHI_D) * half + (cells % N_PHI_D) // 2  # index on the coarse grid
    present = np.zeros(rows * half, dtype=bool)
    present[slot] = True
    present = present.reshape(rows, half)
    after = np.roll(present, -1, axis=1)  # odd cell 2j + 1 lies between 2j and 2j + 2
    full = np.zeros((rows, N_PHI_D), dtype=bool)
    full[:, 0::2] = present
    full[:, 1::2] = present | after
    full &= (grid_cosine_weight() > 0).reshape(rows, N_PHI_D)
    n_odd = (present.astype(np.float32) + after).reshape(-1)
    out_cells = np.flatnonzero(full.reshape(-1)).astype(np.int64)
    out = []
    for a in arrays:
        a = np.asarray(a, np.float32)
        lead = a.shape[:-1]
        coarse = np.zeros(lead + (rows * half,), np.float32)
        coarse[..., slot] = a
        coarse = coarse.reshape(lead + (rows, half))
        dense = np.empty(lead + (rows, N_PHI_D), np.float32)
        dense[..., 0::2] = coarse
        # Absent cells hold 0, so the sum over the stored neighbours divided by their count.
        odd = (coarse + np.roll(coarse, -1, axis=-1)).reshape(lead + (-1,)) / np.maximum(n_odd, 1)
        dense[..., 1::2] = odd.reshape(lead + (rows, half))
        out.append(np.ascontiguousarray(dense.reshape(lead + (rows * N_PHI_D,))[..., out_cells]))
    return out_cells, out


def check_half(path: str | os.PathLike, arrays: list) -> None:
    """Refuse float16 storage of values it cannot hold (one line naming ``path``)."""
    for a in arrays:
        if np.abs(np.asarray(a)).max(initial=0.0) > _HALF_MAX:
            raise InputError(f"{os.fspath(path)}: a basis value exceeds float16's range (65504); "
                             f"store it in float32")


def quantize(components: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """int8 storage of ``(K, P)`` components: blocks of :data:`INT8_BLOCK` consecutive
    cells of one component share a float32 scale (their largest magnitude over 127), so
    each value is kept to 0.4% of the largest in its block. A component is large only
    near the specular peak and small elsewhere; one scale per component would round the
    small values away, one per block keeps them. Returns ``(int8 (K, P), float32 (K, B))``."""
    c = np.asarray(components, np.float32)
    k, p = c.shape
    nb = -(-p // INT8_BLOCK)
    padded = np.zeros((k, nb * INT8_BLOCK), np.float32)
    padded[:, :p] = c
    blocks = padded.reshape(k, nb, INT8_BLOCK)
    scale = np.abs(blocks).max(axis=2) / 127.0
    q = np.rint(blocks / np.where(scale > 0, scale, 1.0)[..., None]).astype(np.int8)
    return np.ascontiguousarray(q.reshape(k, -1)[:, :p]), scale.astype(np.float32)


def dequantize(q: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """Inverse of :func:`quantize`: float32 ``(K, P)``."""
    k, p = q.shape
    idx = np.arange(p) // INT8_BLOCK
    return q.astype(np.float32) * np.asarray(scale, np.float32)[:, idx]
