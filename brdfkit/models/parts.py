"""What each part of a model is as a file (:data:`PART_FILES`): its name, what messages
call it, the formats its header records, and the digest that names it.

A *model* (what ``-m`` takes) is a file or a built-in *bundle* of *parts*, each one
safetensors file whose metadata ``format`` says which part it is:

============ ================== ============================== ===========================
part         called             header ``format``              digest (``digest`` rule)
============ ================== ============================== ===========================
``network``  hypernetwork       ``brdfkit-model``              its weights' SHA-256, in the
                                                               header (``header``)
``basis``    PCA basis          ``brdfkit-basis`` (or          the file's SHA-256 (``file``)
                                ``brdfkit-ipca``, its first
                                name)
``prior``    learnt prior       ``brdfkit-prior``              its content's SHA-256, in the
                                                               header (``header``)
``residual`` basis residual     ``brdfkit-residual``           the file's SHA-256 (``file``)
============ ================== ============================== ===========================

A header digest sits under the key ``fingerprint`` (its first name, kept since format 1)
and is checked against the weights when the file loads. This table is what the built-in
manifest (:mod:`brdfkit.models.builtin`) needs of a part; the part registry
:data:`brdfkit.embeddings.parts.PARTS`, which the embedding kinds, the reconstruction
methods and ``brdfkit fit``'s recipes refer to, adds to each entry its loader (in a layer
above the packages that load them).

May import: the ground floor and :mod:`brdfkit.io`. No torch.
"""

from __future__ import annotations

import dataclasses
import os

__all__ = ["PartFile", "PART_FILES", "HEADER_DIGEST_KEY", "part_file", "part_of_format"]

HEADER_DIGEST_KEY = "fingerprint"
"""The header key of a ``header``-digest part's digest (its first name, kept)."""


@dataclasses.dataclass(frozen=True)
class PartFile:
    """One part's file.

    Attributes
    ----------
    name
        The part's name: a key of a bundle's ``parts`` in the manifest.
    label
        What messages call it (``"PCA basis"``).
    formats
        The header ``format`` values of its files, the one written first.
    digest
        ``"header"`` (the digest the file's header records, checked against its content
        when it loads) or ``"file"`` (the SHA-256 of the file's bytes).
    """

    name: str
    label: str
    formats: tuple
    digest: str

    def __post_init__(self):
        if self.digest not in ("header", "file"):
            raise ValueError(f"part {self.name!r}: digest rule {self.digest!r} is not 'header' or 'file'")

    def recorded_digest(self, path: str | os.PathLike) -> str | None:
        """The digest ``path`` names itself by under this part's rule: the header's
        (``None`` when it records none) or the file's SHA-256 (computed once per process
        while the file keeps its size and time)."""
        if self.digest == "header":
            from brdfkit.io.tensorfile import open_safetensors

            with open_safetensors(os.fspath(path), framework="numpy", diagnose="brdfkit model file") as f:
                return (f.metadata() or {}).get(HEADER_DIGEST_KEY)
        from brdfkit.io.digest import cached_file_digest

        return cached_file_digest(path)


PART_FILES: dict[str, PartFile] = {
    "network": PartFile("network", "hypernetwork", ("brdfkit-model",), "header"),
    "basis": PartFile("basis", "PCA basis", ("brdfkit-basis", "brdfkit-ipca"), "file"),
    "prior": PartFile("prior", "learnt prior", ("brdfkit-prior",), "header"),
    "residual": PartFile("residual", "basis residual", ("brdfkit-residual",), "file"),
}
"""The parts' files by part name (the module's table)."""


def part_file(name: str) -> PartFile:
    """The :class:`PartFile` of part ``name``; :class:`KeyError` for an unknown one (a
    name in the code, not from a user)."""
    return PART_FILES[name]


def part_of_format(fmt) -> PartFile | None:
    """The part whose files record the header ``format`` ``fmt``, or ``None``.

    Examples
    --------
    >>> part_of_format("brdfkit-ipca").name, part_of_format("pickle")
    ('basis', None)
    """
    return next((p for p in PART_FILES.values() if fmt in p.formats), None)
