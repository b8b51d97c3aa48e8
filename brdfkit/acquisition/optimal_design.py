"""The render design: measurement directions chosen by the render error they leave.

:mod:`brdfkit.acquisition.planning`'s ``render`` design. Nielsen et al. 2015 choose directions that
keep the basis fit well conditioned; that ignores two things brdfkit is judged by: what
the fit already knows before any sample (the ridge's Gaussian regulariser fitted to the
training coefficients, which :func:`brdfkit.prior.model.solve` and IPCA both use), and which errors
show on screen (a render weighs the BRDF by the light it reflects, the display encoding
by the brightness of the pixel). This design chooses the directions that minimise the
*expected render error* of the fit, a Bayesian (L-optimal) experimental design in the
sense of Chaloner and Verdinelli 1995 ("Bayesian Experimental Design: A Review",
Statistical Science 10(3)).

The model
---------
In the units of the ridge fit (coefficients ``z = c / sigma``, its Gaussian regulariser
``z ~ N(0, I)``), a sample at cell ``i`` with design row ``a_i = components_i * sigma`` (as
:mod:`brdfkit.acquisition.planning` builds it) and precision ``q_i`` leaves the posterior covariance::

    S(N) = (I + sum_{i in N} q_i a_i a_i^T)^-1

``q_i = 1 / lam + g_i^p / s2`` is the precision :func:`~brdfkit.prior.model.solve`
gives the sample (IPCA's likelihood ``lam``; the metric's ``s2``, ``g`` its linearisation,
``p`` 2 for ``weight = "metric"``, 1 for ``"energy"``); for a plain PCA basis (IPCA) it is
``1 / lam`` alone. The render error of the fit is, to first order, ``|J (z_hat - z)|^2``
with ``J`` the Jacobian of the displayed image (exposure, clip, sRGB OETF: what PSNR and
Delta E see, :func:`brdfkit.render.screen.screen_error`) with respect to ``z``; its
expectation is ``trace(J^T J S(N))``. ``J`` and ``g`` depend on the material: they are
averaged over materials drawn from the ridge's Gaussian (``draws`` of them, and the mean
material), i.e. over the spread of the training materials the basis was fitted to.

``J`` comes from :class:`brdfkit.render.screen.Screen`, the 32 px render whose PSNR ranks
reconstructions as the 128 px reference renders do (``docs/notes/render-error.md``), of the
reference scene and of the same scene with the environment turned half a turn
(``scenes``): the plan should not serve one lighting only.

The greedy choice
-----------------
Adding cell ``i`` lowers the expected error by
``q_i (S a_i)^T M (S a_i) / (1 + q_i a_i^T S a_i)`` (``M = J^T J``; Sherman-Morrison), so
each step takes the candidate that lowers it most, then updates ``S`` by rank one; the
products ``A S`` and ``A S M`` over all candidates are updated by rank one too, so a step
costs ``O(P K)`` for ``P`` candidates and ``K`` components. The candidates are those of
:mod:`brdfkit.acquisition.planning` (measurable cells the basis covers). The design is deterministic:
``seed`` only seeds the Gaussian draws.
"""

from __future__ import annotations

import numpy as np

from brdfkit.errors import InputError
from brdfkit.geometry import GRID_SHAPE

__all__ = ["DEFAULT_DRAWS", "Likelihood", "render_metric", "cell_precision", "greedy_render"]

DEFAULT_DRAWS = 16
"""Materials drawn from the ridge's Gaussian to average ``J^T J`` and ``q`` over (besides the
mean material)."""

_SCENES = (0.0, 0.5)  # turns of the reference environment about the vertical


class Likelihood:
    """The sample precision of the fit a plan is for: ``weight`` (``"metric"``,
    ``"energy"`` or ``None`` for IPCA's ridge alone), ``s2`` and ``lam``, as
    :class:`brdfkit.prior.model.PriorConfig` holds them."""

    def __init__(self, weight: str | None = None, s2: float = 1e-2, lam: float = 0.1):
        if weight not in (None, "metric", "energy") or not (s2 > 0 and lam > 0):
            raise InputError(f"invalid likelihood: weight {weight!r}, s2 {s2!r}, lam {lam!r}")
        self.weight, self.s2, self.lam = weight, float(s2), float(lam)

    def __repr__(self) -> str:
        return f"Likelihood(weight={self.weight!r}, s2={self.s2}, lam={self.lam})"


def _gaussian_draws(basis, draws: int, seed: int) -> np.ndarray:
    """Coefficients ``(draws + 1, K)`` of materials drawn from ``N(0, diag(sigma^2))``,
    the first the mean material (all zero)."""
    rng = np.random.default_rng(seed)
    z = rng.standard_normal((draws, basis.n_components))
    return np.vstack([np.zeros((1, basis.n_components)), z]) * basis.sigma.astype(np.float64)[None, :]


def _rho(tab: np.ndarray, w: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """BRDF ``rho`` (1/sr, ``>= 0``) and ``d rho / d mapped`` of coefficients ``c (D, K)``
    at rows ``tab (M, K + 2)`` (``[reference, mean, components]``) with cosine weights
    ``w (M,)``: ``(D, M)`` each (the inverse mapping of :meth:`PcaBasis.decode`)."""
    from brdfkit.basis.mapping import EPS, from_mapped

    ref, mean, comp = tab[:, 0], tab[:, 1], tab[:, 2:]
    m = mean[None, :] + c @ comp.T
    rho = from_mapped(m, w, ref, floor=0.0)  # the criterion's published form
    return rho, np.where(rho > 0, np.exp(m) * (ref + EPS)[None, :] / w, 0.0)


def render_metric(basis, draws: int = DEFAULT_DRAWS, seed: int = 0, scenes=_SCENES,
                  device=None) -> np.ndarray:
    """``M = E[J^T J]`` ``(K, K)`` float64 in the ridge fit's units ``z = c / sigma``: the
    expected squared change of the displayed screen images (module docstring) per unit
    change of ``z``, averaged over the Gaussian draws and summed over the scenes."""
    import torch

    from brdfkit.render.display import display_slope
    from brdfkit.render.screen import rotated_envmap, screen
    from brdfkit.geometry.trilinear import lookup_trilinear

    k = basis.n_components
    sig = basis.sigma.astype(np.float64)
    cs = _gaussian_draws(basis, draws, seed)
    out = np.zeros((k, k))
    for turn in scenes:
        sc = screen(device, env=rotated_envmap(turn) if turn else None)
        th, td, pd = (t.double().cpu().numpy() for t in (sc.theta_h, sc.theta_d, sc.phi_d))
        tab = lookup_trilinear(basis.lookup_table().reshape(GRID_SHAPE + (-1,)), th, td, pd).astype(np.float64)
        w = basis.weight(th, td, pd)
        ok = np.isfinite(tab).all(1) & (w > 0)
        tab, w = tab[ok], w[ok]
        pix = sc.pix.cpu().numpy()[ok]
        rw = sc.rw.double().cpu().numpy()[ok]  # (M, 3)
        comp = torch.from_numpy(tab[:, 2:] * sig[None, :])  # d mapped / d z
        for c in cs:
            rho, drho = _rho(tab, w, c[None, :])
            rho, drho = rho[0], drho[0]
            img = np.zeros((sc.pixels, 3))
            np.add.at(img, pix, rw * rho[:, None])
            slope = display_slope(img)
            for ch in range(3):
                f = torch.from_numpy(rw[:, ch] * drho)[:, None] * comp  # (M, K)
                jac = torch.zeros(sc.pixels, k, dtype=torch.float64).index_add_(0, torch.from_numpy(pix), f)
                jac = jac.numpy() * slope[:, ch:ch + 1]
                out += jac.T @ jac / sc.pixels
    return out / (len(cs) * 3)


def cell_precision(basis, cells: np.ndarray, likelihood: Likelihood, draws: int = DEFAULT_DRAWS,
                   seed: int = 0) -> np.ndarray:
    """The precision ``q (P,)`` of a sample at each of ``cells`` (flat MERL indices the
    basis covers), averaged over the Gaussian draws (module docstring)."""
    from brdfkit.geometry import cell_angles, cos_theta_i
    from brdfkit.basis import EPS

    q = np.full(len(cells), 1.0 / likelihood.lam)
    if likelihood.weight is None:
        return q
    tab = basis.lookup_table()[cells].astype(np.float64)
    th, td, pd = cell_angles(cells)
    w = basis.weight(th, td, pd)
    cos = np.clip(cos_theta_i(th, td, pd), 0.0, None)
    p = 2 if likelihood.weight == "metric" else 1
    acc = np.zeros(len(cells))
    cs = _gaussian_draws(basis, draws, seed)
    for c in cs:
        rho, _ = _rho(tab, w, c[None, :])
        g = cos * (rho[0] + EPS / w) / (1 + rho[0] * cos)
        acc += g ** p
    return q + acc / len(cs) / likelihood.s2


def greedy_render(rows: np.ndarray, q: np.ndarray, metric: np.ndarray, n: int) -> np.ndarray:
    """Positions ``(n,)`` into the candidates, chosen greedily (module docstring).

    Parameters
    ----------
    rows
        ``(P, K)`` design rows ``a_i`` (components times sigma).
    q
        ``(P,)`` sample precisions.
    metric
        ``(K, K)`` ``M = E[J^T J]``.
    n
        Directions to choose, ``<= P``.
    """
    p, k = rows.shape
    if n > p:
        raise InputError(f"{n} directions asked for, but the basis covers only {p} measurable cells")
    a = np.asarray(rows, np.float64)
    m = np.asarray(metric, np.float64)
    s = np.eye(k)
    u = a.copy()       # A S
    v = a @ m          # A S M
    taken = np.zeros(p, bool)
    chosen = []
    for _ in range(n):
        num = q * np.einsum("ij,ij->i", v, u)
        den = 1.0 + q * np.einsum("ij,ij->i", u, a)
        gain = np.where(taken, -np.inf, num / den)
        i = int(np.argmax(gain))
        chosen.append(i)
        taken[i] = True
        si = u[i].copy()                  # S a_i
        scale = q[i] / den[i]
        au = a @ si                       # A S a_i
        msi = m @ si
        s -= scale * np.outer(si, si)
        u -= scale * np.outer(au, si)
        v -= scale * np.outer(au, msi)
    return np.array(chosen, np.int64)
