"""Trilinear lookups in MERL-grid tables, and the table prepared for a renderer's many.

:func:`lookup_trilinear` interpolates a ``(90, 90, 180, C)`` table (NumPy or torch) at
arbitrary angles, in the grid's own coordinates
(:func:`brdfkit.geometry.fractional_indices`), leaving out the corners not measured and
renormalising the weights over the rest (``fill`` where none is measured).
:class:`TrilinearTable` gives what it gives on the plain table, to the bit, NaN semantics
included, only faster: a render of a table evaluates 11.8 M direction pairs, and this
lookup was most of each (``docs/notes/performance.md``). :func:`lookup_trilinear` takes either.

How, and why this way (PyTorch's CPU kernels, one thread; ``docs/notes/performance.md``):

* One row per cell: its ``C`` values with NaN replaced by 0, then its measured flags (1
  or 0; one flag when every channel is measured or not together, as in MERL tables,
  else one per channel), padded to 8 or a multiple of 16 bytes (16 for a float32 MERL
  table). A lookup fetches each of its eight corners as *one* element of a 1-D gather
  (an ``int64`` or ``complex128`` view of the rows): eight gathers a point, all of a
  corner's numbers from one cache line, no NaN tests.
* Each ``(theta_h, theta_d)`` run of cells repeats its ``phi_d = 0`` cell after the last
  (181 cells a run), so the wrap of ``phi_d`` over ``pi`` costs no operation.
* The gathered rows are turned channel-major once, copied as integers of the same width
  (PyTorch transposes an ``int32`` array about twice as fast as a ``float32`` one, or as
  a multiplication reading it strided), and all the arithmetic runs on contiguous
  ``(8, m)`` and ``(m,)`` arrays (no strided or broadcast ``(m, C)`` operations, which
  run several times slower), in blocks of :attr:`TrilinearTable.block` points: large
  enough to amortise each operation's few microseconds of dispatch, small enough to
  stay in cache.
* Each term and each sum is the one the plain lookup computes, in the same order: value
  times weight and flag times weight (exact: the flag is 0 or 1), the weight
  ``(w_h w_d) w_phi``, summed corner by corner with ``theta_h`` outermost; so the result
  is the same to the bit (``tests/test_lookup.py`` pins it against a frozen copy).
"""

from __future__ import annotations

import numpy as np

from brdfkit.geometry import N_CELLS, N_PHI_D, N_THETA_D, N_THETA_H, array_module, fractional_indices

__all__ = ["lookup_trilinear", "TrilinearTable", "lookup_prepared", "lookup_prepared_many"]


def lookup_trilinear(table, theta_h, theta_d, phi_d, fill=float("nan")):
    """Trilinear interpolation of a MERL-grid table at arbitrary angles.

    Interpolates in the grid's own coordinates (``sqrt`` spacing of ``theta_h``), clamps
    at ``theta = pi/2`` and wraps ``phi_d`` over ``pi``. Corners holding NaN (cells not
    measured) are left out and the remaining weights renormalised, so values next to the
    horizon stay defined; where no corner is measured the result is ``fill``.

    Parameters
    ----------
    table
        ``(90, 90, 180, C)`` array or tensor, NaN where not measured, or a
        :class:`TrilinearTable` of one (same results to the bit, about four times faster
        than the plain table, on one CPU thread; for many calls).
    theta_h, theta_d, phi_d
        Angles in radians, broadcastable, shape ``(...)``.

    Returns
    -------
    array
        ``(..., C)`` of the table's dtype (float64 for NumPy).
    """
    u_h, u_d, u_p = fractional_indices(theta_h, theta_d, phi_d)
    if isinstance(table, TrilinearTable):
        return lookup_prepared(table, u_h, u_d, u_p, fill)
    xp = array_module(u_h)
    flat = table.reshape(N_CELLS, -1)
    if xp is np:
        u_h, u_d, u_p = np.broadcast_arrays(u_h, u_d, u_p)
        floor = lambda a: np.floor(a).astype(np.int64)  # noqa: E731
    else:
        u_h, u_d, u_p = xp.broadcast_tensors(u_h, u_d, u_p)
        floor = lambda a: xp.floor(a).long()  # noqa: E731
    i0, j0, k0 = floor(u_h), floor(u_d), floor(u_p)
    fh, fd, fp = u_h - i0, u_d - j0, u_p - k0
    i0 = xp.clip(i0, 0, N_THETA_H - 1)
    j0 = xp.clip(j0, 0, N_THETA_D - 1)
    i1 = xp.clip(i0 + 1, 0, N_THETA_H - 1)
    j1 = xp.clip(j0 + 1, 0, N_THETA_D - 1)
    k0 = k0 % N_PHI_D
    k1 = (k0 + 1) % N_PHI_D
    acc = None
    wsum = None
    for ii, wh in ((i0, 1 - fh), (i1, fh)):
        for jj, wd in ((j0, 1 - fd), (j1, fd)):
            for kk, wp in ((k0, 1 - fp), (k1, fp)):
                v = flat[kk + N_PHI_D * (jj + N_THETA_D * ii)]
                w = (wh * wd * wp)[..., None]
                ok = ~xp.isnan(v)
                # zeros_like, not 0 * v: 0 * NaN is NaN and would poison the sum.
                wv = w * xp.where(ok, v, xp.zeros_like(v))
                wk = xp.where(ok, w, xp.zeros_like(w))
                acc = wv if acc is None else acc + wv
                wsum = wk if wsum is None else wsum + wk
    out = acc / xp.where(wsum > 0, wsum, 1 + 0 * wsum)
    return xp.where(wsum > 0, out, fill + 0 * out)


class TrilinearTable:
    """A MERL-grid table prepared for many :func:`lookup_trilinear` calls.

    Costs 1.34 times a float32 MERL table's memory (23.5 MB), and to build about as much
    as one plain lookup of 100,000 points; build it once per table. Runs in torch, on the
    table's device: a NumPy table is held as a CPU tensor, and its lookups return NumPy
    arrays.

    Parameters
    ----------
    table
        ``(90, 90, 180, C)`` array or tensor, NaN where not measured.
    """

    def __init__(self, table):
        import torch

        self.numpy = isinstance(table, np.ndarray)
        flat = torch.from_numpy(np.ascontiguousarray(table)) if self.numpy else table
        flat = flat.reshape(N_CELLS, -1)
        self.channels = c = flat.shape[1]
        nan = torch.isnan(flat)
        # One flag per cell when every channel is measured or not together (MERL tables).
        shared = bool((nan == nan[:, :1]).all())
        measured = ~(nan[:, :1] if shared else nan)
        self.flags = measured.shape[1]
        width, size = c + self.flags, flat.element_size()
        while width * size != 8 and width * size % 16:
            width += 1
        rows = flat.new_zeros((N_THETA_H * N_THETA_D, N_PHI_D + 1, width))
        rows[:, :N_PHI_D, :c] = torch.where(nan, 0.0, flat).reshape(-1, N_PHI_D, c)
        rows[:, :N_PHI_D, c:c + self.flags] = measured.reshape(-1, N_PHI_D, self.flags)
        rows[:, N_PHI_D] = rows[:, 0]
        # No NaN is left in the rows (unmeasured values are 0), so finite is no infinity:
        # one reduction instead of isfinite's four passes (a third of the build).
        lo, hi = torch.aminmax(rows)
        self.finite = bool(lo > -torch.inf) and bool(hi < torch.inf)
        self.rows = rows.reshape(-1, width)
        view = self.rows.view(torch.int64 if width * size == 8 else torch.complex128)
        self._elements = view.reshape(-1) if view.shape[1] == 1 else view
        self._int = {2: torch.int16, 4: torch.int32, 8: torch.int64}[size]
        # Per axis (theta_h, theta_d, phi_d), corners 0 and 1: weights frac * (-1, 1) +
        # (1, 0); indices floor + (0, 1), clamped to the grid (phi_d's corner 1 may be 180,
        # the repeated cell) and scaled to row numbers.
        f32, i32 = dict(device=flat.device), dict(dtype=torch.int32, device=flat.device)
        self._sign = torch.tensor([[-1.0], [1.0]], **f32)
        self._one_zero = torch.tensor([[1.0], [0.0]], **f32)
        self._zero_one = torch.tensor([[0], [1]], **i32)
        top = [[[N_THETA_H - 1]] * 2, [[N_THETA_D - 1]] * 2, [[N_PHI_D - 1], [N_PHI_D]]]
        self._top = torch.tensor(top, **i32)
        self._step = torch.tensor([[[N_THETA_D * (N_PHI_D + 1)]], [[N_PHI_D + 1]], [[1]]], **i32)
        # Points per block (2^13 and 2^15 were slower on one CPU thread); a GPU takes more.
        self.block = 1 << 14 if flat.device.type == "cpu" else 1 << 20


def lookup_prepared(lut: TrilinearTable, u_h, u_d, u_p, fill):
    """Trilinear lookup at continuous grid coordinates (those of
    :func:`brdfkit.geometry.fractional_indices`), broadcastable, shape ``(...)``.

    Returns ``(..., C)`` of the promoted type of the table and the coordinates, a tensor
    (channel-major in memory for 1-D coordinates) or a NumPy array for a NumPy table.
    """
    return lookup_prepared_many([lut], u_h, u_d, u_p, fill)[0]


def lookup_prepared_many(luts, u_h, u_d, u_p, fill):
    """:func:`lookup_prepared` of several prepared tables at the same coordinates: the
    corners' rows and weights are computed once per block and each table gathers and
    sums its own, so each result is its :func:`lookup_prepared`, to the bit (the same
    operations on the same numbers). The tables must share their kind (NumPy or torch),
    dtype and device; their channels may differ.

    Why not one table with both tables' rows side by side (32-byte rows, one cache miss
    a corner for both): PyTorch's CPU gather moves at most 16 bytes an element, so such
    rows take two elements a corner, and on the project machine (``docs/notes/performance.md``) that measured
    no faster than two tables, while sharing the corner computation saves its share.
    """
    import torch

    lut = luts[0]
    for other in luts[1:]:
        if (other.numpy, other.rows.dtype, other.rows.device) != (lut.numpy, lut.rows.dtype, lut.rows.device):
            raise ValueError("tables looked up together must share kind, dtype and device")
    if lut.numpy:
        u = torch.from_numpy(np.stack(np.broadcast_arrays(u_h, u_d, u_p)))
    else:
        u = torch.stack(torch.broadcast_tensors(u_h, u_d, u_p))
    shape, n = u.shape[1:], u[0].numel()
    u = u.view(3, n)
    outs = [u.new_empty((t.channels, n), dtype=torch.promote_types(t.rows.dtype, u.dtype)) for t in luts]
    for s in range(0, n, lut.block):
        corner, w = _corners(lut, u[:, s:s + lut.block] if n > lut.block else u)
        for t, out in zip(luts, outs):
            _combine(t, corner, w, fill, out[:, s:s + lut.block] if n > lut.block else out)
    outs = [out.T.reshape(shape + (t.channels,)) for t, out in zip(luts, outs)]
    return [out.numpy() for out in outs] if lut.numpy else outs


def _corners(lut, u):
    """Row numbers ``(8 m,)`` and weights ``(8, m)`` of the corners of grid coordinates
    ``u`` ``(3, m)``, in few operations (each costs a few microseconds of dispatch on a
    CPU, whatever its size)."""
    import torch

    m = u.shape[1]
    f = torch.floor(u)
    # Weights -frac + 1 (the plain lookup's 1 - frac) and frac + 0, frac = u - floor(u)
    # (its u - i0); NaN (whose weight makes the result NaN, as in the plain lookup) made
    # a valid index.
    frac = (u - f)[:, None]
    wh, wd, wp = frac.mul(lut._sign.to(u.dtype)).add_(lut._one_zero.to(u.dtype)).unbind(0)
    i = f.nan_to_num_(0.0).int()[:, None].add(lut._zero_one)
    ih, id_, ip = i.clamp_(max=lut._top).mul_(lut._step).unbind(0)
    # Corner (a, b, k) at 4 a + 2 b + k: the plain lookup's loop order (theta_h outer),
    # its weight (w_h w_d) w_phi.
    corner = ih.view(2, 1, 1, m) + id_.view(1, 2, 1, m) + ip.view(1, 1, 2, m)
    w = (wh.view(2, 1, 1, m) * wd.view(1, 2, 1, m) * wp.view(1, 1, 2, m)).view(8, m)
    return corner.view(-1), w


def _combine(lut, corner, w, fill, out):
    """Gather the corners' rows of ``lut`` and interpolate into ``out`` ``(C, m)``."""
    import torch

    m, c, rows = w.shape[1], lut.channels, lut.rows
    g = lut._elements.index_select(0, corner)
    t = g.view(lut._int).view(8, m, -1).permute(2, 0, 1).contiguous().view(rows.dtype)
    t = t.mul_(w) if t.dtype == w.dtype else t * w
    t = t.unbind(1)
    acc = t[0] + t[1]
    for k in range(2, 8):
        acc += t[k]
    val, wsum = acc[:c], acc[c:c + lut.flags]
    # The weights are >= 0 or NaN: wsum > 0 fails only where wsum is 0 (no measured
    # corner: the plain lookup's acc / 1, then fill + 0 * that) or NaN (NaN either way).
    none = wsum == 0
    torch.div(val, wsum + none, out=out)
    if lut.finite:  # fill + 0 * out is fill
        # Where no corner is measured every corner's value is 0 and its weight finite and
        # >= 0 (or NaN, and then wsum is NaN, not 0), so out is already +0: a fill of 0
        # (the renderer's) needs no pass.
        if fill != 0.0:
            out.masked_fill_(none, fill)
    else:
        out.copy_(torch.where(none, fill + 0 * out, out))
