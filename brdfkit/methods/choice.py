"""Which method and file a ``-m`` value means (``brdfkit sparse``, ``brdfkit bench``).

A model (what ``-m`` takes) is a file or the name of a built-in bundle
(:mod:`brdfkit.models.builtin`, ``docs/models.md``) of up to four parts: its
hypernetwork (``network``), PCA basis (``basis``), learnt prior (``prior``) and basis
residual (``residual``). A built-in name therefore names a different file for each method
(:func:`resolve_for`); a path is the file as it is, its part told by the format its header
records (:func:`brdfkit.embeddings.parts.file_part`). ``--method auto``, ``brdfkit sparse``'s default, picks the
method too (:func:`choose`): a built-in's learnt prior when it has one (the better sparse
reconstruction, ``docs/notes/generalisation.md``), else its hypernetwork; a file by its part.
"""

from __future__ import annotations

import dataclasses
import os

__all__ = ["AUTO", "METHOD_PARTS", "Choice", "resolve_for", "file_method", "choose"]

AUTO = "auto"
"""The ``--method`` value that lets :func:`choose` pick the method."""

METHOD_PARTS = {"hypernet": "network", "ipca": "basis", "prior": "prior"}
"""The part of a built-in each method takes; a method not listed gets its ``-m`` value as
it is (its loader says what it takes)."""


@dataclasses.dataclass(frozen=True)
class Choice:
    """What runs: ``method`` (a :data:`brdfkit.methods.METHODS` name), its model file
    ``path`` (``None``: none given and no default installed, or a method that takes
    none) and ``label``, the model as the user named it, for messages."""

    method: str
    path: str | None
    label: str | None


def resolve_for(method: str, spec: str | os.PathLike) -> str:
    """The model file of ``method`` that a ``-m`` value names: a path as it is; a
    built-in name the part :data:`METHOD_PARTS` gives, checked against the manifest.

    Raises
    ------
    InputError
        An unknown name, or a built-in without that part (one line).
    """
    from brdfkit.models.builtin import resolve_part

    part = METHOD_PARTS.get(method)
    return resolve_part(spec, part) if part else os.fspath(spec)


def file_method(path: str | os.PathLike) -> str:
    """The method a model file is for (:func:`brdfkit.embeddings.parts.file_part`):
    ``prior``, ``ipca`` (a basis), else ``hypernet``."""
    from brdfkit.embeddings.parts import file_part

    part = file_part(path)
    return {"prior": "prior", "basis": "ipca"}.get(part, "hypernet")


def _default_entry():
    from brdfkit.models.builtin import default_bundle

    return default_bundle()


def choose(method: str, spec: str | os.PathLike | None) -> Choice:
    """The method and model file to run for ``--method`` ``method`` and ``-m`` ``spec``.

    ``method`` :data:`AUTO`: with no ``spec``, the default built-in's learnt prior when
    it has one, else its hypernetwork; a built-in name likewise; a file by its format
    (:func:`file_method`). A named method takes the part of a built-in it uses
    (:func:`resolve_for`); with no ``spec``, ``hypernet``, ``prior`` and ``ipca`` take the
    default built-in's, the others none (their loader says what they need).

    Raises
    ------
    InputError
        An unknown name, or a built-in without the part the method needs.
    """
    if spec is None:
        if method != AUTO and method not in METHOD_PARTS:
            return Choice(method, None, None)
        entry = _default_entry()
        if entry is None:
            return Choice("hypernet" if method == AUTO else method, None, None)
        if method == AUTO:
            method = "prior" if entry.part("prior") else "hypernet"
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
    method = "prior" if entry.part("prior") else "hypernet"
    return Choice(method, resolve_for(method, spec), spec)
