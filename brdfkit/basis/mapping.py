"""The basis's log mapping and its inverse: the one place every user of a basis maps BRDF
values (the basis, its fit, its refinement on renders, the learnt prior, the residual).

Nielsen et al. 2015 (``MapBRDF`` of brdf.compute.dtu.dk) map a cosine-weighted value::

    x  = rho * w,                      w = cos(theta_i) cos(theta_o) (or its floor)
    x' = ln((x + eps) / (x_ref + eps)),   eps = EPS = 0.001

with ``x_ref`` the per-cell median of the training set's weighted values.

Grazing cells (:class:`LogMapping`)
-----------------------------------
Where ``x_ref`` is far below ``eps`` (the rows of ``theta_h`` above about 80 deg, where
``w`` is small), Nielsen's ``eps`` swamps every value: a material ten times darker or
brighter than the median maps to nearly the same ``x'``, so the basis, the residual, the
prior and the refinement have nothing to fit there, and a decoded table was 0.1 to 10
times the material along those rows (``docs/notes/compression.md``, "Grazing rows"). A
mapping with a resolution *share* ``kappa`` resolves values down to that share of the
reference instead, and keeps Nielsen's slope at the reference, so that the basis's fit
spends the same budget on those cells as before::

    e  = clip(x_ref^2 / eps, kappa x_ref, eps)       (the resolution)
    s  = (x_ref + e) / (x_ref + eps)                 (the scale: the slope at x_ref kept)
    x' = s ln((x + e) / (x_ref + e))

Wherever ``x_ref >= eps`` this is Nielsen's mapping exactly (``e = eps``, ``s = 1``);
below, the share ``e / x_ref`` falls smoothly from 1 to ``kappa``. ``kappa = 0`` is
Nielsen's mapping everywhere (:data:`NIELSEN`; every basis file written before the share
existed). ``docs/notes/compression.md`` measures the choice of ``kappa`` on renders and on
the grazing rows.

The inverse's lower bound
-------------------------
The exact inverse ``x = expm1(x'/s) (x_ref + e) + x_ref`` is negative where a decoder's
small error of ``x'`` crosses the mapped value of 0, and clamping it gave exact zeros where
the material is not black. :meth:`LogMapping.from_mapped` bounds it below by a small share
:data:`FLOOR` of the reference (at most :data:`CAP`; Nielsen's mapping adds a small
absolute part where it cannot resolve the values, which vanishes at the horizon): of the
right order where the median is, far below every value a render sees, and where the exact
inverse is above the bound it is returned as it is, so a true value maps and comes back
exactly.

The functions take NumPy arrays (float64 results) or torch tensors (their own dtype,
differentiable). The module-level functions are Nielsen's mapping (:data:`NIELSEN`).
"""

from __future__ import annotations

import dataclasses

import numpy as np

__all__ = ["EPS", "FLOOR", "CAP", "SHARE_FLOOR", "E_MIN", "Z_MAX", "LogMapping", "NIELSEN", "to_mapped", "from_mapped", "lower_bound"]

EPS = 0.001
"""Nielsen et al.'s ``eps`` of the weighted values."""

FLOOR = 0.001
"""The decoded value's lower bound as a share of the reference (module docstring)."""

CAP = 0.005 * EPS
"""The largest lower bound, in weighted units: far below what the mapping resolves, so
that a true value is decoded exactly wherever it is above it (under a bright reference
too)."""

_TINY = 3e-3 * EPS  # weighted: where the median is dark, what Nielsen's mapping cannot resolve
_W_TINY = 0.005  # below this weight the absolute part shrinks with it: a basis without a
# floor of w (Nielsen's) has cells of w ~ 1e-6 at the horizon, where _TINY / w would be vast
E_MIN = 1e-12
"""The least resolution ``e`` and the absolute part of a share's lower bound, weighted: above
0 where a reference is 0 (no training value there)."""
SHARE_FLOOR = 0.005
"""A mapping with a share bounds its decode below by this share of the reference
(:meth:`LogMapping.lower_bound`)."""
Z_MAX = 20.0
"""The largest ``x' / s`` a mapping with a share inverts (``x < e^20 (x_ref + e)``): where
``s`` is small a decoder's error of ``x'`` is divided by it, and nothing may overflow."""


def _is_torch(x) -> bool:
    return type(x).__module__.startswith("torch")


def _maximum(x, bound):
    """``max(x, bound)``, NaN kept (unmeasured cells)."""
    if _is_torch(x):
        import torch

        return torch.maximum(x, torch.as_tensor(bound, dtype=x.dtype, device=x.device))
    return np.maximum(x, bound)


@dataclasses.dataclass(frozen=True)
class LogMapping:
    """A log mapping of cosine-weighted BRDF values against a per-cell reference (module
    docstring).

    Attributes
    ----------
    share
        ``kappa``: the share of the reference down to which the mapping resolves values
        where the reference is below ``eps``; 0 (the default) is Nielsen's mapping.

    Examples
    --------
    >>> import numpy as np
    >>> m = LogMapping(0.1)
    >>> float(m.to_mapped(np.array(0.5), 0.5, 0.25))   # x_ref >= eps: Nielsen's mapping
    0.0
    >>> x_ref = 1e-5   # a grazing cell: 10 and 100 times darker than the reference
    >>> [round(float(m.to_mapped(np.array(f * x_ref), 1.0, x_ref)), 4) for f in (0.1, 0.01)]
    [-0.0186, -0.0251]
    >>> [round(float(NIELSEN.to_mapped(np.array(f * x_ref), 1.0, x_ref)), 4) for f in (0.1, 0.01)]
    [-0.009, -0.0099]
    >>> round(float(m.from_mapped(m.to_mapped(np.array(0.1 * x_ref), 1.0, x_ref), 1.0, x_ref) / x_ref), 9)
    0.1
    """

    share: float = 0.0

    def __post_init__(self):
        if not (isinstance(self.share, (int, float)) and not isinstance(self.share, bool)
                and 0.0 <= self.share < 1.0):
            raise ValueError(f"a mapping's resolution share must be in [0, 1), got {self.share!r}")

    def record(self) -> dict:
        """What a basis file records of it: ``{}`` for Nielsen's mapping (files from before
        the share are written again as they were), else ``{"eps_share": "kappa"}``."""
        return {"eps_share": repr(float(self.share))} if self.share else {}

    @classmethod
    def from_record(cls, meta: dict) -> "LogMapping":
        """The mapping a basis file's metadata names (:meth:`record`); ``ValueError`` if
        it is not a share in ``[0, 1)``."""
        text = meta.get("eps_share")
        if text is None:
            return NIELSEN
        try:
            share = float(text)
        except (TypeError, ValueError):
            raise ValueError(f"eps_share {text!r} is not a number") from None
        return cls(share)

    def resolution(self, reference):
        """``(e, s)``: the resolution and the scale at weighted references ``x_ref``
        (module docstring), float64 NumPy or in the reference's torch dtype."""
        if not self.share:
            return EPS, 1.0
        if _is_torch(reference):
            e = (reference * (reference / EPS).clamp(min=self.share)).clamp(min=E_MIN, max=EPS)
        else:
            reference = np.asarray(reference, np.float64)
            e = np.clip(reference * np.maximum(reference / EPS, self.share), E_MIN, EPS)
        return e, (reference + e) / (reference + EPS)

    def to_mapped(self, rho, weight, reference, out=None):
        """Mapped values ``s ln((max(rho, 0) w + e) / (x_ref + e))``.

        Parameters
        ----------
        rho
            BRDF values, 1/sr, any shape; negative values (impossible) count as 0.
        weight
            The mapping's weight ``w`` (:meth:`brdfkit.basis.model.PcaBasis.weight`),
            broadcastable.
        reference
            ``x_ref``, the weighted reference, broadcastable.
        out
            A NumPy array to write into, in its own dtype (the fit maps 151 tables in
            float32, in place); default: a new float64 array.
        """
        e, s = self.resolution(reference)
        if _is_torch(rho):
            y = ((rho.clamp(min=0) * weight + e) / (reference + e)).log()
            return y if not self.share else y * s
        if out is not None:
            np.clip(rho, 0.0, None, out=out)
            y = np.log((out * weight + e) / (reference + e), out=out)
            if self.share:
                y *= s
            return y
        rho = np.clip(np.asarray(rho, np.float64), 0.0, None)
        y = np.log((rho * weight + e) / (np.asarray(reference, np.float64) + e))
        return y * s if self.share else y

    def from_mapped(self, mapped, weight, reference, floor: float = FLOOR):
        """BRDF values (1/sr) of mapped values: the inverse of :meth:`to_mapped`, in its
        ``expm1`` form (exact where ``x'`` and ``x_ref`` are small), bounded below by
        :meth:`lower_bound` (module docstring): ``> 0``, and exact for every value above
        the bound. ``floor=0`` gives the inverse clamped at 0 (Nielsen et al.'s as
        published for :data:`NIELSEN`: the IPCA baseline's, and the training
        objectives')."""
        e, s = self.resolution(reference)
        if _is_torch(mapped):
            z = mapped if not self.share else (mapped / s).clamp(max=Z_MAX)
            x = z.expm1() * (reference + e) + reference
        else:
            reference = np.asarray(reference, np.float64)
            z = np.asarray(mapped, np.float64)
            if self.share:
                z = np.minimum(z / s, Z_MAX)
            x = np.expm1(z) * (reference + e) + reference
        if not floor:
            return (x.clamp(min=0) if _is_torch(x) else np.clip(x, 0.0, None)) / weight
        return _maximum(x, self.lower_bound(reference, weight, floor)) / weight

    def lower_bound(self, reference, weight, floor: float = FLOOR):
        """The decoded value's lower bound in weighted units (module docstring), NumPy or
        torch like ``reference``: Nielsen's :func:`lower_bound` (``floor`` its share of
        the reference); with a share, ``min(SHARE_FLOOR x_ref, CAP)`` plus a vanishing
        ``1e-12 min(1, w / 0.005)``. Why relative alone: the mapping resolves values down
        to its share of the reference, and an absolute bound would sit above the dark
        grazing values it resolves (chrome-steel's, 1% of the reference); why
        :data:`SHARE_FLOOR`: a basis's error in the log space of a dark grazing cell can
        reach far below the value, and at 0.001 of the reference 0.1% of the cells of
        the first 10 MERL test materials were decoded below 1% of their value
        (``docs/notes/compression.md``, "Grazing rows")."""
        if not self.share:
            return lower_bound(reference, weight, floor)
        if _is_torch(reference):
            return (SHARE_FLOOR * reference).clamp(max=CAP) + E_MIN * (weight / _W_TINY).clamp(max=1.0)
        return (np.minimum(SHARE_FLOOR * np.asarray(reference, np.float64), CAP)
                + E_MIN * np.minimum(weight / _W_TINY, 1.0))

    def rho_slope(self, rho, weight, reference):
        """``d rho / d x'`` at BRDF values ``rho`` (1/sr): ``(max(rho, 0) w + e) / (s w)``,
        what the fits linearise with (the prior's likelihood, the render weights)."""
        e, s = self.resolution(reference)
        if _is_torch(rho):
            return (rho.clamp(min=0) * weight + e) / (s * weight)
        return (np.clip(np.asarray(rho, np.float64), 0.0, None) * weight + e) / (s * np.asarray(weight, np.float64))


NIELSEN = LogMapping()
"""Nielsen et al.'s mapping (``kappa = 0``)."""


def to_mapped(rho, weight, reference, out=None):
    """:meth:`LogMapping.to_mapped` of Nielsen's mapping.

    Examples
    --------
    >>> import numpy as np
    >>> float(to_mapped(np.array(0.5), 0.5, 0.25))
    0.0
    """
    return NIELSEN.to_mapped(rho, weight, reference, out)


def lower_bound(reference, weight, floor: float = FLOOR):
    """The decoded value's lower bound in weighted units: ``min(floor x_ref, CAP) + 3e-3
    eps min(1, w / 0.005)`` (module docstring), NumPy or torch like ``reference``."""
    if _is_torch(reference):
        return (floor * reference).clamp(max=CAP) + _TINY * (weight / _W_TINY).clamp(max=1.0)
    return np.minimum(floor * np.asarray(reference, np.float64), CAP) + _TINY * np.minimum(weight / _W_TINY, 1.0)


def from_mapped(mapped, weight, reference, floor: float = FLOOR):
    """:meth:`LogMapping.from_mapped` of Nielsen's mapping.

    Examples
    --------
    >>> import numpy as np
    >>> round(float(from_mapped(to_mapped(np.array(0.5), 0.5, 0.25), 0.5, 0.25)), 12)
    0.5
    >>> float(from_mapped(np.array(-10.0), 0.5, 0.25)) > 0
    True
    """
    return NIELSEN.from_mapped(mapped, weight, reference, floor)
