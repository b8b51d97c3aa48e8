"""A residual embedding as a renderable BRDF, checked against its decoder."""

from __future__ import annotations

import numpy as np

from brdfkit.errors import ModelMismatchError
from brdfkit.render.renderable import DecodedBRDF

__all__ = ["ResidualBRDF", "check_embedding"]


def check_embedding(emb, residual, digest: str, name: str = "") -> tuple[np.ndarray, dict]:
    """The ``(K, 3)`` coefficients and correction gains ``{member: gain}``
    (:func:`brdfkit.residual.model.gains`) of a residual embedding, checked against the
    residual (its file's digest, its basis's, the sizes it decodes, its members).

    Raises
    ------
    ModelMismatchError
        Another residual or basis, or a size it does not decode (one line).
    """
    what = f"embedding {name}" if name else "embedding"
    if emb.decoder != digest:
        raise ModelMismatchError(f"{what} was made with basis residual {emb.decoder[:12]}, not with the given one "
                                 f"{digest[:12]}; encode the material again with it")
    basis = (emb.parts or {}).get("basis")
    if basis is not None and basis != residual.basis_digest:
        raise ModelMismatchError(f"{what} holds coefficients of basis {basis[:12]}, but the residual corrects basis "
                                 f"{residual.basis_digest[:12]}")
    k = emb.size // 3
    if emb.size % 3 or k not in residual.components:
        raise ModelMismatchError(f"{what} holds {emb.size} numbers; the residual decodes "
                                 f"{', '.join(str(3 * c) for c in residual.components)}")
    from brdfkit.residual.model import gains

    try:
        g = gains(emb.options)
    except ValueError:
        raise ModelMismatchError(f"{what}: its options {emb.options} are not correction gains") from None
    for member, gain in g.items():
        if not 0.0 <= gain <= 1.0:
            raise ModelMismatchError(f"{what}: correction {gain:g} is outside [0, 1] (a blend extrapolated too far)")
        if member not in residual.members(k):
            raise ModelMismatchError(f"{what}: the residual has no member {member} for {emb.size} numbers")
    return emb.values.reshape(k, 3), g


class ResidualBRDF(DecodedBRDF):
    """A residual embedding as a renderable BRDF (``eval_pairs``, ``eval_dirs``,
    ``to_table``): decoded in NumPy, for a render only at the cells its pairs reach
    (:class:`~brdfkit.render.renderable.DecodedBRDF`: the hyponet at those cells alone)."""

    def __init__(self, residual, coefficients, gain=1.0, name: str = "embedding", device=None):
        self.residual = residual
        self.coefficients = np.asarray(coefficients, np.float32)
        self.gain = gain if isinstance(gain, dict) else float(gain)  # member 0's, or {member: gain}
        self.name = name

    def to_table(self) -> np.ndarray:
        """float64 ``(90, 90, 180, 3)``, 1/sr, NaN off the basis's cells."""
        return self.residual.decode(self.coefficients, self.gain)

    def at_cells(self, cells) -> tuple:
        """``(cells, values)``: the decode at those of the flat MERL ``cells`` the basis
        covers, float64 ``(n, 3)``."""
        return self.residual.decode_at(self.coefficients, cells, self.gain)
