"""Which method and file a ``-m`` value means for a sparse reconstruction (``brdfkit
sparse``, ``brdfkit validate``, ``brdfkit bench``): what :mod:`brdfkit.methods.service`
says the model serves, as the :class:`Choice` of one run.

Each method names the part of a model it takes (:attr:`brdfkit.methods.Method.part`), so
a built-in's name names a different file for each method (:func:`resolve_for`); a path is
the file as it is, its part told by the format its header records. ``--method auto``,
``brdfkit sparse``'s default, picks the method too (:func:`choose`): the model's own
(:attr:`brdfkit.methods.service.Service.default_method`: a built-in's learnt prior, else
its hypernetwork; a file's by its part).
"""

from __future__ import annotations

import dataclasses
import os

from brdfkit.errors import InputError
from brdfkit.methods.service import AUTO

__all__ = ["AUTO", "Choice", "method_of_part", "resolve_for", "file_method", "choose"]


@dataclasses.dataclass(frozen=True)
class Choice:
    """What runs: ``method`` (a :data:`brdfkit.methods.METHODS` name), its model file
    ``path`` (``None``: none given and no default installed, or a method that takes
    none) and ``label``, the model as the user named it, for messages."""

    method: str
    path: str | None
    label: str | None


def method_of_part(part: str, what: str = "") -> str:
    """The method that takes part ``part`` (the first of :data:`brdfkit.methods.METHODS`
    whose :attr:`~brdfkit.methods.Method.part` it is): that of a model loaded already.

    Raises
    ------
    InputError
        No method takes that part (a basis residual): one line naming ``what`` (a file,
        a loaded model) and the parts the methods take.
    """
    from brdfkit.methods import METHODS
    from brdfkit.models.parts import get_part

    found = next((m.name for m in METHODS.values() if m.part == part), None)
    if found is None:
        takes = ", ".join(f"{m.name} a {get_part(m.part).label}" for m in METHODS.values() if m.part)
        raise InputError(f"{what or 'model'}: a {get_part(part).label} file, which no sparse-reconstruction method "
                         f"takes ({takes}; a {get_part(part).label} decodes embeddings: `brdfkit encode -m`)")
    return found


def resolve_for(method: str, spec: str | os.PathLike) -> str:
    """The model file of ``method`` that a ``-m`` value names (:meth:`Service.method_for
    <brdfkit.methods.service.Service.method_for>` and :meth:`~brdfkit.methods.service.Service.path`);
    the value as it is for a method that takes no model.

    Raises
    ------
    InputError
        An unknown method or name, a model that does not serve the method (one line).
    """
    from brdfkit.methods import get_method
    from brdfkit.methods.service import serves

    part = get_method(method).part
    if not part:
        return os.fspath(spec)
    service = serves(spec)
    service.method_for(method)
    return service.path(part)


def file_method(path: str | os.PathLike) -> str:
    """The method a model file is for: the one that takes its part.

    Raises
    ------
    InputError
        A file of a part no method takes (a basis residual).
    """
    from brdfkit.methods.service import serves

    return serves(path).method_for(AUTO)


def choose(method: str, spec: str | os.PathLike | None) -> Choice:
    """The method and model file to run for ``--method`` ``method`` and ``-m`` ``spec``
    (``None``: the default built-in).

    ``method`` :data:`AUTO` runs the model's default method; a named method the part of
    the model it takes; with no ``spec``, a method that takes no model takes none, and with
    no default built-in installed the method runs without a file (its loader then says
    what it needs).

    Raises
    ------
    InputError
        An unknown method or name, a model that does not serve the method.
    """
    from brdfkit.methods import METHODS, get_method
    from brdfkit.methods.service import default_service, serves

    if method != AUTO and not get_method(method).part:
        if spec is not None:
            serves(spec).method_for(method)  # refused: the method takes no model
        return Choice(method, None, None)
    service = serves(spec) if spec is not None else default_service()
    if service is None:
        return Choice("hypernet" if method == AUTO else method, None, None)
    chosen = service.method_for(method)
    return Choice(chosen, service.path(METHODS[chosen].part), service.label)
