"""Which method and file a ``-m`` value means (``brdfkit sparse``, ``brdfkit bench``).

A model (what ``-m`` takes) is a file or the name of a built-in bundle
(:mod:`brdfkit.models.builtin`, ``docs/models.md``) of up to four parts (the part registry
:data:`brdfkit.models.parts.PARTS`): its hypernetwork (``network``), PCA basis
(``basis``), learnt prior (``prior``) and basis residual (``residual``). Each method names
the part it takes (:attr:`brdfkit.methods.Method.part`), so a built-in name names a
different file for each method (:func:`resolve_for`); a path is the file as it is, its
part told by the format its header records (:func:`brdfkit.models.parts.file_part`),
and a file of a part no method takes (a basis residual) is refused in one line.
``--method auto``, ``brdfkit sparse``'s default, picks the method too (:func:`choose`): a
built-in's learnt prior (the better sparse reconstruction than the paper's decoder,
``docs/notes/generalisation.md``), else its hypernetwork; a file by its part.
"""

from __future__ import annotations

import dataclasses
import os

from brdfkit.errors import InputError

__all__ = ["AUTO", "Choice", "method_of_part", "resolve_for", "file_method", "choose"]

AUTO = "auto"
"""The ``--method`` value that lets :func:`choose` pick the method."""


@dataclasses.dataclass(frozen=True)
class Choice:
    """What runs: ``method`` (a :data:`brdfkit.methods.METHODS` name), its model file
    ``path`` (``None``: none given and no default installed, or a method that takes
    none) and ``label``, the model as the user named it, for messages."""

    method: str
    path: str | None
    label: str | None


def _part_of_method(method: str) -> str | None:
    from brdfkit.methods import METHODS

    m = METHODS.get(method)
    return None if m is None else m.part


def method_of_part(part: str, what: str = "") -> str:
    """The method that takes part ``part`` (the first of :data:`brdfkit.methods.METHODS`
    whose :attr:`~brdfkit.methods.Method.part` it is).

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
    """The model file of ``method`` that a ``-m`` value names: a path as it is (refused in
    one line when its header says it is another part than the method takes); a built-in
    name the part the method takes, checked against the manifest.

    Raises
    ------
    InputError
        An unknown name, a built-in without that part, a file of another part (one line).
    """
    from brdfkit.models.builtin import is_path_spec, resolve_part

    part = _part_of_method(method)
    if not part:
        return os.fspath(spec)
    if is_path_spec(spec):
        _check_file_part(os.fspath(spec), method, part)
    return resolve_part(spec, part)


def _check_file_part(path: str, method: str, part: str) -> None:
    """Refuse a file whose header names another part than ``part``; a file whose header
    names none is left to the method's loader, which says what it is."""
    from brdfkit.errors import FormatError
    from brdfkit.io.tensorfile import open_safetensors
    from brdfkit.models.parts import get_part, part_of_format

    if not os.path.isfile(path):
        return
    try:
        with open_safetensors(path) as f:
            found = part_of_format((f.metadata() or {}).get("format"))
    except (FormatError, InputError, OSError):
        return
    if found is not None and found.name != part:
        raise InputError(f"{path}: a {found.label} file, not the {get_part(part).label} --method {method} takes")


def file_method(path: str | os.PathLike) -> str:
    """The method a model file is for: the one that takes its part
    (:func:`brdfkit.models.parts.file_part`, :func:`method_of_part`).

    Raises
    ------
    InputError
        A file of a part no method takes (a basis residual).
    """
    from brdfkit.models.parts import file_part

    return method_of_part(file_part(path).name, os.fspath(path))


def _auto_method(entry) -> str:
    """``--method auto``'s method for a built-in bundle: ``prior`` when it has a learnt
    prior, else ``hypernet``."""
    return "prior" if entry.part("prior") else "hypernet"


def _default_entry():
    from brdfkit.models.builtin import default_bundle

    return default_bundle()


def choose(method: str, spec: str | os.PathLike | None) -> Choice:
    """The method and model file to run for ``--method`` ``method`` and ``-m`` ``spec``.

    ``method`` :data:`AUTO`: with no ``spec``, the default built-in's learnt prior when
    it has one, else its hypernetwork; a built-in name likewise; a file by its part
    (:func:`file_method`). A named method takes the part of a built-in it uses
    (:func:`resolve_for`); with no ``spec``, a method that takes a part takes the default
    built-in's, the others none (their loader says what they need).

    Raises
    ------
    InputError
        An unknown name, a built-in without the part the method needs, a file of a part
        no method (or not this method) takes.
    """
    if method != AUTO:
        from brdfkit.methods import get_method

        get_method(method)  # an unknown name refused in one line, listing the methods
    if spec is None:
        if method != AUTO and not _part_of_method(method):
            return Choice(method, None, None)
        entry = _default_entry()
        if entry is None:
            return Choice("hypernet" if method == AUTO else method, None, None)
        if method == AUTO:
            method = _auto_method(entry)
        return Choice(method, resolve_for(method, entry.name), f"{entry.name}, the default built-in")
    from brdfkit.models.builtin import installed_bundles, is_path_spec, resolve_network

    spec = os.fspath(spec)
    if method != AUTO:
        return Choice(method, resolve_for(method, spec), spec)
    if is_path_spec(spec):
        return Choice(file_method(spec), spec, spec)
    entry = next((m for m in installed_bundles() if m.name == spec), None)
    if entry is None:
        resolve_network(spec)  # raises the unknown-name error listing the installed ones
    method = _auto_method(entry)
    return Choice(method, resolve_for(method, spec), spec)
