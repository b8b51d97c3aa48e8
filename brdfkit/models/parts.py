"""The part registry (:data:`PARTS`): each part of a model, defined once.

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

A header digest sits under the key :data:`HEADER_DIGEST_KEY` (``fingerprint``, its first
name, kept since format 1) and is checked against the weights when the file loads; which
digest names a file is :meth:`Part.recorded_digest`, the rule's one implementation. Each
:class:`Part` is also how the part loads, the class of what it loads and where that
records its training materials. Everything else refers to it: the built-in manifest
(:mod:`brdfkit.models.builtin`: the parts of a bundle and their digests), the embedding
kinds (:data:`brdfkit.embeddings.registry.KINDS`: each names the part that decodes it), the
reconstruction methods (:data:`brdfkit.methods.METHODS`: ``Method.part``, so a file of
another part is refused in one line) and ``brdfkit fit``'s recipes
(:data:`brdfkit.training.FITTERS`).

A file says which part it is by the ``format`` its header records (:func:`file_part`); a
loaded object by its class (:func:`part_of`), never by the attributes it happens to have.

May import: the ground floor and :mod:`brdfkit.io`. The loaders and classes live in the
parts' own packages, a layer or more above: a part names them by module path
(``"brdfkit.basis.basis_file:load_basis"``), imported when a file of that part loads, as
:func:`brdfkit.lazy_attributes` names the modules of the lazy packages; nothing here
imports them otherwise, and :func:`part_of` imports nothing at all. Nor does it import
:mod:`brdfkit.models.builtin` (which reads it): a model's name resolves to a part's file
there (:func:`~brdfkit.models.builtin.resolve_part`, :func:`~brdfkit.models.builtin.load_part`),
and what a model serves is :mod:`brdfkit.methods.service`.
"""

from __future__ import annotations

import dataclasses
import importlib
import os
import sys

from brdfkit.errors import InputError

__all__ = ["Part", "PARTS", "HEADER_DIGEST_KEY", "get_part", "part_of_format", "file_part", "part_of"]

HEADER_DIGEST_KEY = "fingerprint"
"""The header key of a ``header``-digest part's digest (its first name, kept)."""


def _named(where: str):
    """The object ``module:name`` names, its module imported."""
    module, name = where.split(":")
    return getattr(importlib.import_module(module), name)


@dataclasses.dataclass(frozen=True)
class Part:
    """One part of a model.

    Attributes
    ----------
    name
        The part's name: a key of a bundle's ``parts`` in the manifest.
    label
        What messages call it (``"PCA basis"``).
    formats
        The header ``format`` values of its files, the one written first.
    digest
        ``"header"`` (the digest the file's header records under
        :data:`HEADER_DIGEST_KEY`, checked against its content when it loads) or
        ``"file"`` (the SHA-256 of the file's bytes).
    loader
        ``"module:function"``: ``function(path)`` loads and checks a file of the part
        (``function(path, device=device)`` with :attr:`on_device`).
    cls
        ``"module:Class"``: the class of what :attr:`loader` returns.
    materials_at
        The attributes of a loaded object that hold its training materials' names
        (``("meta", "materials")``: ``obj.meta["materials"]``).
    on_device
        Whether :attr:`loader` takes a torch device.
    """

    name: str
    label: str
    formats: tuple
    digest: str
    loader: str = dataclasses.field(repr=False)
    cls: str = dataclasses.field(repr=False)
    materials_at: tuple = dataclasses.field(repr=False)
    on_device: bool = dataclasses.field(default=False, repr=False)

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

    def load(self, path: str | os.PathLike, device=None):
        """``(obj, digest)``: the part's file ``path`` loaded and checked, and the digest
        embeddings and manifests name it by (:meth:`recorded_digest`; a header's is the
        one its loader has checked against the content)."""
        path = os.fspath(path)
        load = _named(self.loader)
        obj = load(path, device=device) if self.on_device else load(path)
        return obj, self.recorded_digest(path)

    def type(self) -> type:
        """The class of a loaded part (imported when asked)."""
        return _named(self.cls)

    def materials(self, obj) -> set:
        """The training materials of a loaded ``obj`` of this part."""
        value = obj
        for key in self.materials_at:
            value = value.get(key) if isinstance(value, dict) else getattr(value, key, None)
        return set(value or ())

    def is_loaded(self, obj) -> bool:
        """Whether ``obj`` is a loaded part of this kind (by its class): no object of it
        exists before its module is imported, so this imports nothing to say no."""
        return self.cls.split(":")[0] in sys.modules and isinstance(obj, self.type())


PARTS: dict[str, Part] = {
    "network": Part("network", "hypernetwork", ("brdfkit-model",), "header", "brdfkit.hypernet.network_file:load_network",
                    "brdfkit.hypernet.loaded:LoadedNetwork", ("meta", "materials"), on_device=True),
    "basis": Part("basis", "PCA basis", ("brdfkit-basis", "brdfkit-ipca"), "file", "brdfkit.basis.basis_file:load_basis",
                  "brdfkit.basis.model:PcaBasis", ("materials",)),
    "prior": Part("prior", "learnt prior", ("brdfkit-prior",), "header", "brdfkit.prior.prior_file:load_prior",
                  "brdfkit.prior.model:PriorModel", ("meta", "materials"), on_device=True),
    "residual": Part("residual", "basis residual", ("brdfkit-residual",), "file",
                     "brdfkit.residual.residual_file:load_residual", "brdfkit.residual.model:BasisResidual",
                     ("meta", "materials")),
}
"""The parts of a model by name (the module's table)."""


def get_part(name: str) -> Part:
    """The part called ``name``; :class:`InputError` listing the parts otherwise."""
    try:
        return PARTS[name]
    except (KeyError, TypeError):
        raise InputError(f"unknown model part {name!r}; parts: {', '.join(PARTS)}") from None


def part_of_format(fmt) -> Part | None:
    """The part whose files record the header ``format`` ``fmt``, or ``None``.

    Examples
    --------
    >>> part_of_format("brdfkit-ipca").name, part_of_format("pickle")
    ('basis', None)
    """
    return next((p for p in PARTS.values() if fmt in p.formats), None)


def file_part(path: str | os.PathLike) -> Part:
    """The part a model file is, by the ``format`` its header records; a file that records
    none of the parts' formats (not safetensors, another format, missing) is taken for a
    hypernetwork, whose loader then names what is wrong with it (a pickle, a MERL table, a
    reference table ... in one line)."""
    from brdfkit.errors import FormatError
    from brdfkit.io.tensorfile import open_safetensors

    try:
        with open_safetensors(os.fspath(path)) as f:
            fmt = (f.metadata() or {}).get("format")
    except (FormatError, InputError, OSError):
        fmt = None
    return part_of_format(fmt) or PARTS["network"]


def part_of(obj) -> Part | None:
    """The part a loaded object is, by its class (a
    :class:`~brdfkit.basis.model.PcaBasis`, a :class:`~brdfkit.prior.model.PriorModel`, a
    :class:`~brdfkit.residual.model.BasisResidual`, a
    :class:`~brdfkit.hypernet.loaded.LoadedNetwork`), or ``None``; imports nothing."""
    return next((p for p in PARTS.values() if p.is_loaded(obj)), None)
