"""A table's basis coefficients, refined on renders of objective scenes: a small nonlinear
least-squares problem, solved by Levenberg-Marquardt.

:meth:`~brdfkit.basis.model.PcaBasis.project` gives the coefficients that minimise the
squared error of the *mapped* table (``ln`` of the cosine-weighted values). Renders weigh
that error otherwise: a few cells near the specular peak and the grazing rim make most of
an image's light, and the display's tone curve weighs dark pixels more than bright ones.
:func:`refine_coefficients` starts from the projection and lets the ``3 K`` coefficients
minimise the render-aligned error of the objective scenes (:mod:`brdfkit.render.objective`:
never a scene the results are judged in)::

    F(c) = 1/S sum_s mean_{p, ch} (D(I_s(c))_p,ch - D(T_s)_p,ch)^2 + trust |c - c0|^2 / 3 P

over each scene's fitted pixels (``D`` the display encoding, ``I_s`` the render from the
scene's fixed pair draw, ``T_s`` the table's own render, ``P`` the basis's cells; the
second term is :data:`DEFAULT_TRUST`'s trust term on how far the mapped table moves), and
keeps the coefficients with the lowest render error on held-out pixels, the projection's
own included (:func:`brdfkit.render.objective.refine_loop`).

Why a least-squares solver: the unknowns are few (``K <= 13`` a channel), a render is linear in the
table (``I = M rho``, ``M`` the scene's pairs as a sparse map from the cells they reach to
the pixels), the basis is linear in the mapped space (``x' = mean + U c``), and each
channel's image depends on that channel's coefficients alone; so each channel is a
least-squares problem of ``K`` unknowns whose Jacobian is the product
``D'(I) M diag(rho'(x')) U`` at the reached cells. Levenberg-Marquardt
(:mod:`brdfkit.basis.least_squares`, the one solver of every kind's encode) solves it in a
few iterations, each a handful of sparse products; the 80 Adam steps it replaced ran 308
renders and reached a higher objective (``docs/compression.md``). The three channels are
fixed pieces of work, run on as many threads as :func:`brdfkit.runtime.thread_map` has.

The decode is evaluated only at the cells whose trilinear corners the scenes' pairs
reach, as the renderer's lookup of a decoded table would read them (the same corners,
weights and renormalisation over measured cells): no dense table is decoded. Everything
is NumPy, in float64, counted in iterations: the same table and basis give the same
coefficients to the bit, on any number of threads (an encode holds NumPy's BLAS to one,
:data:`brdfkit.render.objective.THREADS`).
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np

from brdfkit.basis.mapping import EPS, FLOOR, Z_MAX
from brdfkit.geometry import N_CELLS

__all__ = ["DEFAULT_TRUST", "DEFAULT_ITERATIONS", "CellMap", "Screens", "cell_map", "prepare_screens",
           "refine_coefficients", "heldout_error", "solve_channels"]

DEFAULT_TRUST = 0.01
"""Weight of the trust term: the mean squared change of the mapped table over the
basis's cells (``|c - c0|^2 / 3P`` for orthonormal components), added to the render error.
Why: the objective scenes light the sphere little from behind; refined without it, the
coefficients trade the backlit rim for the rest (``docs/compression.md``: -2.5 dB in the
judged ``backlight`` scene for +1.6 dB in the suite mean, 20 training materials); with
it, they move only where renders gain much for a small change of the table."""

SOLVER = "levenberg-marquardt"
"""The refinement's solver as an embedding's ``refinement`` record names it."""

DEFAULT_ITERATIONS = 8
"""Most Levenberg-Marquardt iterations of a refinement (``brdfkit encode --steps``)."""


@dataclasses.dataclass
class CellMap:
    """Some pairs of a screen as a linear map from the BRDF at the cells they reach to the
    pixels they light, with the basis at those cells.

    Attributes
    ----------
    cells
        int64 ``(U,)`` flat MERL indices of the reached cells the basis covers.
    mean, comp, weight, reference, bound
        The basis at those cells, float32 (the basis's own precision): the mean ``(U,)``,
        the components ``(K, U)``, the mapping's weight and reference, and the decode's
        lower bound (:meth:`brdfkit.basis.mapping.LogMapping.lower_bound`), ``(U,)`` each.
    pixels
        int64 ``(n,)`` the image pixels the map's rows are, ascending.
    starts
        int64 ``(n,)`` each row's first entry (the entries are sorted by row).
    cols
        int64 ``(E,)`` each entry's cell (position in ``cells``).
    vals
        float64 ``(3, E)`` each entry's corner weight times the pair's radiance, quadrature
        weight and draw factor, per channel.
    extra
        ``None``, or ``extra(c) -> (U, 3)``: mapped values added to the basis's (a
        residual's correction, :mod:`brdfkit.residual.encoding`).
    resolution, scale
        The mapping's ``e`` and ``s`` at those cells (:meth:`~brdfkit.basis.mapping.LogMapping.resolution`),
        float32 ``(U,)``; ``None`` for Nielsen's mapping (``eps`` and 1).
    """

    cells: np.ndarray
    mean: np.ndarray
    comp: np.ndarray
    weight: np.ndarray
    reference: np.ndarray
    bound: np.ndarray
    pixels: np.ndarray
    starts: np.ndarray
    cols: np.ndarray
    vals: np.ndarray
    extra: object = None
    resolution: np.ndarray | None = None
    scale: np.ndarray | None = None

    def mapped(self, c, ch: int | None = None, extra=None):
        """Mapped values ``(U,)`` of channel ``ch`` of coefficients ``c`` ``(K, 3)``, or
        ``(3, U)`` of all three (``ch`` ``None``); float32 (``extra``: :attr:`extra` of
        ``c`` when made already)."""
        cc = np.asarray(c, np.float64)
        out = (cc[:, ch] if ch is not None else cc.T).astype(np.float32) @ self.comp
        out += self.mean
        if self.extra is not None:
            e = (self.extra(c) if extra is None else extra).T
            out += e[ch] if ch is not None else e
        return out

    def rho(self, mapped):
        """``(rho, d rho / d x')`` of float32 mapped values ``(U,)`` or ``(3, U)``: the
        decode (:func:`brdfkit.basis.mapping.from_mapped`, its default floor) and its
        derivative (0 where the floor holds), float32."""
        if self.scale is not None:
            mapped = np.minimum(mapped / self.scale, np.float32(Z_MAX))
        x = np.expm1(mapped)
        e = x + 1.0
        res = EPS if self.resolution is None else self.resolution
        x *= self.reference + res
        x += self.reference
        above = x > self.bound
        rho = np.where(above, x, self.bound)
        rho /= self.weight
        e *= self.reference + res
        e /= self.weight if self.scale is None else self.weight * self.scale
        e[~above] = 0.0
        return rho, e

    def apply(self, ch: int, x):
        """The map of channel ``ch`` applied to per-cell values ``x`` ``(U,)``: ``(n,)``
        float64."""
        prod = self.vals[ch] * x[self.cols]
        return np.add.reduceat(prod, self.starts)

    @functools.cached_property
    def _padded(self):
        """The entries laid out one row a pixel, padded to the longest row: their cells
        ``(n, R)``, values ``(3, n, R)`` and the components there ``(n, R, K)`` (float32,
        0 in the padding), so that a Jacobian is one batch of small matrix products."""
        n = self.pixels.size
        length = np.diff(np.append(self.starts, self.cols.size))
        width = int(length.max()) if n else 0
        row = np.repeat(np.arange(n), length)
        pos = np.arange(self.cols.size) - np.repeat(self.starts, length)
        cols = np.zeros((n, width), np.int64)
        cols[row, pos] = self.cols
        vals = np.zeros((3, n, width), np.float32)
        vals[:, row, pos] = self.vals
        comp = np.ascontiguousarray(self.comp.T)[cols]
        comp[vals[0] == 0] = 0.0
        return cols, vals, comp

    def jacobian(self, ch: int, slope):
        """``d (map of channel ch applied to rho) / d c`` ``(n, K)`` given ``d rho / d x'``
        at the cells ``(U,)`` (the components are ``d x' / d c``)."""
        cols, vals, comp = self._padded
        w = vals[ch] * slope[cols]
        return np.matmul(w[:, None, :].astype(np.float32), comp)[:, 0, :].astype(np.float64)

    def render(self, c):
        """Image rows ``(n, 3)`` float64 of coefficients ``c`` ``(K, 3)``."""
        rho, _ = self.rho(self.mapped(c))
        return np.stack([self.apply(ch, rho[ch]) for ch in range(3)], 1)


def _corner_entries(screen, pairs, factor, basis_row):
    """The corner entries of ``pairs`` (int64 indices into the screen's pairs, sorted by
    pixel): their rows (pixels), cells, and per-channel values, unmeasured corners
    dropped and the weights renormalised over the measured ones."""
    from brdfkit.render.lookup import cell_of, corners

    rows, w = corners(screen.coords[:, pairs])
    cells = cell_of(rows)
    w = np.where(basis_row[cells] >= 0, w.astype(np.float64), 0.0)
    total = w.sum(0)
    w /= np.where(total > 0, total, 1.0)
    rw = screen.rw[pairs].astype(np.float64).T * (1.0 if factor is None else factor)
    keep = w.T.reshape(-1) > 0  # pair-major: each pair's eight corners together
    vals = (w.T[:, :, None] * rw.T[:, None, :]).reshape(-1, 3)[keep].T
    pix = np.repeat(screen.pix[pairs], 8)[keep]
    return pix, cells.T.reshape(-1)[keep], vals


def cell_map(basis, screen, pairs, factor=None, basis_row=None) -> CellMap:
    """The :class:`CellMap` of a screen's ``pairs`` (int64 ``(m,)``, repeats allowed),
    each weighted by ``factor`` (``(m,)``, or ``None``: 1); ``basis_row``: each MERL
    cell's position among the basis's cells, -1 off them."""
    if basis_row is None:
        basis_row = np.full(N_CELLS, -1, np.int64)
        basis_row[basis.cells] = np.arange(basis.cells.size)
    pairs = np.asarray(pairs, np.int64)
    if factor is not None:  # repeats of a pair drawn several times: one pair, their factors summed
        pairs, inv = np.unique(pairs, return_inverse=True)
        factor = np.bincount(inv.reshape(-1), np.asarray(factor, np.float64), minlength=pairs.size)
    order = np.argsort(screen.pix[pairs], kind="stable")
    pairs = pairs[order]
    factor = None if factor is None else factor[order]
    pix, cells, vals = _corner_entries(screen, pairs, factor, basis_row)
    present = np.zeros(N_CELLS, bool)
    present[cells] = True
    used = np.flatnonzero(present)
    pos = np.zeros(N_CELLS, np.int64)
    pos[used] = np.arange(used.size)
    pixels, starts = np.unique(pix, return_index=True)
    row = basis_row[used]
    weight, reference = basis.cell_weight(used), basis.reference[row].astype(np.float64)
    f32 = lambda a: np.ascontiguousarray(a, np.float32)  # noqa: E731
    mapping = basis.mapping
    res, scale = (None, None) if not mapping.share else (f32(a) for a in mapping.resolution(reference))
    return CellMap(used, f32(basis.mean[row]), f32(basis.rows_at(row)), f32(weight), f32(reference),
                   f32(mapping.lower_bound(reference, weight, FLOOR)), pixels, starts, pos[cells], vals,
                   resolution=res, scale=scale)


@dataclasses.dataclass
class Screens:
    """A table's objective views and, for one basis, the maps of their fitted and
    held-out pairs (:func:`prepare_screens`): what a refinement and a choice between
    candidates share, made once. ``fit_targets`` and ``held_targets``: the table's render
    at each map's pixels, ``(n, 3)`` float64."""

    views: list
    fits: list
    helds: list
    fit_targets: list
    held_targets: list

    def with_extra(self, extra, fits: bool = True) -> "Screens":
        """The same maps, the basis's mapped values at each map's cells corrected by
        ``extra(cells) -> (c -> mapped (U, 3))`` (:func:`refine_coefficients`), made once
        for the cells of all the maps together and evaluated once a set of coefficients;
        ``fits=False``: the held-out maps only (all a choice by :meth:`held_error` needs)."""
        if extra is None:
            return self
        import threading

        maps = (self.fits if fits else []) + self.helds
        present = np.zeros(N_CELLS, bool)
        for m in maps:
            present[m.cells] = True
        union = np.flatnonzero(present)
        of_c = extra(union)
        last: list = [None, None]
        lock = threading.Lock()  # the scenes' renders ask from several threads: evaluated once

        def at(c):
            key = np.asarray(c, np.float64).tobytes()
            with lock:
                if last[0] != key:
                    last[:] = [key, of_c(c)]
                return last[1]

        def attach(m):
            pos = np.searchsorted(union, m.cells)
            out = dataclasses.replace(m, extra=lambda c: at(c)[pos])
            if "_padded" in m.__dict__:  # the Jacobian's layout does not depend on the correction
                out.__dict__["_padded"] = m.__dict__["_padded"]
            return out

        return dataclasses.replace(self, fits=[attach(m) for m in self.fits] if fits else self.fits,
                                   helds=[attach(m) for m in self.helds])

    def held_error(self, c) -> float:
        """The render error on the views' held-out pixels (full pairs) of coefficients
        ``c`` ``(K, 3)``: the mean over the scenes of the display MSE."""
        from brdfkit.render.screen import screen_error
        from brdfkit.runtime import thread_map

        # Each scene a fixed piece of work, their mean taken in order: the same bytes on any threads.
        return float(np.mean(list(thread_map(lambda mt: screen_error(mt[0].render(c), mt[1]),
                                             list(zip(self.helds, self.held_targets))))))


def prepare_screens(basis, table, config=None) -> Screens:
    """:class:`Screens` of ``table`` for ``basis``."""
    from brdfkit.render.objective import ObjectiveConfig, objective_views
    from brdfkit.runtime import stage

    cfg = config or ObjectiveConfig()
    basis_row = np.full(N_CELLS, -1, np.int64)
    basis_row[basis.cells] = np.arange(basis.cells.size)
    with stage("objective views"):
        views = objective_views(table, cfg)
    with stage("cell maps"):  # each map a fixed piece of work
        from brdfkit.runtime import thread_map

        jobs = [(v, v.idx, v.weight) for v in views] + [(v, v.held_pairs, None) for v in views]
        maps = list(thread_map(lambda j: cell_map(basis, j[0].screen, j[1], j[2], basis_row), jobs))
        fits, helds = maps[:len(views)], maps[len(views):]
    return Screens(views, fits, helds, [v.target[m.pixels] for v, m in zip(views, fits)],
                   [v.target[m.pixels] for v, m in zip(views, helds)])


class _Channel:
    """One channel's least-squares problem over the fitted maps: its residuals at that
    channel's coefficients ``x`` ``(K,)`` and their Jacobian (:func:`solve_channels`)."""

    def __init__(self, maps, targets, ch, c0, tau):
        from brdfkit.render.display import display_encode

        self.maps, self.ch, self.c0, self.tau = maps, ch, c0, tau
        # 1 / (S 3 n_s): each scene's mean over its pixels and the 3 channels, averaged over scenes.
        self.alpha = [np.sqrt(1.0 / (len(maps) * 3 * m.pixels.size)) for m in maps]
        self.goal = [display_encode(t[:, ch]) for t in targets]
        # A frozen correction (the only kind a fit takes): made once.
        self.extra = [None if m.extra is None else m.extra(c0) for m in maps]

    def evaluate(self, x):
        """``(r, state)``: the stacked residuals (trust term last) at this channel's
        coefficients ``x`` ``(K,)``, and what :meth:`jacobian` needs of them."""
        from brdfkit.render.display import display_encode

        c = np.zeros_like(self.c0)
        c[:, self.ch] = x
        rs, state = [], []
        for m, a, goal, extra in zip(self.maps, self.alpha, self.goal, self.extra):
            rho, slope = m.rho(m.mapped(c, self.ch, extra))
            img = m.apply(self.ch, rho)
            rs.append(a * (display_encode(img) - goal))
            state.append((img, slope))
        rs.append(np.sqrt(self.tau) * (x - self.c0[:, self.ch]))
        return np.concatenate(rs), state

    def jacobian(self, x, state):
        """The Jacobian ``(R, K)`` of the residuals in this channel's coefficients."""
        from brdfkit.render.display import display_slope

        js = [(a * display_slope(img))[:, None] * m.jacobian(self.ch, slope)
              for m, a, (img, slope) in zip(self.maps, self.alpha, state)]
        return np.concatenate(js + [np.sqrt(self.tau) * np.eye(self.c0.shape[0])])


def solve_channels(maps, targets, c0, trust: float = DEFAULT_TRUST, cells: int = 1):
    """The Levenberg-Marquardt step function of :func:`refine_coefficients` over fitted
    maps (:class:`CellMap`) and their targets: ``step(c, k) -> (c, done)``, one iteration
    (:class:`~brdfkit.basis.least_squares.LevenbergMarquardt`) for each of the three
    channels, each its own problem, with its own damping; the channels are fixed pieces
    of work, run on :func:`brdfkit.runtime.thread_map`'s threads (the same bytes on any
    number of them).

    Parameters
    ----------
    maps, targets
        The fitted maps and the table's render at their pixels.
    c0
        ``(K, 3)`` the start and the trust term's centre (the projection).
    trust, cells
        The trust term's weight and the basis's cell count ``P`` (``trust / 3 P`` a
        squared coefficient).
    """
    from brdfkit.basis.least_squares import LevenbergMarquardt
    from brdfkit.runtime import thread_map

    c0 = np.asarray(c0, np.float64)

    chans = [_Channel(maps, targets, ch, c0, trust / (3 * cells)) for ch in range(3)]
    solvers = list(thread_map(lambda p: LevenbergMarquardt(p.evaluate, p.jacobian, c0[:, p.ch]), chans))

    def step(c, k):
        list(thread_map(lambda lm: lm.step(), [lm for lm in solvers if not lm.done]))
        return np.stack([lm.x for lm in solvers], axis=1), all(lm.done for lm in solvers)

    return step


def refine_coefficients(basis, table, coefficients, config=None, trust: float = DEFAULT_TRUST, extra=None,
                        screens: Screens | None = None) -> tuple[np.ndarray, dict]:
    """Refine a table's basis coefficients on renders of the objective scenes (module docstring).

    Parameters
    ----------
    basis
        :class:`~brdfkit.basis.model.PcaBasis`.
    table
        ``(90, 90, 180, 3)`` BRDF in 1/sr, NaN where unmeasured.
    coefficients
        ``(K, 3)`` start, usually ``basis.project(table)``; also the trust term's centre.
    config
        :class:`brdfkit.render.objective.ObjectiveConfig` (its ``steps``: the most
        Levenberg-Marquardt iterations; scenes, pairs, held-out share, seed, resolution).
    trust
        Weight of the trust term (:data:`DEFAULT_TRUST`; 0: the render error alone).
    extra
        ``extra(cells) -> (c -> mapped (U, 3))``: a correction added to the basis's mapped
        values at the cells a render reaches (a residual's, held at one value while the
        coefficients move: :mod:`brdfkit.residual.encoding`); ``None``: the basis alone.
    screens
        :func:`prepare_screens` of the same table, basis and config, when made already.

    Returns
    -------
    coefficients : numpy.ndarray
        float64 ``(K, 3)``, the kept ones (the start when no iteration lowered the
        held-out error).
    record : dict
        :func:`brdfkit.render.objective.refine_loop`'s: ``{"steps", "best_step",
        "stopped", "solver", "heldout"}`` (``steps`` the iterations).
    """
    from brdfkit.render.objective import ObjectiveConfig, refine_loop

    cfg = config or ObjectiveConfig(steps=DEFAULT_ITERATIONS)
    c0 = np.asarray(coefficients, np.float64)
    if cfg.steps == 0:
        return c0, {"steps": 0, "best_step": 0, "stopped": "steps", "solver": SOLVER, "heldout": []}
    screens = (screens or prepare_screens(basis, table, cfg)).with_extra(extra)
    step = solve_channels(screens.fits, screens.fit_targets, c0, trust=trust, cells=basis.cells.size)
    return refine_loop(c0, step, screens.held_error, steps=cfg.steps, check_every=1, patience=cfg.patience,
                       max_seconds=cfg.max_seconds, solver=SOLVER)


def heldout_error(basis, table, coefficients, config=None, extra=None, screens: Screens | None = None) -> float:
    """The render error on the objective scenes' held-out pixels of coefficients ``(K, 3)``
    (with ``extra`` and ``screens`` as :func:`refine_coefficients` takes them): what a
    refinement keeps its result by, and what an encoder may choose between candidates by."""
    screens = (screens or prepare_screens(basis, table, config)).with_extra(extra, fits=False)
    return screens.held_error(np.asarray(coefficients, np.float64))
