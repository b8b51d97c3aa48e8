"""A residual embedding as a renderable BRDF, checked against its decoder."""

from __future__ import annotations

import numpy as np

from brdfkit.errors import ModelMismatchError

__all__ = ["ResidualBRDF", "check_embedding"]


def check_embedding(emb, residual, digest: str, name: str = "") -> tuple[np.ndarray, float]:
    """The ``(K, 3)`` coefficients and correction weight of a residual embedding, checked
    against the residual (its file's digest, its basis's, the sizes it decodes).

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
    gain = float((emb.options or {}).get("correction", 1.0))
    if not 0.0 <= gain <= 1.0:
        raise ModelMismatchError(f"{what}: correction {gain:g} is outside [0, 1] (a blend extrapolated too far)")
    return emb.values.reshape(k, 3), gain


class ResidualBRDF:
    """A residual embedding as a renderable BRDF (``eval_dirs``, ``to_table``): decoded
    once in NumPy on first use, then looked up as
    :class:`brdfkit.render.renderable.TableBRDF` looks up any table."""

    def __init__(self, residual, coefficients, gain: float = 1.0, name: str = "embedding", device=None):
        self.residual = residual
        self.coefficients = np.asarray(coefficients, np.float32)
        self.gain = float(gain)
        self.name = name
        self.device = device
        self._table = None

    def to_table(self) -> np.ndarray:
        """float64 ``(90, 90, 180, 3)``, 1/sr, NaN off the basis's cells."""
        return self.residual.decode(self.coefficients, self.gain)

    def eval_dirs(self, wi, wo):
        """BRDF ``(N, 3)`` float32 at local direction pairs."""
        if self._table is None:
            from brdfkit.render.renderable import TableBRDF

            self._table = TableBRDF(self.to_table(), name=self.name, device=self.device)
        return self._table.eval_dirs(wi, wo)
