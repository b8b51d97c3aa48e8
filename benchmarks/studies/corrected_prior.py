"""A sparse reconstruction through the basis plus a correction: :class:`CorrectedPrior`,
what ``study_sparse_correction.py`` scores (``brdfkit sparse --method residual`` until it
left the product on 2026-12-01, issue 55: ``docs/notes/generalisation.md``, "What left the
product"). It needs a residual network of the learnt prior's ``K`` components trained on
projections (``brdfkit fit --method residual -O sizes=3K``); the networks of sparse fits
(a sample count as an input) left with it.

The learnt prior fits the basis's ``K`` coefficients to the samples in closed form
(:meth:`brdfkit.prior.model.PriorModel.fit`). The correction is a hypernetwork residual of
the basis (:mod:`brdfkit.residual`): for coefficients, it adds to the basis's mapped table
what the basis misses. The coefficients are then fitted again through it
(:func:`fit_through`): the same least squares as the prior's, the samples' weighted error
and the prior's Gaussian term, with the decode being the basis plus the correction.

Whether the correction helps *this* material the samples themselves say: they are dealt
into :data:`HOLDOUT_FOLDS` folds, each fold's samples predicted from the fits to the
others, by the basis alone and by the basis plus the correction, and the correction is
kept only where its held-out error, in the metric's space ``ln(1 + rho cos_i)``, is the
lower (as ``encode`` keeps a residual embedding's correction only where its held-out
renders are better). The dense table is then decoded in NumPy, no torch.

Run from ``benchmarks/studies/`` (a study imports it as ``corrected_prior``).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from brdfkit.errors import InputError

__all__ = ["CorrectedPrior", "HOLDOUT_FOLDS", "THROUGH_STEPS", "SparseFit", "fit_through"]

HOLDOUT_FOLDS = 5
"""Folds of the samples in the held-out choice (fewer when there are fewer samples)."""

THROUGH_STEPS = 5
"""Most Levenberg-Marquardt iterations of a fit through the correction."""


@dataclasses.dataclass(frozen=True)
class SparseFit:
    """A material's fit: its coefficients ``(K, 3)``, whether the correction is kept (the
    coefficients are then those fitted through it), and the held-out errors of the basis
    alone and with the correction (``None`` when too few samples to hold any out, or the
    choice was given)."""

    coefficients: np.ndarray
    corrected: bool
    heldout: tuple | None


@dataclasses.dataclass
class CorrectedPrior:
    """A learnt prior and a residual of its basis.

    Attributes
    ----------
    prior
        :class:`~brdfkit.prior.model.PriorModel`.
    residual
        :class:`~brdfkit.residual.model.BasisResidual` of the prior's basis, with a network
        for its ``K`` components.
    """

    prior: object
    residual: object

    def __post_init__(self):
        k = self.prior.basis.n_components
        if k not in self.residual.components:
            raise InputError(f"the residual has no network for the learnt prior's {k} components ({3 * k} numbers): "
                             f"train it with brdfkit fit --method residual -O sizes={3 * k}")

    def fit(self, samples, *, correction: str = "auto") -> SparseFit:
        """The coefficients of a sample set and whether the correction is kept:
        ``correction`` ``"auto"`` (the held-out choice, module docstring), ``"on"`` or
        ``"off"``."""
        if correction not in ("auto", "on", "off"):
            raise InputError(f"correction={correction!r}: one of auto, on, off")
        pf = self.prior.fit(samples)
        if correction == "off":
            return SparseFit(pf.coefficients, False, None)
        if correction == "on":
            return SparseFit(fit_through(pf, self.residual), True, None)
        errors = self._heldout(samples)
        if errors is None or not errors[1] < errors[0]:
            return SparseFit(pf.coefficients, False, errors)
        return SparseFit(fit_through(pf, self.residual), True, errors)

    def _heldout(self, samples) -> tuple | None:
        """``(basis alone, with the correction)``: the summed squared error, in the
        metric's space, of every usable sample predicted from the fits to the other folds;
        ``None`` below 2 usable samples."""
        from brdfkit.prior.model import sample_rows

        usable = np.flatnonzero(sample_rows(self.prior.basis, samples)[0])
        folds = min(HOLDOUT_FOLDS, usable.size)
        if folds < 2:
            return None
        # A fixed deal: the choice depends on the samples alone.
        order = usable[np.random.default_rng(0).permutation(usable.size)]
        mapping = self.prior.basis.mapping
        err = np.zeros(2)
        for f in range(folds):
            keep = np.ones(len(samples), bool)
            keep[order[f::folds]] = False
            pf = self.prior.fit(samples.subset(keep))
            through = fit_through(pf, self.residual)
            _, tab, w, cos, rho, hd = sample_rows(self.prior.basis, samples.subset(~keep))
            hd = np.ascontiguousarray(hd, np.float32)
            alone = tab[:, 1:2] + tab[:, 2:] @ pf.coefficients
            corrected = tab[:, 1:2] + tab[:, 2:] @ through + self.residual.correction(through, hd, 0)
            for i, mapped in enumerate((alone, corrected)):
                pred = mapping.from_mapped(mapped, w[:, None], tab[:, 0:1])
                err[i] += float(np.sum((np.log1p(pred * cos[:, None]) - np.log1p(rho * cos[:, None])) ** 2))
        return float(err[0]), float(err[1])

    def decode(self, fit: SparseFit) -> np.ndarray:
        """Dense table float64 ``(90, 90, 180, 3)``, 1/sr, NaN off the basis's cells."""
        return self.residual.decode(fit.coefficients, 1.0 if fit.corrected else 0.0)


def fit_through(fit, residual, steps: int = THROUGH_STEPS) -> np.ndarray:
    """Coefficients ``(K, 3)`` of a prior's fit (:class:`~brdfkit.prior.model.PriorFit`)
    fitted again through the correction: Levenberg-Marquardt on the same least squares,
    the samples' weighted error through the basis plus the correction and the prior's
    Gaussian term, each channel its own problem of ``K`` unknowns (the correction's
    derivative by forward mode, :func:`brdfkit.residual.network.evaluate_with_jacobian`),
    at most ``steps`` iterations, never worse than the start."""
    from brdfkit.residual.network import evaluate_with_jacobian

    k = fit.coefficients.shape[0]
    _, cfg, state = residual.net_for(k)
    sigma = residual.basis.sigma[:k].astype(np.float64)
    a = fit.tab[:, 2:]
    out = fit.coefficients.copy()
    for ch in range(3):
        q, b, mu, sd = fit.q[:, ch], fit.b[:, ch], fit.mean[:, ch], fit.sd[:, ch]

        def terms(c):
            f, jf = evaluate_with_jacobian(state, cfg, c / sigma, fit.hd)
            r = b - a @ c - f
            return float(q @ r ** 2 + np.sum(((c - mu) / sd) ** 2)), r, a + jf.astype(np.float64) / sigma

        c = out[:, ch]
        cost, r, j = terms(c)
        damp = 1e-3
        for _ in range(steps):
            h = j.T @ (q[:, None] * j) + np.diag(1.0 / sd ** 2)
            trial = c + np.linalg.solve(h + damp * np.diag(np.diag(h)), j.T @ (q * r) - (c - mu) / sd ** 2)
            new = terms(trial)
            if new[0] < cost:
                c, (cost, r, j), damp = trial, new, damp / 3
            else:
                damp *= 4
        out[:, ch] = c
    return out
