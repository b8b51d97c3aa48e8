"""The basis's log mapping and its inverse: the one place every user of a basis maps BRDF
values (the basis, its fit, its refinement on renders, the learnt prior, the residual).

Nielsen et al. 2015 (``MapBRDF`` of brdf.compute.dtu.dk) map a cosine-weighted value::

    x  = rho * w,                      w = cos(theta_i) cos(theta_o) (or its floor)
    x' = ln((x + eps) / (x_ref + eps)),   eps = EPS = 0.001

with ``x_ref`` the per-cell median of the training set's weighted values. The exact inverse
``x = exp(x') (x_ref + eps) - eps`` is negative wherever ``x' < ln(eps / (x_ref + eps))``:
there ``eps`` swamps the value (``x`` much below ``eps``, towards grazing angles where
``w`` is small), so a decoder's small error in ``x'`` crosses zero, and clamping it gave
exact zeros where the material is not black. No inverse can recover a value the mapping
does not resolve, so :func:`from_mapped` bounds the exact inverse below by a small share
:data:`FLOOR` of the training set's median at that cell (at most :data:`CAP`): a value
learnt from the training tables, of the right order where the median is, and far below
every value a render sees (where the exact inverse is above the bound it is returned as
it is, so a true value maps and comes back exactly). The decoded BRDF is then positive at
every cell the basis covers. ``docs/notes/compression.md`` measures the choice of
:data:`FLOOR` on renders and on the cells it changes (0.001: no cell decoded below 1% of
its value on the MERL materials tried, black-obsidian's renders 0.03 dB lower).

Both functions take NumPy arrays (float64 results) or torch tensors (their own dtype,
differentiable).
"""

from __future__ import annotations

import numpy as np

__all__ = ["EPS", "FLOOR", "CAP", "to_mapped", "from_mapped", "lower_bound"]

EPS = 0.001
"""Nielsen et al.'s ``eps`` of the weighted values."""

FLOOR = 0.001
"""The decoded value's lower bound as a share of the reference (module docstring)."""

CAP = 0.005 * EPS
"""The largest lower bound, in weighted units: far below what the mapping resolves, so
that a true value is decoded exactly wherever it is above it (under a bright reference
too)."""


def _is_torch(x) -> bool:
    return type(x).__module__.startswith("torch")


def to_mapped(rho, weight, reference, out=None):
    """Mapped values ``ln((max(rho, 0) w + eps) / (x_ref + eps))``.

    Parameters
    ----------
    rho
        BRDF values, 1/sr, any shape; negative values (impossible) count as 0.
    weight
        The mapping's weight ``w`` (:meth:`brdfkit.basis.model.PcaBasis.weight`), broadcastable.
    reference
        ``x_ref``, the weighted reference, broadcastable.
    out
        A NumPy array to write into, in its own dtype (the fit maps 151 tables in float32,
        in place); default: a new float64 array.

    Examples
    --------
    >>> import numpy as np
    >>> float(to_mapped(np.array(0.5), 0.5, 0.25))
    0.0
    """
    if _is_torch(rho):
        return ((rho.clamp(min=0) * weight + EPS) / (reference + EPS)).log()
    if out is not None:
        np.clip(rho, 0.0, None, out=out)
        return np.log((out * weight + EPS) / (reference + EPS), out=out)
    rho = np.clip(np.asarray(rho, np.float64), 0.0, None)
    return np.log((rho * weight + EPS) / (np.asarray(reference, np.float64) + EPS))


def _maximum(x, bound):
    """``max(x, bound)``, NaN kept (unmeasured cells)."""
    if _is_torch(x):
        import torch

        return torch.maximum(x, torch.as_tensor(bound, dtype=x.dtype))
    return np.maximum(x, bound)


def lower_bound(reference, weight, floor: float = FLOOR):
    """The decoded value's lower bound in weighted units: ``min(floor x_ref, CAP) + 3e-3
    eps min(1, w / 0.005)`` (module docstring), NumPy or torch like ``reference``."""
    if _is_torch(reference):
        return (floor * reference).clamp(max=CAP) + _TINY * (weight / _W_TINY).clamp(max=1.0)
    return np.minimum(floor * np.asarray(reference, np.float64), CAP) + _TINY * np.minimum(weight / _W_TINY, 1.0)


def from_mapped(mapped, weight, reference, floor: float = FLOOR):
    """BRDF values (1/sr) of mapped values: the inverse of :func:`to_mapped`, in its
    ``expm1`` form (exact where ``x'`` and ``x_ref`` are small), bounded below by
    :func:`lower_bound` (module docstring): ``> 0``, and exact for every value above the
    bound.
    ``floor=0`` gives Nielsen et al.'s inverse as published, clamped at 0 (the IPCA
    baseline's, and the training objectives').

    Examples
    --------
    >>> import numpy as np
    >>> round(float(from_mapped(to_mapped(np.array(0.5), 0.5, 0.25), 0.5, 0.25)), 12)
    0.5
    >>> float(from_mapped(np.array(-10.0), 0.5, 0.25)) > 0
    True
    """
    if _is_torch(mapped):
        x = mapped.expm1() * (reference + EPS) + reference
    else:
        reference = np.asarray(reference, np.float64)
        x = np.expm1(np.asarray(mapped, np.float64)) * (reference + EPS) + reference
    if not floor:
        return (x.clamp(min=0) if _is_torch(x) else np.clip(x, 0.0, None)) / weight
    return _maximum(x, lower_bound(reference, weight, floor)) / weight


_TINY = 3e-3 * EPS  # weighted: where the median is dark, what the mapping cannot resolve
_W_TINY = 0.005  # below this weight the absolute part shrinks with it: a basis without a
# floor of w (Nielsen's) has cells of w ~ 1e-6 at the horizon, where _TINY / w would be vast
