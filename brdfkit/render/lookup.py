"""A MERL-grid table prepared for a renderer's many trilinear lookups, in NumPy.

:func:`brdfkit.geometry.trilinear.lookup_trilinear` interpolates a ``(90, 90, 180, C)``
table trilinearly in the grid's own coordinates, leaving out the corners not measured
(NaN) and renormalising the weights over the rest (``fill`` where none is). A render
looks a table up at millions of pairs (:mod:`brdfkit.render.pairs` gives their grid
coordinates); :class:`TableRows` holds the table so that each of a point's eight corners
is one 16-byte gather:

* one row per cell: its ``C`` values with NaN replaced by 0, then its measured flags (1
  or 0; one flag when every channel is measured or not together, as in MERL tables,
  else one per channel), padded to a multiple of four float32 (16 bytes);
* each ``(theta_h, theta_d)`` run of cells repeats its ``phi_d = 0`` cell after the last
  (181 cells a run), so the wrap of ``phi_d`` over ``pi`` costs no operation.

The interpolated value is ``sum_c w_c v_c / sum_c w_c f_c`` over the corners ``c``
(weights ``w_h w_d w_p``, flags ``f``): the plain lookup's, to float32 rounding
(``tests/test_lookup.py``). :func:`corners` gives the corners' row numbers and weights
alone, with which a refinement evaluates a decoder only at the cells a render reaches
(:mod:`brdfkit.basis.refine_on_screen`); :meth:`TableRows.from_cells` holds a decode at
those cells alone (:meth:`brdfkit.render.renderable.DecodedBRDF.prepare_cells`).

Examples
--------
>>> import numpy as np
>>> rows = TableRows(np.full((90, 90, 180, 3), 0.25))
>>> rows.lookup(np.array([[10.5], [3.2], [179.5]], np.float32)).round(6).tolist()
[[0.25], [0.25], [0.25]]
"""

from __future__ import annotations

import numpy as np

from brdfkit.geometry import N_PHI_D, N_THETA_D, N_THETA_H

__all__ = ["TableRows", "corners", "ROW_CELLS", "BLOCK"]

ROW_CELLS = N_THETA_H * N_THETA_D * (N_PHI_D + 1)
"""Rows of a prepared table: the grid with each ``phi_d`` run's first cell repeated."""

BLOCK = 1 << 13
"""Points per block of a lookup: the corners' rows and weights of one block stay in cache."""

_STEP = (N_THETA_D * (N_PHI_D + 1), N_PHI_D + 1, 1)
_TOP = (N_THETA_H - 1, N_THETA_D - 1)
# Corner k = 4 a + 2 b + c: theta_h corner a, theta_d corner b, phi_d corner c.
_BITS = [(k >> 2 & 1, k >> 1 & 1, k & 1) for k in range(8)]


def row_of(cells):
    """The prepared rows of flat MERL cell indices (``phi_d`` runs of 181)."""
    cells = np.asarray(cells, np.int64)
    return cells + cells // N_PHI_D


def cell_of(rows):
    """Flat MERL cell indices of prepared rows (the repeated cell 180 is cell 0 of its run)."""
    rows = np.asarray(rows, np.int64)
    run, k = np.divmod(rows, N_PHI_D + 1)
    return run * N_PHI_D + np.where(k == N_PHI_D, 0, k)


def corners(coords):
    """Row numbers (prepared rows, :data:`ROW_CELLS`) and weights of the eight corners of
    grid coordinates ``coords`` ``(3, m)`` float32 (:func:`brdfkit.geometry.fractional_indices`):
    int64 ``(8, m)`` and float32 ``(8, m)``, in the plain lookup's order (``theta_h``
    outermost) and with its weights ``(w_h w_d) w_p``. A NaN coordinate gives NaN weights
    (so a NaN value) at valid rows."""
    m = coords.shape[1]
    f = np.floor(coords)
    frac = coords - f
    i = f.astype(np.int64)  # NaN: some integer, clipped below to a valid row
    np.clip(i[0], 0, _TOP[0], out=i[0])
    np.clip(i[1], 0, _TOP[1], out=i[1])
    np.clip(i[2], 0, N_PHI_D - 1, out=i[2])
    hi_h = np.minimum(i[0] + 1, _TOP[0])
    hi_d = np.minimum(i[1] + 1, _TOP[1])
    i[0] *= _STEP[0]
    i[1] *= _STEP[1]
    hi_h *= _STEP[0]
    hi_d *= _STEP[1]
    rows = np.empty((8, m), np.int64)
    np.add(i[0], i[1], out=rows[0])
    np.add(i[0], hi_d, out=rows[2])
    np.add(hi_h, i[1], out=rows[4])
    np.add(hi_h, hi_d, out=rows[6])
    rows[0::2] += i[2]
    np.add(rows[0::2], 1, out=rows[1::2])  # phi_d's upper corner: the next row (180: the repeated cell)
    one = 1 - frac
    wh = (one[0] * one[1], one[0] * frac[1], frac[0] * one[1], frac[0] * frac[1])
    weights = np.empty((8, m), np.float32)
    for k in range(4):
        np.multiply(wh[k], one[2], out=weights[2 * k])
        np.multiply(wh[k], frac[2], out=weights[2 * k + 1])
    return rows, weights


class TableRows:
    """A ``(90, 90, 180, C)`` table (NaN where not measured) prepared for lookups (module
    docstring): 1.34 times a float32 MERL table's memory, built in about 0.05 s.

    Parameters
    ----------
    table
        ``(90, 90, 180, C)`` array, 1/sr, NaN where not measured; or, with ``rows``
        given, ``None``.
    rows
        float32 ``(ROW_CELLS, W)`` rows already made (:meth:`from_cells`).
    channels, flags
        With ``rows``: the values and measured flags a row holds.
    """

    def __init__(self, table=None, *, rows=None, channels: int = 3, flags: int = 1):
        if rows is None:
            flat = np.asarray(table, np.float32).reshape(N_THETA_H * N_THETA_D, N_PHI_D, -1)
            channels = flat.shape[2]
            nan = np.isnan(flat)
            shared = bool((nan == nan[..., :1]).all())
            measured = ~(nan[..., :1] if shared else nan)
            flags = measured.shape[2]
            width = -(-(channels + flags) // 4) * 4
            rows = np.zeros((N_THETA_H * N_THETA_D, N_PHI_D + 1, width), np.float32)
            rows[:, :N_PHI_D, :channels] = np.where(nan, 0.0, flat)
            rows[:, :N_PHI_D, channels:channels + flags] = measured
            rows[:, N_PHI_D] = rows[:, 0]
            rows = rows.reshape(ROW_CELLS, width)
        self.rows, self.channels, self.flags = rows, int(channels), int(flags)
        width = rows.shape[1]
        self._elements = rows.view(np.complex128).reshape(-1) if width == 4 else rows.view(np.complex128)

    @classmethod
    def from_cells(cls, cells, values, channels: int = 3) -> "TableRows":
        """Rows holding ``values`` ``(n, C)`` (finite) at flat MERL ``cells`` ``(n,)``,
        every other cell unmeasured: a decoder evaluated only where a render looks
        (:meth:`brdfkit.render.renderable.DecodedBRDF.prepare_cells`)."""
        width = -(-(channels + 1) // 4) * 4
        rows = np.zeros((ROW_CELLS, width), np.float32)
        r = row_of(cells)
        rows[r, :channels] = values
        rows[r, channels] = 1.0
        wrap = np.asarray(cells) % N_PHI_D == 0  # the repeated cell 180 of its run
        rows[r[wrap] + N_PHI_D] = rows[r[wrap]]
        return cls(rows=rows, channels=channels, flags=1)

    def gather(self, rows):
        """float32 ``(*rows.shape, W)`` of row numbers ``rows``."""
        g = self._elements[rows.reshape(-1)]
        return g.view(np.float32).reshape(rows.shape + (self.rows.shape[1],))

    def combine(self, g, weights, out):
        """Interpolate gathered corner rows ``g`` ``(8, m, W)`` with ``weights`` ``(8, m)``
        into ``out`` ``(C, m)``: ``sum w v / sum w f``, 0 where no corner is measured.
        The corners are summed in order, as the plain lookup sums them."""
        w = np.repeat(weights[:, :, None], g.shape[2], axis=2)  # contiguous: no strided broadcast
        w *= g
        acc = w[0]
        for k in range(1, 8):
            acc += w[k]
        c, f = self.channels, self.flags
        wsum = acc[:, c:c + f].T
        wsum = wsum + (wsum == 0)  # no measured corner: every value is 0, so is the result
        np.divide(acc[:, :c].T, wsum, out=out)

    def lookup(self, coords, out=None):
        """float32 ``(C, m)`` at grid coordinates ``coords`` ``(3, m)`` (0 where no corner
        is measured: the renderer's fill)."""
        m = coords.shape[1]
        out = np.empty((self.channels, m), np.float32) if out is None else out
        for s in range(0, m, BLOCK):
            rows, w = corners(coords[:, s:s + BLOCK])
            self.combine(self.gather(rows), w, out[:, s:s + BLOCK])
        return out
