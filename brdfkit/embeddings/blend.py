"""Blending two embeddings: material editing by interpolation (``brdfkit interpolate``)."""

from __future__ import annotations

import math

import numpy as np

from brdfkit.errors import InputError, ModelMismatchError
from brdfkit.io.embedding import Embedding

__all__ = ["interpolate"]


def interpolate(a: Embedding, b: Embedding, t: float, allow_extrapolation: bool = False) -> Embedding:
    """Blend two embeddings of the same kind, decoders and size: ``(1 - t) a + t b``
    (for a basis embedding, a blend of the log-mapped tables), its decode options blended
    alike.

    Computed in float64 and rounded to float32, so ``t = 0`` gives ``a`` and ``t = 1``
    gives ``b`` exactly.

    Raises
    ------
    ModelMismatchError
        The embeddings differ in kind, decoders or size.
    InputError
        ``t`` not a finite number, or outside ``[0, 1]`` without ``allow_extrapolation``.

    Examples
    --------
    >>> import numpy as np
    >>> a = Embedding(np.zeros(6, np.float32), "basis", "f" * 64, "a")
    >>> b = Embedding(np.ones(6, np.float32), "basis", "f" * 64, "b")
    >>> interpolate(a, b, 0.25).values.tolist()
    [0.25, 0.25, 0.25, 0.25, 0.25, 0.25]
    >>> interpolate(a, b, 0.0).values is not a.values, bool((interpolate(a, b, 1.0).values == b.values).all())
    (True, True)
    """
    try:
        t = float(t)
    except (TypeError, ValueError):
        raise InputError(f"t: {t!r} is not a number") from None
    if not math.isfinite(t):
        raise InputError(f"t: {t!r} is not a finite number")
    if not allow_extrapolation and not 0.0 <= t <= 1.0:
        raise InputError(f"t = {t:g} is outside [0, 1]; pass allow_extrapolation=True to extrapolate")
    if a.kind != b.kind:
        raise ModelMismatchError(f"cannot interpolate a {a.kind} embedding ({a.source or 'a'}) with a {b.kind} one "
                                 f"({b.source or 'b'}): encode both the same way")
    if a.decoder != b.decoder or a.size != b.size or (a.parts or {}) != (b.parts or {}):
        raise ModelMismatchError(
            f"cannot interpolate embeddings of different decoders or sizes: {a.source or 'a'} is {a.size} numbers "
            f"of decoder {a.decoder[:12]}, {b.source or 'b'} {b.size} of decoder {b.decoder[:12]}")
    values = ((1.0 - t) * a.values.astype(np.float64) + t * b.values.astype(np.float64)).astype(np.float32)
    if not np.isfinite(values).all():
        raise InputError(f"t = {t:g} extrapolates beyond float32 range")
    options = None
    if a.options or b.options:
        from brdfkit.embeddings.registry import get_kind

        kind = get_kind(a.kind)  # an option left out is its kind's default, not always 0
        keys = sorted(set(a.options or {}) | set(b.options or {}))
        options = {k: (1.0 - t) * kind.option(a.options, k) + t * kind.option(b.options, k) for k in keys}
    return Embedding(values, a.kind, a.decoder, f"interpolate({a.source or 'a'}, {b.source or 'b'}, t={t:g})", 0,
                     parts=dict(a.parts) if a.parts else None, options=options)
