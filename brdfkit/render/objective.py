"""The objective of a refinement on renders: the scenes it descends, their small renders,
the pairs each step renders, the held-out pixels, and the budget.

Two refinements start from a closed-form or encoder estimate of a dense table and let a
few numbers descend the render-aligned error (:mod:`brdfkit.render.screen`): a
hypernetwork latent (:mod:`brdfkit.hypernet.refine_on_screen`) and a basis embedding's
coefficients (:mod:`brdfkit.basis.refine_on_screen`). What they descend is the same, and
lives here:

1. The table is rendered in low-resolution *objective* scenes of the suite
   (:data:`OBJECTIVE`, :mod:`brdfkit.render.scene_suite`): never a scene the results are
   judged in.
2. A ``holdout`` share of each scene's pixels is never fitted; the refiners keep the
   numbers whose error on those pixels (full pairs) is lowest, the start's own included.
3. Each step renders the fitted pixels from a fixed draw of their pairs
   (:func:`draw_pairs`: ``pairs_per_pixel`` per pixel, in proportion to the table's own
   integrand, mixed with a uniform share, weighted for an unbiased estimate of the full
   render).
4. The budget is counted in steps, never in seconds (:class:`ObjectiveConfig`), and a
   refinement runs on :data:`THREADS` torch thread(s) whatever the caller's setting: the
   same table and model give the same numbers to the bit, however loaded the machine is.

``docs/notes/render-error.md`` measures how the error ranks reconstructions as the judged
scenes' renders do.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from brdfkit.errors import InputError, require_counts

__all__ = ["OBJECTIVE", "THREADS", "ObjectiveConfig", "ObjectiveView", "draw_pairs", "objective_views", "refine_loop",
           "Adam"]

OBJECTIVE = ("studio-0", "studio-1", "studio-2", "studio-3")
"""The scenes a refinement descends: four of the suite's objective scenes, none of them
judged. Chosen by ``benchmarks/studies/study_error.py --judges suite``
(``docs/notes/render-error.md``): over 10 test materials and 120 reconstructions, their
render-aligned error ranks reconstructions as the five held-out scenes' mean does with
Spearman 0.966 (PSNR) / 0.959 (Delta E), the reference scene's own 0.930 / 0.908, the
BRDF log RMSE 0.647 / 0.638."""

THREADS = 1
"""Threads of a refinement's arithmetic (torch's for a latent, NumPy's BLAS for a basis or
residual embedding, :func:`brdfkit.runtime.blas_threads`), fixed so that its result does
not depend on the thread count a loaded machine would pick (two threads and one give
other bits in the reductions)."""


@dataclasses.dataclass(frozen=True)
class ObjectiveConfig:
    """Settings of a refinement on renders.

    Attributes
    ----------
    steps
        Most steps (0: the start alone): Adam steps on a latent, Levenberg-Marquardt iterations
        on a basis or residual embedding's coefficients; fewer when the held-out error
        stops improving (``patience``).
    max_seconds
        A wall-clock cap on the steps, or ``None`` (the default: none). A run it cuts
        depends on the machine's speed and load; the result says so.
    lr
        Adam's learning rate on a latent, or ``None``: its refiner's default
        (:data:`brdfkit.hypernet.refine_on_screen.DEFAULT_LR`). The Levenberg-Marquardt
        refinement of a basis or residual embedding has none, and does not read it.
    pairs_per_pixel
        Pairs drawn per pixel for the fitted render (the full render has about 280).
    uniform_share
        Share of the draw that is uniform over a pixel's pairs rather than in proportion
        to the table's integrand (keeps pairs where the table is dark but a model may not be).
    holdout
        Share of the pixels held out to choose the result, in ``(0, 1)``.
    check_every, patience
        Steps between held-out checks (Levenberg-Marquardt checks after every iteration, and
        does not read ``check_every``); checks without a gain before stopping.
    seed
        Draws the pairs and the held-out pixels.
    resolution
        Side in pixels of the render (:data:`brdfkit.render.screen.SCREEN_RESOLUTION`).
    scenes
        The scenes descended (:data:`OBJECTIVE`): objective scenes of the suite, never a
        judged one.
    """

    steps: int = 40
    max_seconds: float | None = None
    lr: float | None = None
    pairs_per_pixel: int = 48
    uniform_share: float = 0.25
    holdout: float = 0.2
    check_every: int = 5
    patience: int = 6
    seed: int = 0
    resolution: int = 32
    scenes: tuple = OBJECTIVE

    def __post_init__(self):
        if not (isinstance(self.steps, int) and not isinstance(self.steps, bool) and self.steps >= 0):
            raise InputError(f"refinement steps must be a whole number >= 0, got {self.steps!r}")
        if self.max_seconds is not None and not (self.max_seconds > 0.0 and np.isfinite(self.max_seconds)):
            raise InputError(f"max_seconds must be a finite number of seconds > 0, got {self.max_seconds!r}")
        if self.lr is not None and not (self.lr > 0.0 and np.isfinite(self.lr)):
            raise InputError(f"learning rate must be a finite number > 0, got {self.lr!r}")
        if not 0.0 < self.holdout < 1.0:
            raise InputError(f"holdout must be in (0, 1), got {self.holdout!r}")
        if not 0.0 <= self.uniform_share <= 1.0:
            raise InputError(f"uniform_share must be in [0, 1], got {self.uniform_share!r}")
        require_counts(self, ("pairs_per_pixel", "check_every", "patience", "resolution"))
        from brdfkit.render.scene_suite import require_objective

        require_objective(self.scenes, "refinement scenes")

    def learning_rate(self, default: float) -> float:
        """:attr:`lr`, or the refiner's ``default`` when it is ``None``."""
        return default if self.lr is None else float(self.lr)


def draw_pairs(screen, target, cfg, fit_pixels, device=None):
    """A fixed draw of a screen's pairs, for renders that estimate the full one.

    In each of ``fit_pixels``, ``K = cfg.pairs_per_pixel`` of the pixel's ``n`` pairs
    are drawn with replacement, pair ``k`` with probability
    ``p_k = (1 - u) c_k / sum c + u / n`` (``u = cfg.uniform_share``; ``c_k`` the table's
    integrand at the pair, ``target * screen.rw`` summed over the channels; uniform when
    the pixel's integrand is zero) and weighted ``1 / (K p_k)``, so that a render from
    these pairs is an unbiased estimate of the full render, exact for the table itself.
    Pixels without pairs are skipped. The draw is ``rng.choice``'s (inverse CDF of one
    uniform number a pair, the pixels in order), made for all pixels at once.

    Parameters
    ----------
    screen
        :class:`brdfkit.render.screen.Screen` with ``M`` pairs and ``P`` pixels.
    target
        The table at the pairs (:meth:`brdfkit.render.screen.Screen.lookup`), float64
        ``(M, 3)``, 1/sr.
    cfg
        :class:`ObjectiveConfig`: ``seed`` (of a NumPy generator), ``pairs_per_pixel``
        and ``uniform_share``.
    fit_pixels
        Integer array of the pixels to draw in, each in ``[0, P)``, in the draw's order.
    device
        ``None``: NumPy results; else a torch device to put them on (the hypernetwork's
        tuning).

    Returns
    -------
    idx
        int64 ``(K * F,)`` pair indices in ``[0, M)``, ``K`` per pixel with pairs, pixel
        after pixel (``F`` such pixels).
    weight
        float32 ``(K * F,)`` the pairs' ``1 / (K p_k)``.
    """
    rng = np.random.default_rng(cfg.seed)
    pix = np.asarray(screen.pix)
    c = np.clip((np.asarray(target, np.float64) * np.asarray(screen.rw, np.float64)).sum(1), 0, None)
    order = np.argsort(pix, kind="stable")
    starts = np.searchsorted(pix[order], np.arange(screen.pixels + 1))
    fit = np.asarray(fit_pixels, np.int64)
    fit = fit[starts[fit + 1] > starts[fit]]
    n = starts[fit + 1] - starts[fit]
    members = order[np.concatenate([np.arange(starts[p], starts[p + 1]) for p in fit])] if fit.size else order[:0]
    seg = np.repeat(np.arange(fit.size), n)
    cm = c[members]
    tot = np.bincount(seg, cm, minlength=fit.size)
    uniform = 1.0 / n[seg]
    prob = np.where(tot[seg] > 0, (1 - cfg.uniform_share) * cm / np.where(tot > 0, tot, 1.0)[seg]
                    + cfg.uniform_share * uniform, uniform)
    cdf = np.cumsum(prob)
    first = np.concatenate([[0], np.cumsum(n)[:-1]])
    base = np.concatenate([[0.0], cdf])[first]  # the cumulated probability before each pixel
    cdf -= base[seg]
    cdf /= cdf[first + n - 1][seg]  # each pixel's CDF ends at 1, as rng.choice makes it
    cdf += seg
    k = cfg.pairs_per_pixel
    u = rng.random((fit.size, k)) + np.arange(fit.size)[:, None]
    lo = np.repeat(first, k)
    pick = np.clip(np.searchsorted(cdf, u.reshape(-1), side="right"), lo, lo + np.repeat(n, k) - 1)
    idx, wts = members[pick], 1.0 / (k * prob[pick])
    if device is None:
        return idx, wts.astype(np.float32)
    import torch

    return torch.from_numpy(idx).to(device), torch.from_numpy(wts.astype(np.float32)).to(device)


@dataclasses.dataclass
class ObjectiveView:
    """One objective scene's small render of the table (NumPy).

    Attributes
    ----------
    screen
        :class:`brdfkit.render.screen.Screen` of the scene.
    idx, weight
        The fitted pixels' pair draw (:func:`draw_pairs`).
    fit_pixels, held_pixels
        int64 pixel indices fitted and held out.
    held_pairs
        int64 indices of the held-out pixels' pairs (all of them).
    target
        float64 ``(P, 3)``, the table's render.
    at_pairs
        float64 ``(M, 3)``, the table at the screen's pairs.
    """

    screen: object
    idx: np.ndarray
    weight: np.ndarray
    fit_pixels: np.ndarray
    held_pixels: np.ndarray
    held_pairs: np.ndarray
    target: np.ndarray
    at_pairs: np.ndarray | None = None

    def tensors(self, device=None) -> dict:
        """Its arrays as torch tensors on ``device`` (a hyponet's refinement): ``idx``,
        ``weight``, ``fit_pixels``, ``held_pixels``, ``held_pairs``, ``target`` (float32)."""
        import torch

        to = lambda a: torch.from_numpy(np.ascontiguousarray(a)).to(device or "cpu")  # noqa: E731
        return {"idx": to(self.idx), "weight": to(self.weight), "fit_pixels": to(self.fit_pixels),
                "held_pixels": to(self.held_pixels), "held_pairs": to(self.held_pairs),
                "target": to(self.target.astype(np.float32))}


def objective_views(table, cfg: ObjectiveConfig, device=None) -> list[ObjectiveView]:
    """The :class:`ObjectiveView` of every scene of ``cfg.scenes``, each with its own
    held-out pixels and pair draw (seeded by ``cfg.seed``).

    Parameters
    ----------
    table
        ``(90, 90, 180, 3)`` BRDF in 1/sr, NaN where unmeasured.
    cfg
        :class:`ObjectiveConfig`.
    device
        Ignored (NumPy); kept for callers that pass one.
    """
    from brdfkit.render.lookup import TableRows
    from brdfkit.render.scene_suite import scene_env
    from brdfkit.render.screen import screen
    from brdfkit.runtime import thread_map

    rows = TableRows(table)

    def looked_up(name):  # a scene's pairs and the table's render there: a fixed piece of work
        sc = screen(None, cfg.resolution, env=scene_env(name))
        at_pairs = sc.lookup(rows)
        return sc, at_pairs, sc.render_table(rows, at_pairs)

    rng = np.random.default_rng(cfg.seed)  # the draws in the scenes' order, whatever the threads
    views = []
    for sc, at_pairs, target in thread_map(looked_up, list(cfg.scenes)):
        perm = rng.permutation(sc.pixels)
        n_held = max(1, int(round(cfg.holdout * sc.pixels)))
        held = np.sort(perm[:n_held])
        fit = np.sort(perm[n_held:])
        idx, wts = draw_pairs(sc, at_pairs, cfg, fit)
        held_pairs = np.flatnonzero(np.isin(sc.pix, held))
        views.append(ObjectiveView(sc, idx, wts, fit, held, held_pairs, target, at_pairs))
    return views


def refine_loop(start, step, held_error, *, steps: int, check_every: int = 1, patience: int = 2,
                max_seconds: float | None = None, solver: str = "", snapshot=None):
    """The refine-with-a-held-out-check loop that every refinement on renders runs: the
    basis's and the residual's Levenberg-Marquardt iterations
    (:mod:`brdfkit.basis.refine_on_screen`), the hypernetwork latent's Adam steps
    (:mod:`brdfkit.hypernet.refine_on_screen`).

    Every ``check_every`` steps the held-out error of the iterate is measured, and the
    iterate with the lowest is kept, the start's own included: a refinement is never
    worse than its start on the held-out pixels. It stops after ``steps`` steps, when
    ``patience`` checks in a row bring no gain (``"converged"``), when the solver says it
    can go no further (``"converged"``), or, only when asked, after ``max_seconds`` of
    wall-clock time (``"max_seconds"``: the one way a result depends on the machine).

    Parameters
    ----------
    start
        The starting parameters.
    step
        ``step(x, k) -> (x, done)``: solver step ``k`` (from 1) from ``x``; ``done`` when
        it cannot improve the fitted objective any more.
    held_error
        ``held_error(x) -> float``.
    steps, check_every, patience, max_seconds
        The budget, in steps (module docstring).
    solver
        Its name, for the record.
    snapshot
        ``snapshot(x) -> copy`` of an iterate that ``step`` may change in place (default:
        the iterate itself).

    Returns
    -------
    best
        The kept parameters.
    record : dict
        ``{"steps", "best_step", "stopped", "solver", "heldout"}``: the steps taken, the
        one kept (0: the start), why it stopped, the solver, and the held-out errors of
        the start and of every check.

    Examples
    --------
    >>> best, rec = refine_loop(4.0, lambda x, k: (x / 2, False), lambda x: abs(x - 1.1), steps=5)
    >>> best, rec["best_step"], rec["stopped"], len(rec["heldout"])
    (1.0, 2, 'converged', 5)
    """
    import time

    keep = snapshot or (lambda x: x)
    x, first = start, float(held_error(start))
    best, best_step, best_err = keep(start), 0, first
    errors, k, stopped, t0 = [first], 0, "steps", time.perf_counter()
    while k < steps:
        if max_seconds is not None and time.perf_counter() - t0 >= max_seconds:
            stopped = "max_seconds"
            break
        x, done = step(x, k + 1)
        k += 1
        if k % check_every == 0 or done or k == steps:
            err = float(held_error(x))
            errors.append(err)
            if err < best_err:
                best, best_step, best_err = keep(x), k, err
            elif k - best_step >= patience * check_every:
                stopped = "converged"
                break
        if done:
            stopped = "converged"
            break
    return best, {"steps": k, "best_step": best_step, "stopped": stopped, "solver": solver, "heldout": errors}


class Adam:
    """Adam (Kingma and Ba 2015) over a few tensors, the refinements' optimiser.

    Written out because ``torch.optim.Adam``'s constructor imports ``torch._dynamo``: 2 s
    of a 5 s ``brdfkit encode`` on an idle 2-core machine, for an update of 39 numbers.
    The update is torch's (defaults ``betas = (0.9, 0.999)``, ``eps = 1e-8``, no weight
    decay): ``p -= lr / (1 - b1^t) m / (sqrt(v) / sqrt(1 - b2^t) + eps)``.

    Examples
    --------
    >>> import torch
    >>> z = torch.zeros(2, requires_grad=True)
    >>> opt = Adam([z], lr=0.1)
    >>> ((z - 1) ** 2).sum().backward(); opt.step()
    >>> [round(float(x), 6) for x in z]
    [0.1, 0.1]
    """

    def __init__(self, params, lr: float, betas=(0.9, 0.999), eps: float = 1e-8):
        import torch

        self.params = list(params)
        self.lr, (self.b1, self.b2), self.eps, self.t = float(lr), betas, float(eps), 0
        self.m = [torch.zeros_like(p) for p in self.params]
        self.v = [torch.zeros_like(p) for p in self.params]

    def zero_grad(self, set_to_none: bool = True) -> None:
        for p in self.params:
            p.grad = None

    def step(self) -> None:
        import torch

        self.t += 1
        c1, c2 = 1 - self.b1 ** self.t, (1 - self.b2 ** self.t) ** 0.5
        with torch.no_grad():
            for p, m, v in zip(self.params, self.m, self.v):
                if p.grad is None:
                    continue
                m.mul_(self.b1).add_(p.grad, alpha=1 - self.b1)
                v.mul_(self.b2).addcmul_(p.grad, p.grad, value=1 - self.b2)
                p.addcdiv_(m, (v.sqrt() / c2).add_(self.eps), value=-self.lr / c1)
