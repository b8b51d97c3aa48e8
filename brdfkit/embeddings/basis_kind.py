"""The ``basis`` embedding kind: the coefficients of a PCA basis's leading components,
``3 K`` numbers, refined on renders (:mod:`brdfkit.basis.coefficients`)."""

from __future__ import annotations

from brdfkit.embeddings.kind import EmbeddingKind, Offer

__all__ = ["KIND"]


def _sizes(basis):
    from brdfkit.basis.coefficients import basis_sizes

    return basis_sizes(basis)


def _default_size(basis):
    from brdfkit.basis.coefficients import DEFAULT_SIZE

    return min(DEFAULT_SIZE, 3 * basis.n_components)


def _offer(path) -> Offer:
    from brdfkit.basis.basis_file import read_components
    from brdfkit.basis.coefficients import DEFAULT_SIZE, basis_sizes

    k = read_components(path)
    return Offer(tuple(basis_sizes(k)), min(DEFAULT_SIZE, 3 * k))


def _encode(basis, digest, table, *, source, size, steps, refine, max_seconds=None):
    from brdfkit.basis.coefficients import encode_coefficients

    return encode_coefficients(basis, table, digest=digest, size=size, source=source, steps=steps if refine else 0)


def _open(basis, digest, emb, name, device):
    from brdfkit.basis.coefficients import BasisBRDF, check_coefficients

    return BasisBRDF(basis, check_coefficients(emb, basis, digest, name), name=name or "embedding", device=device)


KIND = EmbeddingKind("basis", "coefficients of a PCA basis, refined on renders (3 numbers a component)", "basis",
                     _sizes, _default_size, _encode, _open, start="projection", offer=_offer)
