"""Measuring in rounds: the render design given the samples measured so far.

A lab measures a few directions, looks at the values, and chooses the next few for this
material (``brdfkit plan -n K --given SAMPLES``; ``docs/planning.md`` has the protocol).
The ``render`` design of :mod:`brdfkit.acquisition.optimal_design` chooses the directions
that most lower the expected render error ``trace(J^T J S)`` of the fit; given samples,
it changes in two ways, as a sequential Bayesian design does (Chaloner and Verdinelli
1995, "Bayesian Experimental Design: A Review", Statistical Science 10(3), section 2.3):

1. **The greedy starts from the posterior after the given samples**, not from the prior.
   In the ridge fit's units (``z = c / sigma``), per colour channel ``ch``::

       S_ch = (diag(sigma^2 / sd_ch^2) + sum_s q_s,ch a_s a_s^T)^-1

   with ``a_s`` the design row of given sample ``s`` (the components times sigma at its
   angles, read as the fit reads them), ``q_s,ch`` the precision the fit gives it *at
   its own measured value* and ``sd`` the prior's standard deviations. For a learnt prior
   (:class:`~brdfkit.prior.model.PriorModel`) ``q`` and ``sd`` are its fit's
   (:meth:`~brdfkit.prior.model.PriorModel.fit`): the set encoder reads the prior's mean,
   and with a learnt spread its ``sd``, from the samples, so its posterior depends on
   what was measured, where a fixed Gaussian's would depend only on where. For a plain
   basis (IPCA's ridge) ``q = 1 / lam`` and ``sd = sigma``.
2. **The Jacobian ``J`` and the candidates' precisions ``q`` are linearised at this
   material**: at the fit's estimate ``c_hat`` from the given samples and at ``draws``
   materials drawn from the posterior around it (:func:`posterior_draws`), where the
   plan without samples averages over materials drawn from the prior. The draws share one
   standard normal vector over the three channels (a material's channel errors share the
   directions that were measured).

Each channel has its own posterior, precisions and ``J^T J``; the expected error is their
sum and a greedy step takes the candidate whose gains, summed over the channels, are
largest (:func:`~brdfkit.acquisition.optimal_design.greedy_render` with ``start``). Cells
a given sample falls in are never candidates (``brdfkit plan`` takes them out of the
pool). The expected error reported (:func:`expected_error`) is that sum: the displayed
screen's squared error per pixel and channel (sRGB code values in ``[0, 1]``), summed over
the design's two scenes, to first order and within the basis (the basis's own truncation
error is not in it): what a round is expected to buy, not a render's PSNR.

Examples
--------
>>> from brdfkit.acquisition.planning import plan_target
>>> from brdfkit.acquisition.sampling import draw_samples
>>> from brdfkit.testing.examples import lambertian_table, tiny_basis
>>> target = plan_target(tiny_basis(4))
>>> post = posterior_after(target, draw_samples(lambertian_table(), 6, seed=1))
>>> post.estimate.shape, post.covariance.shape, post.used
((4, 3), (3, 4, 4), 6)
>>> bool((np.linalg.eigvalsh(post.covariance) <= 1 + 1e-9).all())  # the samples only narrow the prior's I
True
"""

from __future__ import annotations

import dataclasses

import numpy as np

from brdfkit.errors import InputError

__all__ = ["Posterior", "posterior_after", "posterior_draws", "channel_precision", "channel_metric",
           "expected_error", "render_given"]


@dataclasses.dataclass
class Posterior:
    """The fit's posterior after the given samples (:func:`posterior_after`).

    Attributes
    ----------
    estimate
        float64 ``(K, 3)``: the fit's coefficients from the samples (the posterior mean).
    covariance
        float64 ``(3, K, K)``: its covariance a channel, in the ridge fit's units ``z = c /
        sigma`` (the prior's is ``I`` for a plain basis).
    rows
        float64 ``(S, K)``: the design rows of the samples the fit used (components times
        sigma at their angles).
    cells
        int64, sorted: the flat MERL cells the given samples fall in (never planned again).
    count, used
        The given samples, and those the fit used (measured, on a cell the basis covers,
        above the horizon).
    source
        Where they came from (a file name), for the plan's description.
    """

    estimate: np.ndarray
    covariance: np.ndarray
    rows: np.ndarray
    cells: np.ndarray
    count: int
    used: int
    source: str = ""


def posterior_after(target, samples) -> Posterior:
    """The posterior of the fit ``target`` after ``samples`` (module docstring, 1.).

    Parameters
    ----------
    target
        What :func:`brdfkit.acquisition.planning.plan_target` returns: the basis, a label,
        the likelihood, and (its ``prior``) the learnt prior, ``None`` for a plain basis.
    samples
        :class:`~brdfkit.io.samples.SampleSet`, BRDF in 1/sr.

    Returns
    -------
    Posterior

    Raises
    ------
    InputError
        No samples, or none the fit can use (the fit's own refusal, naming the samples).
    """
    from brdfkit.geometry import cell_index
    from brdfkit.prior.model import sample_rows

    basis, _, likelihood = target[:3]
    prior = getattr(target, "prior", None)
    if len(samples) == 0:
        raise InputError(f"{samples.source or 'the given samples'}: no samples given")
    if prior is None and likelihood.weight is not None:
        # the likelihood of a learnt prior without the model that reads its prior mean
        raise InputError("planning given samples for a learnt prior needs the model itself, as plan_target gives it")
    sig = basis.sigma.astype(np.float64)
    if prior is not None:
        fit = prior.fit(samples)
        estimate, sd, q = fit.coefficients, fit.sd, fit.q  # q at the samples' own values
        rows = fit.tab[:, 2:] * sig[None, :]
    else:
        estimate = basis.coefficients(samples, likelihood.lam)
        rows = sample_rows(basis, samples)[1][:, 2:] * sig[None, :]  # the samples the ridge fit uses
        sd = np.broadcast_to(sig[:, None], estimate.shape)
        q = np.full((rows.shape[0], 3), 1.0 / likelihood.lam)
    precision = np.stack([np.diag((sig / sd[:, ch]) ** 2) + (rows * q[:, ch:ch + 1]).T @ rows for ch in range(3)])
    cov = np.linalg.inv(precision)
    cov = 0.5 * (cov + np.swapaxes(cov, 1, 2))  # symmetric to the last bit: Cholesky, the greedy's updates
    cells = np.unique(cell_index(samples.theta_h, samples.theta_d, samples.phi_d))
    return Posterior(np.asarray(estimate, np.float64), cov, rows, cells, len(samples), int(rows.shape[0]),
                     samples.source)


def posterior_draws(basis, post: Posterior, draws: int, seed: int = 0) -> np.ndarray:
    """Coefficients ``(draws + 1, K, 3)`` float64: the estimate, then ``draws`` materials
    drawn from the posterior around it, one standard normal vector a draw for the three
    channels (module docstring, 2.); seeded by ``seed``."""
    k = basis.n_components
    sig = basis.sigma.astype(np.float64)
    e = np.random.default_rng(seed).standard_normal((int(draws), k))
    root = np.linalg.cholesky(post.covariance)  # (3, K, K)
    z = post.estimate[None] / sig[None, :, None] + np.einsum("ckj,dj->dkc", root, e)
    return np.concatenate([post.estimate[None], z * sig[None, :, None]])


def channel_precision(basis, cells: np.ndarray, likelihood, cs: np.ndarray) -> np.ndarray:
    """The precision ``q (3, P)`` of a sample at each of ``cells`` (flat MERL indices the
    basis covers), a channel, averaged over the materials ``cs (D, K, 3)``: what
    :func:`~brdfkit.acquisition.optimal_design.cell_precision` gives a grey material, for
    each channel of these."""
    from brdfkit.acquisition.optimal_design import _rho
    from brdfkit.geometry import cell_angles, cos_theta_i

    q = np.full((3, len(cells)), 1.0 / likelihood.lam)
    if likelihood.weight is None:
        return q
    tab = basis.lookup_table()[cells].astype(np.float64)
    th, td, pd = cell_angles(cells)
    w = basis.weight(th, td, pd)
    cos = np.clip(cos_theta_i(th, td, pd), 0.0, None)
    p = 2 if likelihood.weight == "metric" else 1
    acc = np.zeros_like(q)
    for c in cs:
        rho, _ = _rho(tab, w, c.T, basis.mapping)  # (3, P)
        g = cos * basis.mapping.rho_slope(rho, w, tab[:, 0]) / (1 + rho * cos)
        acc += g ** p
    return q + acc / len(cs) / likelihood.s2


def channel_metric(basis, cs: np.ndarray, scenes=None, device=None) -> np.ndarray:
    """``M_ch = E[J_ch^T J_ch]`` ``(3, K, K)`` float64 in the units ``z = c / sigma``:
    :func:`~brdfkit.acquisition.optimal_design.render_metric` a channel, averaged over the
    materials ``cs (D, K, 3)`` (channel by channel, so that their sum is the grey metric's
    sum when the channels are equal) and summed over the ``scenes`` (turns of the
    environment; ``None``: the design's)."""
    from brdfkit.acquisition.optimal_design import _SCENES, _rho, scene_pairs
    from brdfkit.render.display import display_slope

    k = basis.n_components
    out = np.zeros((3, k, k))
    for turn in _SCENES if scenes is None else scenes:
        tab, w, comp, to_pixels, pixels = scene_pairs(basis, turn, device)
        for c in cs:
            rho, drho = _rho(tab, w, c.T, basis.mapping)  # (3, M) each
            slope = display_slope(np.stack([m @ rho[ch] for ch, m in enumerate(to_pixels)], -1))
            for ch, m in enumerate(to_pixels):
                # The pairs' d rho / d mapped scale the map's columns (one pair a column):
                # the sparse product then gives J_ch without an (M, K) product a channel.
                scaled = m.copy()
                scaled.data *= drho[ch][scaled.indices]
                jac = (scaled @ comp) * slope[:, ch:ch + 1]
                out[ch] += jac.T @ jac / pixels
    return out / (len(cs) * 3)


def expected_error(rows: np.ndarray, q: np.ndarray, metric: np.ndarray, covariance: np.ndarray,
                   chosen=()) -> float:
    """``sum_ch trace(M_ch S_ch)`` after adding the candidates at positions ``chosen`` to
    the posterior ``covariance (3, K, K)``: rows ``(P, K)``, precisions ``q (3, P)``,
    metric ``(3, K, K)`` (module docstring)."""
    chosen = np.asarray(chosen, np.int64)
    a = np.asarray(rows, np.float64)[chosen]
    total = 0.0
    for m, s, qc in zip(metric, covariance, np.asarray(q, np.float64)):
        prec = np.linalg.inv(s) + (a * qc[chosen, None]).T @ a
        total += float(np.trace(m @ np.linalg.inv(prec)))
    return total


def render_given(pool, n: int, seed: int, post: Posterior, draws: int, candidates: int):
    """The ``render`` design given samples: ``n`` cells of ``pool`` (a
    :class:`~brdfkit.acquisition.designs.CandidatePool` without the given cells), chosen
    greedily from the posterior ``post`` among ``candidates`` cells drawn by ``seed``.

    Returns
    -------
    tuple
        ``(cells (n,) int64, (before, after))``: the expected errors
        (:func:`expected_error`) after the given samples, and after these too.
    """
    from brdfkit.acquisition.optimal_design import greedy_render

    p = pool.cells.size
    if n > p:
        raise InputError(f"{n} directions asked for, but only {p} measurable cells the basis covers are not "
                         f"measured yet")
    pick = np.sort(np.random.default_rng(seed).choice(p, size=min(p, max(int(candidates), n)), replace=False))
    cells = pool.cells[pick]
    cs = posterior_draws(pool.basis, post, draws, seed)
    q = channel_precision(pool.basis, cells, pool.likelihood, cs)
    metric = channel_metric(pool.basis, cs)
    rows = pool.rows[pick]
    chosen = greedy_render(rows, q, metric, n, start=post.covariance)
    errors = tuple(expected_error(rows, q, metric, post.covariance, c) for c in ((), chosen))
    return cells[chosen], errors
