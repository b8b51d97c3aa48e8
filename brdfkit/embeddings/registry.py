"""The embedding kinds by name (:data:`KINDS`), in the order ``encode`` prefers them."""

from __future__ import annotations

from brdfkit.embeddings import basis_kind, hypernet_kind, residual_kind
from brdfkit.embeddings.kind import EmbeddingKind
from brdfkit.errors import InputError

__all__ = ["KINDS", "get_kind", "kind_of_part"]

KINDS: dict[str, EmbeddingKind] = {
    "residual": residual_kind.KIND,
    "basis": basis_kind.KIND,
    "hypernet": hypernet_kind.KIND,
}
"""The embedding kinds by name. A model given by name encodes, with no ``--kind``, as the
first kind here whose part it has and whose decoder offers the size asked for."""


def get_kind(name: str) -> EmbeddingKind:
    """The kind called ``name`` (or an old name of it); :class:`InputError` listing the
    known ones otherwise.

    Examples
    --------
    >>> get_kind("latent").name
    'hypernet'
    """
    for kind in KINDS.values():
        if name == kind.name or name in kind.aliases:
            return kind
    raise InputError(f"unknown embedding kind {name!r}; known: {', '.join(KINDS)}")


def kind_of_part(part: str) -> EmbeddingKind | None:
    """The kind a model's ``part`` decodes, or ``None`` (a learnt prior decodes none)."""
    return next((k for k in KINDS.values() if k.part == part), None)
