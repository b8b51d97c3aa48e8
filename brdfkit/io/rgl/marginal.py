"""The conditional 2D distributions of the RGL format, as Mitsuba 3 builds and warps them.

Mitsuba 3's ``measured`` BSDF (and pbrt-v4's ``MeasuredBxDF``) hold every 2D field of a
``.bsdf`` file in a ``Marginal2D`` (Mitsuba's ``include/mitsuba/core/distr_2d.h``,
continuous variant): a grid of ``h x w`` values on the unit square, interpolated
bilinearly, optionally depending on extra parameters (the incident direction
``(phi_i, theta_i)``, and the wavelength or colour channel) between whose grid values it
interpolates linearly, clamping outside. A normalised one is a probability density with
a sampling warp (marginal CDF over rows, conditional CDF over columns, each the exact
integral of the bilinear interpolant) and its inverse.

:class:`Marginal2D` is that object in NumPy, vectorised over query points, each with its
own parameters, in float64: the writer needs the forward warp (:meth:`Marginal2D.sample`:
where a sample-space node lands), the readers the inverse (:meth:`Marginal2D.invert`)
and the interpolant (:meth:`Marginal2D.eval`). Written from the published description
and behaviour of those classes (Dupuy and Jakob 2018, "An Adaptive Parameterization for
Efficient Material Acquisition and Rendering", section 5), not copied.

May import: numpy only.
"""

from __future__ import annotations

import numpy as np

__all__ = ["Marginal2D", "param_corners"]

_EPS = float(np.float32(2.0 ** -24))  # Mitsuba's dr::Epsilon<float>
_ONE_MINUS_EPS = float(np.float32(1.0 - 2.0 ** -24))


def param_corners(values, params):
    """Slices and weights of linear interpolation over parameter grids.

    Parameters
    ----------
    values
        One increasing 1-D array per parameter (its grid values), ``D`` of them.
    params
        ``D`` arrays ``(M,)`` of query values (broadcastable).

    Returns
    -------
    list
        ``[(slice_index (M,) int64, weight (M,) float64)]``, ``2 ** D`` corners: the
        slice index is flat over the parameter grids (last parameter fastest, as the
        fields are stored). A parameter with one grid value has weight 1 on it; values
        outside a grid are clamped (the end slice alone), as in Mitsuba.
    """
    corners = [(np.zeros(1, np.int64), np.ones(1))]
    for grid, p in zip(values, params):
        grid = np.asarray(grid, np.float64)
        n = grid.size
        corners = [(s * n, w) for s, w in corners]
        if n == 1:
            continue
        p = np.asarray(p, np.float64)
        idx = np.clip(np.searchsorted(grid, p, side="left") - 1, 0, n - 2)
        w1 = np.clip((p - grid[idx]) / (grid[idx + 1] - grid[idx]), 0.0, 1.0)
        corners = [(s + idx + k, w * (w1 if k else 1.0 - w1)) for s, w in corners for k in (0, 1)]
    return corners


def _lookup(table, corners, index):
    """``sum_c w_c table[slice_c, index]``: ``table`` ``(S, n)`` or ``(S, n, C)``, ``index``
    ``(M,)``; ``(M,)`` or ``(M, C)``."""
    n = table.shape[1]
    flat = table.reshape(table.shape[0] * n, *table.shape[2:])  # a view: the tables are contiguous
    out = None
    for s, w in corners:
        v = np.take(flat, index if (s.size == 1 and s[0] == 0) else s * n + index, axis=0)
        v = v * (w if v.ndim == 1 else w[:, None])
        out = v if out is None else out + v
    return out


class Marginal2D:
    """A bilinear 2D function on ``[0, 1]^2`` over parameter slices, and its warp.

    Parameters
    ----------
    data
        ``(*param_shape, h, w)`` non-negative values (``h, w >= 2``): row ``y`` of a slice
        sits at ``y / (h - 1)`` of the second coordinate, column ``x`` at ``x / (w - 1)``
        of the first.
    param_values
        One increasing 1-D grid per leading axis of ``data`` (may be empty).
    normalize
        Scale each slice to integrate to 1 (a density); otherwise values are kept
        (a plain interpolant, as Mitsuba's ``ndf``, ``sigma`` and ``rgb`` fields).
    sampling
        Build the CDFs (:meth:`sample` and :meth:`invert` need them).
    channels
        ``data`` is ``(*param_shape, C, h, w)``: ``C`` interpolants evaluated together
        (:meth:`eval` returns ``(M, C)``), as a last parameter at its integer values
        would be (the ``rgb`` field); only without ``sampling``.
    """

    def __init__(self, data, param_values=(), *, normalize=True, sampling=True, channels=False):
        data = np.asarray(data, np.float64)
        self.h, self.w = data.shape[-2:]
        self.param_values = [np.asarray(v, np.float64).reshape(-1) for v in param_values]
        if channels:
            c = data.shape[-3]
            self.data = _f32(np.moveaxis(data.reshape(-1, c, self.h * self.w), 1, 2))
            self.n_slices, self.normalized = self.data.shape[0], False
            return
        slices = data.reshape(-1, self.h, self.w)
        self.n_slices = slices.shape[0]
        if sampling:
            sx, sy = 0.5 / (self.w - 1), 0.5 / (self.h - 1)
            cond = np.cumsum(sx * (slices[:, :, :-1] + slices[:, :, 1:]), axis=2)  # (S, h, w-1)
            rows = cond[:, :, -1]
            marg = np.cumsum(sy * (rows[:, :-1] + rows[:, 1:]), axis=1)  # (S, h-1)
            with np.errstate(divide="ignore"):
                norm = 1.0 / marg[:, -1] if normalize else np.ones(self.n_slices)
            # Computed in float64 and held in float32, as the renderers do.
            self.cond = _f32((cond * norm[:, None, None]).reshape(self.n_slices, -1))
            self.marg = _f32(marg * norm[:, None])
            slices = slices * norm[:, None, None]
        self.data = _f32(slices.reshape(self.n_slices, -1))
        self.normalized = normalize

    def corners(self, params):
        """:func:`param_corners` of this function's parameter grids at ``params``: pass
        them as ``corners=`` to several calls at the same parameters."""
        return param_corners(self.param_values, params)

    def eval(self, pos, params=(), corners=None):
        """The interpolant at points ``pos`` ``(M, 2)`` in ``[0, 1]^2`` (clamped); ``(M,)``
        (``(M, C)`` with ``channels``)."""
        corners = corners if corners is not None else self.corners(params)
        p = np.clip(pos, 0.0, 1.0) * (self.w - 1, self.h - 1)
        x0 = np.minimum(p[:, 0].astype(np.int64), self.w - 2)
        y0 = np.minimum(p[:, 1].astype(np.int64), self.h - 2)
        fx, fy = p[:, 0] - x0, p[:, 1] - y0
        i = x0 + y0 * self.w
        v00, v10 = _lookup(self.data, corners, i), _lookup(self.data, corners, i + 1)
        v01, v11 = _lookup(self.data, corners, i + self.w), _lookup(self.data, corners, i + self.w + 1)
        if v00.ndim > 1:
            fx, fy = fx[:, None], fy[:, None]
        return (1 - fy) * ((1 - fx) * v00 + fx * v10) + fy * ((1 - fx) * v01 + fx * v11)

    def invert(self, pos, params=(), corners=None):
        """The sample-space point each of ``pos`` ``(M, 2)`` warps from (the inverse of
        :meth:`sample`), and the density there: ``((M, 2), (M,))``."""
        corners = corners if corners is not None else self.corners(params)
        w, h = self.w, self.h
        p = np.clip(pos, 0.0, 1.0) * (w - 1, h - 1)
        x0 = np.minimum(p[:, 0].astype(np.int64), w - 2)
        y0 = np.minimum(p[:, 1].astype(np.int64), h - 2)
        fx, fy = p[:, 0] - x0, p[:, 1] - y0
        i = x0 + y0 * w
        v00, v10 = _lookup(self.data, corners, i), _lookup(self.data, corners, i + 1)
        v01, v11 = _lookup(self.data, corners, i + w), _lookup(self.data, corners, i + w + 1)
        c0, c1 = v00 + (v01 - v00) * fy, v10 + (v11 - v10) * fy
        pdf = c0 + (c1 - c0) * fx
        sx = fx * (c0 + (c1 - c0) * 0.5 * fx) / (w - 1)
        ic = y0 * (w - 1)
        prev = np.maximum(ic + x0 - 1, 0)
        cdf0 = np.where(x0 > 0, _lookup(self.cond, corners, prev), 0.0)
        cdf1 = np.where(x0 > 0, _lookup(self.cond, corners, prev + (w - 1)), 0.0)
        sx = sx + cdf0 + (cdf1 - cdf0) * fy
        r0 = _lookup(self.cond, corners, ic + w - 2)
        r1 = _lookup(self.cond, corners, ic + 2 * (w - 1) - 1)
        sx = sx / (r0 + (r1 - r0) * fy)
        sy = fy * (r0 + (r1 - r0) * 0.5 * fy) / (h - 1)
        sy = sy + np.where(y0 > 0, _lookup(self.marg, corners, np.maximum(y0 - 1, 0)), 0.0)
        if not self.normalized:
            sy = sy / _lookup(self.marg, corners, np.full_like(y0, h - 2))
        return np.stack([sx, sy], -1), pdf

    def sample(self, u, params=()):
        """Warp uniform points ``u`` ``(M, 2)`` to the distribution: ``((M, 2), pdf (M,))``.

        Rows first (the marginal CDF), then the column in the row pair (the conditional
        CDF interpolated between the two rows), each segment inverted exactly.
        """
        corners = self.corners(params)
        w, h = self.w, self.h
        u = np.clip(np.asarray(u, np.float64), _EPS, _ONE_MINUS_EPS)
        m = u.shape[0]
        marg = np.broadcast_to(sum(wt[:, None] * self.marg[s] for s, wt in corners), (m, h - 1))
        sy = u[:, 1] * (1.0 if self.normalized else marg[:, -1])
        row = np.minimum((marg < sy[:, None]).sum(1), h - 2)
        sy = sy - np.where(row > 0, marg[np.arange(m), np.maximum(row - 1, 0)], 0.0)
        ic = row * (w - 1)
        r0 = _lookup(self.cond, corners, ic + w - 2)
        r1 = _lookup(self.cond, corners, ic + 2 * (w - 1) - 1)
        ty = _segment(sy, h - 1, r0, r1)
        sx = u[:, 0] * (r0 + (r1 - r0) * ty)
        cols = np.arange(w - 1)
        cond = sum(wt[:, None] * ((1 - ty)[:, None] * self.cond[s[:, None], (ic[:, None] + cols)]
                                  + ty[:, None] * self.cond[s[:, None], (ic[:, None] + w - 1 + cols)])
                   for s, wt in corners)
        col = np.minimum((cond < sx[:, None]).sum(1), w - 2)
        sx = sx - np.where(col > 0, cond[np.arange(m), np.maximum(col - 1, 0)], 0.0)
        i = row * w + col
        v00, v10 = _lookup(self.data, corners, i), _lookup(self.data, corners, i + 1)
        v01, v11 = _lookup(self.data, corners, i + w), _lookup(self.data, corners, i + w + 1)
        c0, c1 = v00 + (v01 - v00) * ty, v10 + (v11 - v10) * ty
        tx = _segment(sx, w - 1, c0, c1)
        pos = np.stack([(col + tx) / (w - 1), (row + ty) / (h - 1)], -1)
        return pos, c0 + (c1 - c0) * tx


def _f32(a):
    """``a`` rounded to float32, held in float64."""
    return a.astype(np.float32).astype(np.float64)


def _segment(s, inv_width, v0, v1):
    """``t`` in ``[0, 1]`` with ``integral_0^t lerp(v0, v1, x) dx / inv_width = s``."""
    non_const = np.abs(v0 - v1) > 1e-4 * (v0 + v1)
    s2 = s * 2.0 * inv_width
    with np.errstate(invalid="ignore", divide="ignore"):
        t_lin = (v0 - np.sqrt(np.maximum(v0 * v0 + s2 * (v1 - v0), 0.0))) / (v0 - v1)
        t_const = s2 / (v0 + v1)
    t = np.where(non_const, t_lin, t_const)
    return np.clip(np.nan_to_num(t, nan=0.0, posinf=1.0), 0.0, 1.0)
