"""How much each cell of a training table shows in renders: the residual's training
through the objective scenes' renders (``brdfkit fit --method residual -O
render_weight=L``).

A small render of an objective scene (:data:`brdfkit.render.objective.OBJECTIVE`, never a
judged one) is linear in the table: pixel ``p`` of a channel is ``I_p = sum_c A_pc rho_c``,
``A`` the screen's pairs, their trilinear corner weights and radiance times quadrature
weight (:func:`brdfkit.basis.refine_on_screen.cell_map`). The render error is measured
after the display encoding ``D`` (:mod:`brdfkit.render.display`), so to first order a
change ``dx'_c`` of cell ``c``'s mapped value moves pixel ``p`` by
``D'(I_p) A_pc (d rho / d x')_c dx'_c``, with ``d rho / d x' = (rho w + eps) / w``
(:mod:`brdfkit.basis.mapping`). A cell's *render weight* is the square of that summed over
the pixels and the scenes::

    g_c = (d rho / d x')_c^2  sum_scenes sum_p D'(I_p)^2 A_pc^2

the diagonal of the Gauss-Newton matrix of the render error in the mapped values: the loss
``sum_c g_c e_c^2`` is the render error of mapped errors ``e`` that do not cancel within a
pixel. Per channel it is scaled to mean 1 over the measured cells, so that every channel
of every material counts alike, as in the mapped loss.

The weights span many decades (a mirror peak's cells are a million times a diffuse cell's),
so the training does not multiply uniformly drawn cells by them: it draws cells *in
proportion* to the loss weight ``(1 - L) + L g_c`` (a share ``L`` of each row's cells from
a fixed pool drawn from ``g``, :func:`cell_pool`), whose plain mean square is then that
weighted loss without the variance of rare heavy cells.
"""

from __future__ import annotations

import numpy as np

__all__ = ["POOL", "scene_maps", "render_weights", "cell_pool"]

POOL = 65536
"""Cells of a row's pool drawn in proportion to its render weights."""


def scene_maps(basis, resolution: int = 32, scenes=None) -> list:
    """``[(screen, maps)]`` of the objective scenes: each screen
    (:func:`brdfkit.render.screen.screen`) and, per channel, the squares of its linear map
    from the basis's cells to its pixels (scipy CSR ``(P, cells)``, pairs summed per pixel
    and cell before squaring), with the map's pixels and cells' positions in the basis."""
    import scipy.sparse

    from brdfkit.basis.refine_on_screen import cell_map
    from brdfkit.render.objective import OBJECTIVE
    from brdfkit.render.scene_suite import scene_env
    from brdfkit.render.screen import screen

    basis_row = np.full(90 * 90 * 180, -1, np.int64)
    basis_row[basis.cells] = np.arange(basis.cells.size)
    out = []
    for name in scenes or OBJECTIVE:
        sc = screen(None, resolution, env=scene_env(name))
        m = cell_map(basis, sc, np.arange(sc.pix.size), basis_row=basis_row)
        length = np.diff(np.append(m.starts, m.cols.size))
        rows = np.repeat(np.arange(m.pixels.size), length)
        squares = []
        for ch in range(3):
            a = scipy.sparse.csr_matrix((m.vals[ch], (rows, m.cols)), shape=(m.pixels.size, m.cells.size))
            a.sum_duplicates()
            squares.append(a.multiply(a).T.tocsr())
        out.append((sc, squares, m.pixels, basis_row[m.cells]))
    return out


def render_weights(basis, table, maps) -> np.ndarray:
    """float32 ``(P, 3)``: the render weight of each of the basis's cells and channels for
    ``table`` (``(90, 90, 180, 3)``, 1/sr, NaN unmeasured; module docstring), mean 1 per
    channel over the measured cells, 0 at the unmeasured ones.

    ``maps``: :func:`scene_maps` of the basis.
    """
    from brdfkit.render.display import display_slope

    g = np.zeros((basis.cells.size, 3))
    for sc, squares, pixels, at in maps:
        image = np.asarray(sc.render_table(np.nan_to_num(table)), np.float64)
        d2 = display_slope(image)[pixels] ** 2
        for ch in range(3):
            np.add.at(g[:, ch], at, squares[ch] @ d2[:, ch])
    rho = np.asarray(table, np.float64).reshape(-1, 3)[basis.cells]
    g *= basis.mapping.rho_slope(rho, basis.cell_weight()[:, None], basis.reference[:, None]) ** 2
    g[~np.isfinite(rho)] = 0.0
    mean = g.mean(axis=0)
    return (g / np.where(mean > 0, mean, 1.0)).astype(np.float32)


def cell_pool(weights: np.ndarray, seed: int, size: int = POOL) -> np.ndarray:
    """int32 ``(size,)`` cells drawn with replacement in proportion to ``weights`` ``(P,)``
    (one row's render weights), sorted: the pool a row's render-weighted cells come from.

    Examples
    --------
    >>> cell_pool(np.array([0.0, 1.0, 0.0, 3.0]), seed=0, size=8).tolist()
    [1, 1, 3, 3, 3, 3, 3, 3]
    """
    p = np.asarray(weights, np.float64)
    total = p.sum()
    if not total > 0:
        return np.random.default_rng(seed).integers(0, p.size, size, dtype=np.int32)
    cdf = np.cumsum(p / total)
    u = np.random.default_rng(seed).random(size)
    return np.sort(np.searchsorted(cdf, u * cdf[-1], side="right").clip(0, p.size - 1)).astype(np.int32)
