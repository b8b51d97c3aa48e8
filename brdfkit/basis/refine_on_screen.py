"""A table's basis coefficients, refined on renders of objective scenes.

:meth:`~brdfkit.basis.model.PcaBasis.project` gives the coefficients that minimise the
squared error of the *mapped* table (``ln`` of the cosine-weighted values). Renders weigh
that error otherwise: a few cells near the specular peak and the grazing rim make most of
an image's light, and the display's tone curve weighs dark pixels more than bright ones.
:func:`refine_coefficients` starts from the projection and lets the ``3 K`` coefficients
descend the render-aligned error of the objective scenes (:mod:`brdfkit.render.objective`:
never a scene the results are judged in), plus a trust term (:data:`DEFAULT_TRUST`) on
how far the mapped table moves from the projection; each step renders a fixed draw of one
scene's pairs, and the coefficients with the lowest render error on held-out pixels are
kept, the projection's own included.

The decode is evaluated only at the cells whose trilinear corners the scenes' pairs
reach, as the renderer's lookup of a decoded table would read them (the same corners,
weights and renormalisation over measured cells, :func:`brdfkit.geometry.trilinear.lookup_trilinear`):
no dense table is decoded during the steps.

The budget is in steps, on :data:`~brdfkit.render.objective.THREADS` torch thread(s): the
same table and basis give the same coefficients to the bit.
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np

from brdfkit.basis.mapping import from_mapped
from brdfkit.geometry import N_CELLS, N_PHI_D, N_THETA_D, N_THETA_H, fractional_indices

__all__ = ["DEFAULT_LR", "DEFAULT_TRUST", "Screens", "prepare_screens", "refine_coefficients", "heldout_error",
           "trilinear_corners"]

DEFAULT_LR = 0.06
"""Adam's learning rate, in units of each component's training standard deviation."""

DEFAULT_TRUST = 0.01
"""Weight of the trust term: the mean squared change of the mapped table over the
basis's cells (``|c - c0|^2 / 3P`` for orthonormal components), added to the render error.
Why: the objective scenes light the sphere little from behind; refined without it, the
coefficients trade the backlit rim for the rest (``docs/compression.md``: -2.5 dB in the
judged ``backlight`` scene for +1.6 dB in the suite mean, 20 training materials); with
it, they move only where renders gain much for a small change of the table."""


def trilinear_corners(theta_h, theta_d, phi_d, measured):
    """The eight corner cells and weights of :func:`brdfkit.geometry.trilinear.lookup_trilinear`
    at angles (radians, ``(m,)`` NumPy), with its renormalisation over measured corners.

    Parameters
    ----------
    theta_h, theta_d, phi_d
        Angles, float32 or float64 ``(m,)``.
    measured
        bool ``(N_CELLS,)``: the cells that hold a value.

    Returns
    -------
    cells : numpy.ndarray
        int64 ``(8, m)`` flat MERL indices.
    weights : numpy.ndarray
        float64 ``(8, m)``, 0 at unmeasured corners, summing to 1 over a point's corners
        (to 0 where none is measured: the lookup's fill of 0).

    Examples
    --------
    >>> import numpy as np
    >>> cells, w = trilinear_corners(np.array([0.3]), np.array([0.4]), np.array([1.0]),
    ...                              np.ones(90 * 90 * 180, bool))
    >>> cells.shape, round(float(w.sum()), 12)
    ((8, 1), 1.0)
    """
    u_h, u_d, u_p = (np.asarray(u, np.float64) for u in fractional_indices(theta_h, theta_d, phi_d))
    i0, j0, k0 = (np.floor(u).astype(np.int64) for u in (u_h, u_d, u_p))
    fh, fd, fp = u_h - i0, u_d - j0, u_p - k0
    i0, j0 = np.clip(i0, 0, N_THETA_H - 1), np.clip(j0, 0, N_THETA_D - 1)
    i1, j1 = np.clip(i0 + 1, 0, N_THETA_H - 1), np.clip(j0 + 1, 0, N_THETA_D - 1)
    k0 = k0 % N_PHI_D
    k1 = (k0 + 1) % N_PHI_D
    cells, weights = [], []
    for ii, wh in ((i0, 1 - fh), (i1, fh)):
        for jj, wd in ((j0, 1 - fd), (j1, fd)):
            for kk, wp in ((k0, 1 - fp), (k1, fp)):
                cells.append(kk + N_PHI_D * (jj + N_THETA_D * ii))
                weights.append(wh * wd * wp)
    cells, weights = np.stack(cells), np.stack(weights)
    weights = np.where(measured[cells], weights, 0.0)
    total = weights.sum(axis=0)
    return cells, weights / np.where(total > 0, total, 1.0)


@dataclasses.dataclass
class _Cells:
    """The basis at the cells some pairs reach (torch float32): mean ``(U,)``,
    components ``(U, K)``, the mapping's weight ``(U,)`` and reference ``(U,)``, and
    ``extra(c) -> (U, 3)``, mapped values added to the basis's (``None``: none; a
    residual's correction, :mod:`brdfkit.residual`)."""

    mean: object
    comp: object
    weight: object
    reference: object
    ids: object = None
    extra: object = None

    def rho(self, c):
        """BRDF ``(U, 3)`` (1/sr) of coefficients ``c`` ``(K, 3)``:
        :meth:`~brdfkit.basis.model.PcaBasis.decode` at these cells."""
        import torch

        mapped = torch.addmm(self.mean[:, None], self.comp, c.to(self.comp.dtype))
        if self.extra is not None:
            mapped = mapped + self.extra(c)
        return from_mapped(mapped, self.weight[:, None], self.reference[:, None])


@dataclasses.dataclass
class _Pairs:
    """Some of a screen's pairs as a linear map from the BRDF at the cells they reach
    to the image: ``cells`` (:class:`_Cells`), ``matrix`` and its transpose, sparse CSR
    ``(3 P, 3 U)`` (channel-major; each pair's corner weights times its radiance,
    quadrature weight and draw factor, summed per pixel and cell), ``pixels`` ``P``."""

    cells: object
    matrix: object
    transposed: object
    pixels: int

    def render(self, c):
        """Image ``(P, 3)`` float32 of coefficients ``c`` (differentiable)."""
        rho = self.cells.rho(c)
        img = _sparse_product().apply(self.matrix, self.transposed, rho.T.reshape(-1, 1))
        return img.reshape(3, self.pixels).T


def _csr_tensor(crow, col, values, shape, dtype):
    """``torch.sparse_csr_tensor`` without its "CSR support is in beta" warning (the
    product is all that is used)."""
    import warnings

    import torch

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        return torch.sparse_csr_tensor(crow, col, values, shape, dtype=dtype)


def _csr(rows, cols, vals, shape):
    """A float32 CSR tensor of COO entries (duplicates summed), built in NumPy: torch's
    own COO product is 25 times slower than a CSR one on a CPU, and CSR has no autograd
    of its transpose (:func:`_sparse_product` takes both)."""
    import torch

    key = rows.astype(np.int64) * shape[1] + cols
    uniq, inv = np.unique(key, return_inverse=True)
    summed = np.bincount(inv.reshape(-1), weights=vals, minlength=uniq.size)
    r, c = uniq // shape[1], uniq % shape[1]
    crow = np.searchsorted(r, np.arange(shape[0] + 1))
    return _csr_tensor(torch.from_numpy(crow), torch.from_numpy(c), torch.from_numpy(summed), shape, torch.float32)


def _transpose(matrix):
    """The CSR tensor of a CSR tensor's transpose (its CSC structure, read as CSR)."""
    csc = matrix.to_sparse_csc()
    return _csr_tensor(csc.ccol_indices(), csc.row_indices(), csc.values(), (matrix.shape[1], matrix.shape[0]),
                       matrix.dtype)


@functools.lru_cache(maxsize=1)
def _sparse_product():
    """The autograd function ``matrix @ x`` with the gradient ``transposed @ g`` (both
    CSR), made on first use (torch is imported only then)."""
    import torch

    class SparseProduct(torch.autograd.Function):
        @staticmethod
        def forward(ctx, matrix, transposed, x):
            ctx.transposed = transposed
            return matrix @ x

        @staticmethod
        def backward(ctx, g):
            return None, None, ctx.transposed @ g

    return SparseProduct


def _prepare(basis, screen, measured, idx, factor) -> _Pairs:
    """:class:`_Pairs` of a screen's pairs ``idx`` (int64 torch ``(m,)``, repeats allowed),
    each weighted by ``factor`` (``(m,)``, or ``None``: 1)."""
    import torch

    i = idx.cpu().numpy()
    th, td, pd = (t.float().cpu().numpy()[i] for t in (screen.theta_h, screen.theta_d, screen.phi_d))
    corners, w = trilinear_corners(th, td, pd, measured)
    used, pos = np.unique(corners.reshape(-1), return_inverse=True)
    row = np.searchsorted(basis.cells, used).clip(0, len(basis.cells) - 1)
    row = np.where(basis.cells[row] == used, row, 0)  # unmeasured corners weigh 0

    weight = basis.cell_weight(used)
    weight = np.where(weight > 0, weight, 1.0)
    # float32 (the basis's own precision): half the time of float64 a step.
    f32 = {"dtype": torch.float32}
    cells = _Cells(torch.tensor(basis.mean[row], **f32), torch.tensor(basis.components[:, row].T, **f32),
                   torch.tensor(weight, **f32), torch.tensor(basis.reference[row], **f32), used)
    rw = screen.rw.double().cpu().numpy()[i]
    if factor is not None:
        rw = rw * factor.double().cpu().numpy()[:, None]
    pix = np.broadcast_to(screen.pix.cpu().numpy()[i], w.shape).reshape(-1)
    pos = pos.reshape(-1)
    n, u = screen.pixels, used.size
    rows = np.concatenate([pix + ch * n for ch in range(3)])
    cols = np.concatenate([pos + ch * u for ch in range(3)])
    vals = np.concatenate([(w * rw[:, ch]).reshape(-1) for ch in range(3)])
    matrix = _csr(rows, cols, vals, (3 * n, 3 * u))
    transposed = _transpose(matrix)
    return _Pairs(cells, matrix, transposed, n)


@dataclasses.dataclass
class Screens:
    """A table's objective views and, for one basis, the linear maps of their fitted and
    held-out pairs (:func:`prepare_screens`): what a refinement and a choice between
    candidates share, made once."""

    views: list
    fits: list
    helds: list
    targets: list

    def with_extra(self, extra) -> "Screens":
        """The same maps, the basis's mapped values at each map's cells corrected by
        ``extra(cells) -> (c -> mapped (U, 3))`` (:func:`refine_coefficients`)."""
        if extra is None:
            return self

        def attach(p):
            return _Pairs(dataclasses.replace(p.cells, extra=extra(p.cells.ids)), p.matrix, p.transposed, p.pixels)

        return Screens(self.views, [attach(p) for p in self.fits], [attach(p) for p in self.helds], self.targets)


def prepare_screens(basis, table, config=None) -> Screens:
    """:class:`Screens` of ``table`` for ``basis`` (its objective views, on
    :data:`~brdfkit.render.objective.THREADS` thread(s))."""
    import torch

    from brdfkit.render.objective import THREADS, ObjectiveConfig, objective_views
    from brdfkit.runtime import torch_threads

    cfg = config or ObjectiveConfig()
    measured = np.zeros(N_CELLS, bool)
    measured[basis.cells] = True
    with torch_threads(THREADS):
        views = objective_views(table, cfg, torch.device("cpu"))
        fits = [_prepare(basis, v.screen, measured, v.idx, v.weight) for v in views]
        helds = [_prepare(basis, v.screen, measured, v.held_pairs, None) for v in views]
    return Screens(views, fits, helds, [v.target.float().cpu() for v in views])


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
        ``(K, 3)`` start, usually ``basis.project(table)``.
    config
        :class:`brdfkit.render.objective.ObjectiveConfig` (steps, scenes, pairs,
        held-out share, seed, resolution; its ``lr`` is read in units of the components'
        training standard deviations, :data:`DEFAULT_LR` when ``None``).
    trust
        Weight of the trust term (:data:`DEFAULT_TRUST`; 0: the render error alone).
    extra
        ``extra(cells) -> (c -> mapped (U, 3))``: a correction added to the basis's mapped
        values at the cells a render reaches, differentiable in the coefficients (a
        residual's, :mod:`brdfkit.residual.encoding`); ``None``: the basis alone.
    screens
        :func:`prepare_screens` of the same table, basis and config, when made already.

    Returns
    -------
    coefficients : numpy.ndarray
        float64 ``(K, 3)``, the kept ones (the start when no step lowered the held-out error).
    record : dict
        ``{"steps", "best_step", "stopped", "heldout": [start, kept]}``.
    """
    from brdfkit.render.objective import THREADS, ObjectiveConfig
    from brdfkit.runtime import torch_threads

    cfg = config or ObjectiveConfig()
    c0 = np.asarray(coefficients, np.float64)
    if cfg.steps == 0:
        return c0, {"steps": 0, "best_step": 0, "stopped": "steps", "heldout": []}
    screens = (screens or prepare_screens(basis, table, cfg)).with_extra(extra)
    with torch_threads(THREADS):
        return _descend(basis, c0, cfg, screens, trust)


def heldout_error(basis, table, coefficients, config=None, extra=None, screens: Screens | None = None) -> float:
    """The render error on the objective scenes' held-out pixels of coefficients ``(K, 3)``
    (with ``extra`` and ``screens`` as :func:`refine_coefficients` takes them): what a
    refinement keeps its result by, and what an encoder may choose between candidates by."""
    import torch

    from brdfkit.render.objective import THREADS
    from brdfkit.runtime import torch_threads

    screens = (screens or prepare_screens(basis, table, config)).with_extra(extra)
    with torch_threads(THREADS):
        return _held_error(screens)(torch.tensor(np.asarray(coefficients, np.float64)))


def _held_error(screens: Screens):
    """``c -> error`` on the views' held-out pixels (full pairs)."""
    import torch

    from brdfkit.render.screen import screen_error

    def held_error(c):
        with torch.no_grad():
            return float(np.mean([float(screen_error(h.render(c), t, v.held_pixels.cpu()))
                                  for v, h, t in zip(screens.views, screens.helds, screens.targets)]))

    return held_error


def _descend(basis, c0, cfg, screens: Screens, trust=0.0):
    """The Adam steps of :func:`refine_coefficients` over the screens' views (one scene a
    step)."""
    import torch

    from brdfkit.render.objective import Adam
    from brdfkit.render.screen import screen_error

    views, fits, targets = screens.views, screens.fits, screens.targets
    sigma = torch.tensor(basis.sigma, dtype=torch.float64)[:, None]
    start = torch.tensor(c0)
    held_error = _held_error(screens)

    z = torch.zeros_like(start, requires_grad=True)
    opt = Adam([z], lr=cfg.learning_rate(DEFAULT_LR))
    best = (held_error(start), 0, start.clone())
    first, step, stopped = best[0], 0, "steps"
    while step < cfg.steps:
        k = step % len(views)
        loss = screen_error(fits[k].render(start + sigma * z), targets[k], views[k].fit_pixels.cpu())
        if trust:
            loss = loss + trust * ((sigma * z) ** 2).sum() / (3 * basis.cells.size)
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        step += 1
        if step % cfg.check_every == 0:
            c = (start + sigma * z).detach()
            err = held_error(c)
            if err < best[0]:
                best = (err, step, c.clone())
            elif step - best[1] >= cfg.patience * cfg.check_every:
                stopped = "converged"
                break
    err, best_step, cb = best
    return cb.numpy(), {"steps": step, "best_step": best_step, "stopped": stopped, "heldout": [first, err]}
