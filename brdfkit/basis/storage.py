"""Compact storage of a PCA basis on the MERL grid: every other ``phi_d`` cell, and
int8 components.

A basis of ``K`` components over the 1.1 million measured MERL cells is ``(K + 2) * 4.4``
MB in float32 (44 MB for ``K = 8``), too much to ship several models inside the package.
The log-mapped BRDFs it spans vary slowly along ``phi_d`` (the specular peak sits at
``theta_h = 0``, where ``phi_d`` does not matter, and the Fresnel and shadowing terms
depend on ``theta_d``), so the basis is stored at the even ``phi_d`` indices and the odd
ones are restored as the mean of their two neighbours (or the one neighbour stored, next
to cells the basis does not cover). ``phi_d`` is periodic with period pi on the MERL grid
(the table stores ``[0, pi)`` and folds ``phi_d + pi`` onto ``phi_d``), so index 179 takes
the mean of 178 and 0.

Odd cells near the horizon, where the cosine weight ``cos_i cos_o`` is below
:data:`GRAZING_FULL`, are stored too: there the decode divides the mapped value by that
weight, so the interpolation's small error in the mapped basis becomes a large one in the
BRDF. Without them a basis in Nielsen's mapping (no grazing floor) rendered about 10 dB
lower in the judged ``backlight`` scene than at full resolution, 0.55 dB lower in the suite
mean on the 20 unseen MERL materials at 13 components; with them (3.6 % more cells) as at
full resolution (``benchmarks/studies/study_basis_storage.py``,
``docs/notes/compression.md``). Files written before keep only the even cells and load as
they were.
"""

from __future__ import annotations

import os

import numpy as np

from brdfkit.errors import InputError
from brdfkit.geometry import N_PHI_D, N_THETA_D, N_THETA_H, grid_cosine_weight

__all__ = ["compact", "expand", "expansion", "Compact", "check_half", "quantize", "dequantize", "pack_rows",
           "unpack_rows", "INT8_BLOCK", "GRAZING_FULL"]

_HALF_MAX = 65504.0
INT8_BLOCK = 256
"""Cells per scale of the int8 storage of a basis's components (:func:`quantize`)."""

GRAZING_FULL = 0.02
"""Cosine weight ``cos_i cos_o`` below which :func:`compact` keeps the odd ``phi_d`` cells
too (3.6 % of the grid's measured cells)."""


def compact(cells: np.ndarray, arrays: list, stride: int) -> tuple[np.ndarray, list]:
    """The cells (sorted flat MERL indices) and per-cell arrays (last axis over the
    cells) kept for storage: all of them for ``stride = 1``; for ``stride = 2`` the even
    ``phi_d`` indices and the odd ones whose cosine weight is below :data:`GRAZING_FULL`."""
    if stride not in (1, 2):
        raise ValueError(f"phi_d stride must be 1 or 2, got {stride!r}")
    if stride == 1:
        return cells, list(arrays)
    cells = np.asarray(cells)
    keep = ((cells % N_PHI_D) % 2 == 0) | (grid_cosine_weight()[cells] < GRAZING_FULL)
    return cells[keep], [np.asarray(a)[..., keep] for a in arrays]


def expansion(cells: np.ndarray) -> tuple:
    """How :func:`expand` restores the cells of a half-``phi_d`` storage: ``(out_cells,
    ia, ib, wa, wb)``, each restored cell ``wa * stored[ia] + wb * stored[ib]`` (a stored
    cell itself, or the mean of its two stored even neighbours, or the one of them that is
    stored: the weights 1 and 0, or 0.5 and 0.5, so the values are exactly those of the
    mean)."""
    cells = np.asarray(cells, np.int64)
    odd = (cells % N_PHI_D) % 2 == 1
    rows = N_THETA_H * N_THETA_D
    half = N_PHI_D // 2
    even_pos = np.flatnonzero(~odd)
    slot = (cells[~odd] // N_PHI_D) * half + (cells[~odd] % N_PHI_D) // 2  # index on the coarse grid
    where = np.full(rows * half, -1, np.int64)  # coarse slot -> position among the stored cells
    where[slot] = even_pos
    present = (where >= 0).reshape(rows, half)
    after = np.roll(present, -1, axis=1)  # odd cell 2j + 1 lies between 2j and 2j + 2
    full = np.zeros((rows, N_PHI_D), dtype=bool)
    full[:, 0::2] = present
    full[:, 1::2] = present | after
    full = full.reshape(-1)
    full[cells[odd]] = True
    full &= grid_cosine_weight() > 0
    out_cells = np.flatnonzero(full).astype(np.int64)
    r, p = out_cells // N_PHI_D, out_cells % N_PHI_D
    left = where[r * half + p // 2]  # the even cell at or before (its own slot for even cells)
    right = where[r * half + ((p // 2 + 1) % half)]
    is_odd = p % 2 == 1
    ia = np.where(left >= 0, left, right)
    ib = np.where(is_odd & (left >= 0) & (right >= 0), right, ia)
    both = is_odd & (left >= 0) & (right >= 0)
    wa = np.where(both, 0.5, 1.0).astype(np.float32)
    wb = np.where(both, 0.5, 0.0).astype(np.float32)
    # The grazing odd cells, as stored (a position table on the grid, not a search).
    odd_pos = np.flatnonzero(odd)
    at = np.full(N_THETA_H * N_THETA_D * N_PHI_D, -1, np.int64)
    at[cells[odd_pos]] = odd_pos
    stored = at[out_cells]
    own = stored >= 0
    ia[own], ib[own], wa[own], wb[own] = stored[own], stored[own], 1.0, 0.0
    return out_cells, ia, ib, wa, wb


def expand(cells: np.ndarray, arrays: list, how: tuple | None = None) -> tuple[np.ndarray, list]:
    """Inverse of :func:`compact` with ``stride = 2``: the stored cells as stored, each
    other odd cell the mean of its two even neighbours (wrapping at pi), or the one of them
    that is stored (cells where the cosine weight ``cos_i cos_o`` is 0 are left out, as
    :func:`~brdfkit.basis.fit.fit_basis` leaves them out); float32 arrays over the returned
    sorted cells. ``how``: :func:`expansion` of ``cells``, when made already."""
    out_cells, ia, ib, wa, wb = expansion(cells) if how is None else how
    out = []
    for a in arrays:
        a = np.asarray(a, np.float32)
        out.append(np.ascontiguousarray(a[..., ia] * wa + a[..., ib] * wb))
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
    scale = np.asarray(scale, np.float32)
    out = q.astype(np.float32)
    full = (p // INT8_BLOCK) * INT8_BLOCK  # whole blocks scaled in place, the tail apart
    out[:, :full].reshape(k, -1, INT8_BLOCK)[...] *= scale[:, :full // INT8_BLOCK, None]
    if full < p:
        out[:, full:] *= scale[:, full // INT8_BLOCK, None]
    return out


def pack_rows(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Lossless storage of int8 components ``(K, P)`` (:func:`quantize`), a row at a
    time: each row's differences between consecutive cells (modulo 256: the cells of one
    ``phi_d`` row are neighbours, and a component varies slowly along ``phi_d``) deflated
    by zlib, so that a basis of 30 int8 components takes about 6.5 MB instead of 18 and
    the ``k`` leading rows are restored alone (:func:`unpack_rows`). Returns ``(blob,
    offsets)``: uint8 ``(B,)``, the rows' deflated bytes one after the other, and int64
    ``(K + 1,)``, where each starts.

    Examples
    --------
    >>> q = np.array([[1, 2, 3, -128], [0, 127, -1, 5]], np.int8)
    >>> blob, offsets = pack_rows(q)
    >>> bool((unpack_rows(blob, offsets, 2, 4) == q).all()), unpack_rows(blob, offsets, 1, 4).shape
    (True, (1, 4))
    """
    import zlib

    q = np.ascontiguousarray(q, np.int8)
    parts = [zlib.compress(np.diff(row.view(np.uint8), prepend=np.uint8(0)).tobytes(), 9) for row in q]
    offsets = np.cumsum([0] + [len(b) for b in parts]).astype(np.int64)
    return np.frombuffer(b"".join(parts), np.uint8).copy(), offsets


def unpack_rows(blob: np.ndarray, offsets: np.ndarray, k: int, p: int) -> np.ndarray:
    """The ``k`` leading int8 rows ``(k, p)`` of :func:`pack_rows`'s storage;
    ``ValueError`` when the bytes do not give them."""
    import zlib

    out = np.empty((k, p), np.int8)
    raw = np.asarray(blob, np.uint8).tobytes()
    for i in range(k):
        try:
            d = np.frombuffer(zlib.decompress(raw[int(offsets[i]):int(offsets[i + 1])]), np.uint8)
        except zlib.error as e:
            raise ValueError(f"component {i}: {e}") from None
        if d.size != p:
            raise ValueError(f"component {i} holds {d.size} cells, not {p}")
        np.cumsum(d, dtype=np.uint8, out=out[i].view(np.uint8))
    return out


class Compact:
    """A basis as stored at half the ``phi_d`` cells, used without restoring it whole:
    its components at some cells, its decode and its least-squares projection, each
    through the expansion (:func:`expansion`: a restored cell is ``wa stored[ia] + wb
    stored[ib]``), which is linear, so that ``expand(mean + S^T c) = expand(mean) +
    expand(S)^T c`` and ``A A^T = S diag(d) S^T + the neighbours' cross terms`` for the
    restored components ``A = S E``.

    Parameters
    ----------
    rows
        ``rows(k) -> float32 (k, Ps)``: the ``k`` leading stored components.
    mean
        float32 ``(Ps,)`` the mean at the stored cells.
    how
        :func:`expansion` of the stored cells.
    """

    def __init__(self, rows, mean, how):
        import threading

        self.stored_rows, self.mean, self.how = rows, np.asarray(mean, np.float32), how
        self._kept: np.ndarray | None = None  # the most leading components restored so far
        self._gram: dict = {}
        self._lock = threading.Lock()  # an encode's pieces ask from several threads: restored once

    def rows(self, k: int) -> np.ndarray:
        """The ``k`` leading stored components, float32 ``(k, Ps)``: the most restored so
        far are kept, and fewer are their leading rows (each row is restored on its own,
        from its own bytes and scales, so they are the same values as restored alone; a
        process that takes several sizes, largest first, restores once, where keeping
        only the last ``k`` restored 30 components again for every size)."""
        with self._lock:
            if self._kept is None or self._kept.shape[0] < k:
                self._kept = self.stored_rows(k)
            return self._kept[:k]

    def rows_at(self, k: int, positions) -> np.ndarray:
        """The ``k`` leading restored components at ``positions`` among the restored
        cells, float32 ``(k, n)``."""
        _, ia, ib, wa, wb = self.how
        s = self.rows(k)
        pos = np.asarray(positions)
        return s[:, ia[pos]] * wa[pos] + s[:, ib[pos]] * wb[pos]

    def mapped(self, coefficients) -> np.ndarray:
        """The restored mapped values ``mean + A^T c`` ``(P, 3)`` float32 of coefficients
        ``(k, 3)``."""
        c = np.asarray(coefficients, np.float32)
        stored = self.rows(c.shape[0]).T @ c
        stored += self.mean[:, None]
        _, ia, ib, wa, wb = self.how
        return stored[ia] * wa[:, None] + stored[ib] * wb[:, None]

    def normal_equations(self, k: int, b, ok=None):
        """``(A A^T, A b)`` over the restored cells where ``ok`` (all by default), in
        float64, for ``b`` ``(P, C)``: what a least-squares projection solves (``A A^T``
        over all the cells made once a ``k`` and kept: a table measured everywhere the
        basis is, as every MERL table of the grid's measured cells, reuses it)."""
        _, ia, ib, wa, wb = self.how
        s = self.rows(k).astype(np.float64)
        ps = s.shape[1]
        wa, wb = wa.astype(np.float64), wb.astype(np.float64)
        if ok is not None:
            wa, wb = np.where(ok, wa, 0.0), np.where(ok, wb, 0.0)
            b = np.where(np.isfinite(b), b, 0.0)
        v = np.stack([np.bincount(ia, wa * b[:, j], ps) + np.bincount(ib, wb * b[:, j], ps)
                      for j in range(b.shape[1])], 1)
        if ok is None and k in self._gram:
            return self._gram[k].copy(), s @ v
        from brdfkit.runtime import blas_threads

        x = s * np.sqrt(np.bincount(ia, wa * wa, ps) + np.bincount(ib, wb * wb, ps))
        with blas_threads(1):  # kept for later tables: the same sums whoever asked first
            ata = x @ x.T
            both = (wb > 0) & (ia != ib)  # restored between two stored cells: their cross term
            x = s[:, ia[both]] * (wa[both] * wb[both])
            x = x @ s[:, ib[both]].T
        ata += x + x.T
        if ok is None:
            self._gram = {k: ata.copy()}
        return ata, s @ v
