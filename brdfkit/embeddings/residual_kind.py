"""The ``residual`` embedding kind: a basis embedding's coefficients plus the weight of a
hypernetwork residual's correction, refined on renders and chosen per material
(:mod:`brdfkit.residual`)."""

from __future__ import annotations

from brdfkit.embeddings.kind import EmbeddingKind, Offer

__all__ = ["KIND"]


def _default_of(sizes: tuple) -> int | None:
    """The default of the sizes a residual offers: 39 numbers when it offers them, else
    its largest (``None``: it offers none)."""
    from brdfkit.basis.coefficients import DEFAULT_SIZE

    return DEFAULT_SIZE if DEFAULT_SIZE in sizes else (sizes[-1] if sizes else None)


def _default_size(residual):
    return _default_of(tuple(residual.sizes()))


def _offer(path) -> Offer:
    from brdfkit.residual.residual_file import read_offer

    sizes, members = read_offer(path)
    return Offer(sizes, _default_of(sizes), members)


def _encode(residual, digest, table, *, source, size, steps, refine, max_seconds=None):
    from brdfkit.residual.encoding import encode_residual

    return encode_residual(residual, table, digest=digest, size=size, source=source, steps=steps if refine else 0)


def _open(residual, digest, emb, name, device):
    from brdfkit.residual.brdf import ResidualBRDF, check_embedding

    c, gain = check_embedding(emb, residual, digest, name)
    return ResidualBRDF(residual, c, gain, name=name or "embedding", device=device)


def _option_defaults():
    from brdfkit.residual.model import OPTION_DEFAULTS

    return dict(OPTION_DEFAULTS)


KIND = EmbeddingKind("residual", "coefficients of a PCA basis plus a hypernetwork's correction, chosen per material "
                     "(3 numbers a component)", "residual", lambda r: r.sizes(), _default_size, _encode, _open,
                     option_defaults=_option_defaults(), offer=_offer)
