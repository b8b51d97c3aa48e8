"""The part registry (:data:`PARTS`): each part of a model, its file and its loader.

A model (what ``-m`` takes) is a file or a built-in bundle of parts: a hypernetwork
(``network``), a PCA basis (``basis``), a learnt prior (``prior``) and a basis residual
(``residual``). Each :class:`ModelPart` here is one of them: its file
(:class:`brdfkit.models.parts.PartFile`: name, label, header formats, digest rule) and
its loader, the one place that says how that part loads, which digest names it and
which materials it was trained on. Everything else refers to it:

* the embedding kinds (:data:`brdfkit.embeddings.KINDS`): each kind names the part that
  decodes it, and loads its decoder through it;
* the reconstruction methods (:data:`brdfkit.methods.METHODS`): each method names the
  part it takes (``Method.part``), so a file of another part is refused in one line;
* what ``brdfkit fit`` trains (:data:`brdfkit.training.FITTERS`): each recipe names the
  part its file is.

A file says which part it is by the ``format`` its header records (:func:`file_part`); a
loaded object by its class (:func:`part_of`), never by the attributes it happens to have.
"""

from __future__ import annotations

import dataclasses
import os
import sys
from typing import Callable

from brdfkit.errors import InputError
from brdfkit.models.parts import PART_FILES, PartFile, part_of_format

__all__ = ["ModelPart", "PARTS", "get_part", "file_part", "part_of", "load_part"]


@dataclasses.dataclass(frozen=True)
class ModelPart:
    """One part of a model.

    Attributes
    ----------
    file
        Its :class:`~brdfkit.models.parts.PartFile`: name, label, header formats, digest
        rule.
    load_fn
        ``load_fn(path, device) -> (obj, digest)``: the file loaded and checked, and the
        digest embeddings and manifests name it by (the file's rule).
    type_fn
        ``type_fn() -> class`` of what :attr:`load_fn` returns (imported when asked).
    type_module
        The module that class is defined in: no object of it exists before that module is
        imported, so :meth:`is_loaded` imports nothing to say no.
    materials_fn
        ``materials_fn(obj) -> set``: the names of the materials it was trained on.
    """

    file: PartFile
    load_fn: Callable = dataclasses.field(repr=False)
    type_fn: Callable = dataclasses.field(repr=False)
    type_module: str
    materials_fn: Callable = dataclasses.field(repr=False)

    @property
    def name(self) -> str:
        """The part's name (``network``, ``basis``, ``prior``, ``residual``)."""
        return self.file.name

    @property
    def label(self) -> str:
        """What messages call it (``"PCA basis"``)."""
        return self.file.label

    def load(self, path: str | os.PathLike, device=None):
        """``(obj, digest)`` of the part's file ``path`` (:attr:`load_fn`)."""
        return self.load_fn(os.fspath(path), device)

    def materials(self, obj) -> set:
        """The training materials of a loaded ``obj`` of this part."""
        return set(self.materials_fn(obj) or ())

    def is_loaded(self, obj) -> bool:
        """Whether ``obj`` is a loaded part of this kind (by its class)."""
        return self.type_module in sys.modules and isinstance(obj, self.type_fn())


def _network(path, device):
    from brdfkit.hypernet.network_file import load_network

    net = load_network(path, device=device)
    return net, net.digest


def _network_type():
    from brdfkit.hypernet.loaded import LoadedNetwork

    return LoadedNetwork


def _basis(path, device):
    from brdfkit.basis.basis_file import load_basis
    from brdfkit.io.digest import cached_file_digest

    return load_basis(path), cached_file_digest(path)


def _basis_type():
    from brdfkit.basis.model import PcaBasis

    return PcaBasis


def _prior(path, device):
    from brdfkit.prior.prior_file import load_prior

    model = load_prior(path, device=device)
    return model, model.digest


def _prior_type():
    from brdfkit.prior.model import PriorModel

    return PriorModel


def _residual(path, device):
    from brdfkit.io.digest import cached_file_digest
    from brdfkit.residual.residual_file import load_residual

    return load_residual(path), cached_file_digest(path)


def _residual_type():
    from brdfkit.residual.model import BasisResidual

    return BasisResidual


PARTS: dict[str, ModelPart] = {
    "network": ModelPart(PART_FILES["network"], _network, _network_type, "brdfkit.hypernet.loaded",
                         lambda n: n.meta.get("materials")),
    "basis": ModelPart(PART_FILES["basis"], _basis, _basis_type, "brdfkit.basis.model", lambda b: b.materials),
    "prior": ModelPart(PART_FILES["prior"], _prior, _prior_type, "brdfkit.prior.model",
                       lambda p: p.meta.get("materials")),
    "residual": ModelPart(PART_FILES["residual"], _residual, _residual_type, "brdfkit.residual.model",
                          lambda r: r.meta.get("materials")),
}
"""The parts of a model by name (the module's text); their files are
:data:`brdfkit.models.parts.PART_FILES`."""


def get_part(name: str) -> ModelPart:
    """The part called ``name``; :class:`InputError` listing the parts otherwise."""
    try:
        return PARTS[name]
    except (KeyError, TypeError):
        raise InputError(f"unknown model part {name!r}; parts: {', '.join(PARTS)}") from None


def file_part(path: str | os.PathLike) -> ModelPart:
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
    found = part_of_format(fmt)
    return PARTS[found.name] if found is not None else PARTS["network"]


def part_of(obj) -> ModelPart | None:
    """The part a loaded object is, by its class (a
    :class:`~brdfkit.basis.model.PcaBasis`, a :class:`~brdfkit.prior.model.PriorModel`, a
    :class:`~brdfkit.residual.model.BasisResidual`, a
    :class:`~brdfkit.hypernet.loaded.LoadedNetwork`), or ``None``; imports nothing."""
    return next((p for p in PARTS.values() if p.is_loaded(obj)), None)


def load_part(spec: str | os.PathLike, part: str, device="cpu"):
    """Part ``part`` of the model ``spec`` (a built-in's name or a file), loaded and
    checked: a built-in's file against the manifest's digest, a file against the digest
    it records."""
    from brdfkit.models.builtin import resolve_part

    return get_part(part).load(resolve_part(spec, part), device)[0]
