"""A sparse reconstruction through the basis plus the correction (``brdfkit sparse``'s
default): :class:`CorrectedPrior`.

The learnt prior fits the basis's coefficients to the samples in closed form
(:meth:`brdfkit.prior.model.PriorModel.coefficients`); the correction, a hypernetwork
residual trained on such fits (:mod:`brdfkit.prior.correction`), adds to the basis's
mapped table what the coefficients and the sample count say the basis misses. Whether it
does for *this* material the samples themselves say: they are dealt into
:data:`HOLDOUT_FOLDS` folds, each fold's samples predicted from a fit to the others, by
the basis alone and by the basis plus the correction, and the correction is kept only
where its held-out error, in the metric's space ``ln(1 + rho cos_i)``, is the lower (as
``encode`` keeps a residual embedding's correction only where its held-out renders are
better). The dense table is then decoded in NumPy, no torch.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from brdfkit.errors import InputError

__all__ = ["CorrectedPrior", "HOLDOUT_FOLDS", "SparseFit"]

HOLDOUT_FOLDS = 5
"""Folds of the samples in the held-out choice (fewer when there are fewer samples)."""


@dataclasses.dataclass(frozen=True)
class SparseFit:
    """A material's fit: its coefficients ``(K, 3)``, whether the correction is kept, the
    sample count it was fitted from, and the held-out errors of the basis alone and with
    the correction (``None`` when too few samples to hold any out)."""

    coefficients: np.ndarray
    corrected: bool
    count: int
    heldout: tuple | None


@dataclasses.dataclass
class CorrectedPrior:
    """A learnt prior and the correction trained on its fits.

    Attributes
    ----------
    prior
        :class:`~brdfkit.prior.model.PriorModel`.
    residual
        :class:`~brdfkit.residual.model.BasisResidual` whose network for the basis's
        ``K`` components takes the sample count (``ResidualConfig.count``).
    residual_digest
        SHA-256 of the residual file (the decoder an embedding names).
    """

    prior: object
    residual: object
    residual_digest: str = ""

    def __post_init__(self):
        k = self.prior.basis.n_components
        _, cfg, _ = self.residual.net_for(k)
        if not cfg.count:
            raise InputError(f"the residual's network for {3 * k} numbers was not trained on sparse fits "
                             f"(brdfkit fit --method correction)")

    def fit(self, samples, *, correction: str = "auto") -> SparseFit:
        """The coefficients of a sample set and whether the correction is kept:
        ``correction`` ``"auto"`` (the held-out choice, module docstring), ``"on"`` or
        ``"off"``."""
        if correction not in ("auto", "on", "off"):
            raise InputError(f"correction={correction!r}: one of auto, on, off")
        from brdfkit.prior.model import sample_rows

        c = self.prior.coefficients(samples)
        ok = sample_rows(self.prior.basis, samples)[0]
        n = int(ok.sum())
        if correction != "auto":
            return SparseFit(c, correction == "on", n, None)
        errors = self._heldout(samples, ok)
        if errors is None:
            return SparseFit(c, False, n, None)
        return SparseFit(c, bool(errors[1] < errors[0]), n, errors)

    def _heldout(self, samples, ok) -> tuple | None:
        """``(basis alone, with the correction)``: the summed squared error of every
        usable sample predicted from a fit to the other folds; ``None`` below 2 samples."""
        from brdfkit.prior.model import sample_rows

        usable = np.flatnonzero(ok)
        folds = min(HOLDOUT_FOLDS, usable.size)
        if folds < 2:
            return None
        # A fixed deal (the same samples, the same folds): the choice depends on the
        # samples alone.
        order = usable[np.random.default_rng(0).permutation(usable.size)]
        err = np.zeros(2)
        for f in range(folds):
            out = order[f::folds]
            keep = np.ones(len(samples), bool)
            keep[out] = False
            c = self.prior.coefficients(samples.subset(keep))
            _, tab, w, cos, rho, hd = sample_rows(self.prior.basis, samples.subset(~keep))
            base = tab[:, 1:2] + tab[:, 2:] @ c  # (S, 3) mapped
            corr = self.residual.correction(c, np.ascontiguousarray(hd, np.float32), 0, int(keep[usable].sum()))
            for i, mapped in enumerate((base, base + corr)):
                pred = self.prior.basis.mapping.from_mapped(mapped, w[:, None], tab[:, 0:1])
                err[i] += float(np.sum((np.log1p(pred * cos[:, None]) - np.log1p(rho * cos[:, None])) ** 2))
        return float(err[0]), float(err[1])

    def decode(self, fit: SparseFit) -> np.ndarray:
        """Dense table float64 ``(90, 90, 180, 3)``, 1/sr, NaN off the basis's cells."""
        return self.residual.decode(fit.coefficients, 1.0 if fit.corrected else 0.0, fit.count)

    def embedding(self, fit: SparseFit, source: str = ""):
        """The fit as a residual embedding (:class:`~brdfkit.io.embedding.Embedding`, kind
        ``"residual"``, ``3 K`` numbers, ``options`` the correction's gain and the
        sample count)."""
        from brdfkit.io.embedding import Embedding
        from brdfkit.residual.model import gain_options

        options = {**gain_options(0 if fit.corrected else None), "samples": fit.count}
        return Embedding(np.asarray(fit.coefficients, np.float32).reshape(-1), "residual", self.residual_digest,
                         source, fit.count, parts={"basis": self.residual.basis_digest,
                                                   "residual": self.residual_digest}, options=options)
