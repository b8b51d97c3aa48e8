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
each step takes the candidate that lowers it most, then updates ``S`` by rank one; the two
numbers of each candidate the gain needs, ``a_j^T S a_j`` and ``a_j^T S M S a_j``, follow
from ``A S a_i`` and ``A S M S a_i``, so a step costs two passes of ``O(P K)`` for ``P``
candidates and ``K`` components. The candidates are those of
:mod:`brdfkit.acquisition.planning` (measurable cells the basis covers). The design is deterministic:
``seed`` only seeds the Gaussian draws.

Given the samples measured so far, the greedy starts from the posterior after them instead
of ``I``, one a colour channel, and ``J`` and ``q`` are taken at this material's estimate:
:mod:`brdfkit.acquisition.rounds` (``brdfkit plan --given``).
"""

from __future__ import annotations

import weakref

import numpy as np

from brdfkit.errors import InputError

__all__ = ["DEFAULT_DRAWS", "Likelihood", "render_metric", "scene_pairs", "cell_precision", "greedy_render"]

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


def _rho(tab: np.ndarray, w: np.ndarray, c: np.ndarray, mapping) -> tuple[np.ndarray, np.ndarray]:
    """BRDF ``rho`` (1/sr, ``>= 0``) and ``d rho / d mapped`` of coefficients ``c (D, K)``
    at rows ``tab (M, K + 2)`` (``[reference, mean, components]``) with cosine weights
    ``w (M,)``: ``(D, M)`` each (the inverse of the basis's ``mapping``, as
    :meth:`PcaBasis.decode` takes it)."""
    ref, mean, comp = tab[:, 0], tab[:, 1], tab[:, 2:]
    m = mean[None, :] + c @ comp.T
    rho = mapping.from_mapped(m, w, ref, floor=0.0)  # the criterion's published form
    return rho, np.where(rho > 0, mapping.rho_slope(rho, w, ref), 0.0)


def _array(x, dtype):
    """A screen's field as a NumPy array (a torch tensor's values on the CPU)."""
    if type(x).__module__.startswith("torch"):
        x = x.detach().cpu().numpy()
    return np.asarray(x, dtype)


def _basis_at_pairs(basis, th, td, pd):
    """The basis's ``[reference, mean, components]`` at the pairs, trilinearly, as
    :func:`brdfkit.geometry.trilinear.lookup_trilinear` reads its lookup table (the corners
    it does not cover left out, the weights renormalised over the rest), and where some
    corner is covered: ``(tab (M, K + 2) float64, ok (M,))``. The table's rows are
    covered or not as a whole, so the eight weights are worked out once for all ``K + 2``
    channels: a third of the plain lookup's time."""
    from brdfkit.geometry import N_PHI_D, N_THETA_D, N_THETA_H, fractional_indices

    table = basis.lookup_table()
    covered = np.isfinite(table[:, 0])
    spare = int(np.asarray(basis.cells)[0])  # any covered row: read with weight 0
    u_h, u_d, u_p = fractional_indices(th, td, pd)
    i0, j0, k0 = (np.floor(u).astype(np.int64) for u in (u_h, u_d, u_p))
    fh, fd, fp = u_h - i0, u_d - j0, u_p - k0
    i0, j0 = np.clip(i0, 0, N_THETA_H - 1), np.clip(j0, 0, N_THETA_D - 1)
    i1, j1 = np.clip(i0 + 1, 0, N_THETA_H - 1), np.clip(j0 + 1, 0, N_THETA_D - 1)
    k0 = k0 % N_PHI_D
    k1 = (k0 + 1) % N_PHI_D
    corners = []
    for ii, wh in ((i0, 1 - fh), (i1, fh)):
        for jj, wd in ((j0, 1 - fd), (j1, fd)):
            for kk, wp in ((k0, 1 - fp), (k1, fp)):
                cell = kk + N_PHI_D * (jj + N_THETA_D * ii)
                have = covered[cell]
                corners.append((np.where(have, cell, spare), np.where(have, wh * wd * wp, 0.0)))
    wsum = sum(w for _, w in corners)
    ok = wsum > 0
    norm = 1.0 / np.where(ok, wsum, 1.0)
    tab = np.zeros((th.size, table.shape[1]))
    for cell, w in corners:
        tab += (w * norm)[:, None] * table[cell]
    return tab, ok


_METRICS: dict = {}  # (id(basis), draws, seed, scenes, device) -> (weak reference to the basis, M)


def render_metric(basis, draws: int = DEFAULT_DRAWS, seed: int = 0, scenes=_SCENES,
                  device=None) -> np.ndarray:
    """``M = E[J^T J]`` ``(K, K)`` float64 in the ridge fit's units ``z = c / sigma``: the
    expected squared change of the displayed screen images (module docstring) per unit
    change of ``z``, averaged over the Gaussian draws and summed over the scenes. In
    NumPy: the pixels sum their pairs through one sparse matrix a scene. Kept per basis
    object and arguments (a process that plans many times for one basis: the bench's
    planned samplings)."""
    key = (id(basis), int(draws), int(seed), tuple(scenes), str(device))
    hit = _METRICS.get(key)
    if hit is not None and hit[0]() is basis:
        return hit[1].copy()
    out = _render_metric(basis, draws, seed, scenes, device)
    if len(_METRICS) > 64:
        _METRICS.clear()
    _METRICS[key] = (weakref.ref(basis), out)
    return out.copy()


def scene_pairs(basis, turn: float = 0.0, device=None):
    """The screen's pairs a scene's Jacobian reads (:class:`brdfkit.render.screen.Screen`,
    the environment turned by ``turn``), those the basis covers with a weight:
    ``(tab (M, K + 2), w (M,), comp (M, K), to_pixels, pixels)``, ``comp`` the mapped
    value's derivative ``d mapped / d z`` (the components times sigma), ``to_pixels`` a
    sparse ``(pixels, M)`` map a channel summing each pixel's pairs with their radiance
    weights."""
    import scipy.sparse

    from brdfkit.render.screen import rotated_envmap, screen

    sc = screen(device, env=rotated_envmap(turn) if turn else None)
    th, td, pd = (_array(t, np.float64) for t in (sc.theta_h, sc.theta_d, sc.phi_d))
    tab, ok = _basis_at_pairs(basis, th, td, pd)
    w = basis.weight(th, td, pd)
    ok &= w > 0
    tab, w = tab[ok], w[ok]
    pix = _array(sc.pix, np.int64)[ok]
    rw = _array(sc.rw, np.float64)[ok]  # (M, 3)
    comp = tab[:, 2:] * basis.sigma.astype(np.float64)[None, :]
    # pixel p's row of J (channel ch): sum over its pairs m of rw_m drho_m comp_m, times
    # the slope; the pairs' radiance weights go into one sparse map a channel
    to_pixels = [scipy.sparse.csr_matrix((rw[:, ch], (pix, np.arange(pix.size))), shape=(sc.pixels, pix.size))
                 for ch in range(3)]
    return tab, w, comp, to_pixels, sc.pixels


def _render_metric(basis, draws, seed, scenes, device) -> np.ndarray:
    from brdfkit.render.display import display_slope

    k = basis.n_components
    cs = _gaussian_draws(basis, draws, seed)
    out = np.zeros((k, k))
    for turn in scenes:
        tab, w, comp, to_pixels, pixels = scene_pairs(basis, turn, device)
        for c in cs:
            rho, drho = _rho(tab, w, c[None, :], basis.mapping)
            slope = display_slope(np.stack([m @ rho[0] for m in to_pixels], -1))
            dcomp = drho[0][:, None] * comp  # d rho / d z at each pair
            for ch in range(3):
                jac = (to_pixels[ch] @ dcomp) * slope[:, ch:ch + 1]
                out += jac.T @ jac / pixels
    return out / (len(cs) * 3)


def cell_precision(basis, cells: np.ndarray, likelihood: Likelihood, draws: int = DEFAULT_DRAWS,
                   seed: int = 0) -> np.ndarray:
    """The precision ``q (P,)`` of a sample at each of ``cells`` (flat MERL indices the
    basis covers), averaged over the Gaussian draws (module docstring)."""
    from brdfkit.geometry import cell_angles, cos_theta_i

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
        rho, _ = _rho(tab, w, c[None, :], basis.mapping)
        g = cos * basis.mapping.rho_slope(rho[0], w, tab[:, 0]) / (1 + rho[0] * cos)
        acc += g ** p
    return q + acc / len(cs) / likelihood.s2


def greedy_render(rows: np.ndarray, q: np.ndarray, metric: np.ndarray, n: int, start=None) -> np.ndarray:
    """Positions ``(n,)`` into the candidates, chosen greedily (module docstring).

    Parameters
    ----------
    rows
        ``(P, K)`` design rows ``a_i`` (components times sigma).
    q
        ``(P,)`` sample precisions, or ``(C, P)``: one posterior a colour channel, each
        with its own precisions (:mod:`brdfkit.acquisition.rounds`).
    metric
        ``(K, K)`` ``M = E[J^T J]``, or ``(C, K, K)``, one a channel.
    n
        Directions to choose, ``<= P``.
    start
        ``(C, K, K)`` posterior covariances ``S`` to start from (the samples measured so
        far); ``None``: the prior's, ``I``. A step takes the candidate whose gains summed
        over the channels are largest.
    """
    p, k = rows.shape
    if n > p:
        raise InputError(f"{n} directions asked for, but the basis covers only {p} measurable cells")
    a = np.asarray(rows, np.float64)
    qs = np.asarray(q, np.float64).reshape(-1, p)
    ms = np.asarray(metric, np.float64).reshape(-1, k, k)
    channels = max(len(qs), len(ms), 1 if start is None else np.size(start) // (k * k))
    qs, ms = np.broadcast_to(qs, (channels, p)), np.broadcast_to(ms, (channels, k, k))
    # Per candidate j only two numbers of S change the gain: ua_j = a_j S a_j and
    # vu_j = a_j S M S a_j. A rank-one update of S changes each by terms of au = A S a_i
    # and b = A S M S a_i, two passes over the candidates a choice (the rows of A S and
    # A S M kept whole took six, and their outer-product updates most of the time).
    if start is None:  # S = I: the plain products, the bytes of a plan without samples
        ss = [np.eye(k) for _ in qs]
        ua = [np.einsum("ij,ij->i", a, a) for _ in qs]
        vu = [np.einsum("ij,ij->i", a @ m, a) for m in ms]
    else:
        ss = [np.array(s, np.float64) for s in np.broadcast_to(np.reshape(start, (-1, k, k)), (channels, k, k))]
        as_ = [a @ s for s in ss]
        ua = [np.einsum("ij,ij->i", x, a) for x in as_]
        vu = [np.einsum("ij,ij->i", x @ m, x) for x, m in zip(as_, ms)]
    taken = np.zeros(p, bool)
    chosen = []
    for _ in range(n):
        dens = [1.0 + qc * u for qc, u in zip(qs, ua)]
        gain = qs[0] * vu[0] / dens[0]
        for qc, v, d in zip(qs[1:], vu[1:], dens[1:]):
            gain = gain + qc * v / d
        i = int(np.argmax(np.where(taken, -np.inf, gain)))
        chosen.append(i)
        taken[i] = True
        for c, (qc, s, m, den) in enumerate(zip(qs, ss, ms, dens)):
            si = s @ a[i]                     # S a_i
            scale = qc[i] / den[i]
            msi = m @ si
            au = a @ si                       # A S a_i
            b = a @ (s @ msi)                 # A S M S a_i
            vu[c] += scale * au * (scale * au * float(msi @ si) - 2.0 * b)
            ua[c] -= scale * au * au
            s -= scale * np.outer(si, si)
    return np.array(chosen, np.int64)
