"""Which method and model file a ``-m`` value means (``brdfkit sparse``, ``brdfkit bench``).

A built-in model (:mod:`brdfkit.models.builtin`, ``docs/models.md``) has up to three
parts: its hypernetwork, and optionally a learnt prior and the PCA basis that prior is
fitted with. A built-in name therefore names a different file for each method
(:func:`resolve_for`); a path is the file as it is. ``--method auto``, ``brdfkit
sparse``'s default, picks the method too (:func:`choose`): a built-in's learnt prior
when it has one (the better sparse reconstruction, ``docs/notes/generalisation.md``), else its
hypernetwork; a file by the format its header records.
"""

from __future__ import annotations

import dataclasses
import os

__all__ = ["AUTO", "Choice", "resolve_for", "file_method", "choose"]

AUTO = "auto"
"""The ``--method`` value that lets :func:`choose` pick the method."""

# The part of a built-in each method takes (brdfkit.models.builtin's resolvers); a method
# not listed gets its -m value as it is (its loader says what it takes).
_RESOLVERS = {"hypernet": "resolve_model", "ipca": "resolve_basis", "prior": "resolve_prior"}


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
    built-in name its hypernetwork (``hypernet``), its learnt prior (``prior``) or its
    PCA basis (``ipca``), checked against the manifest.

    Raises
    ------
    InputError
        An unknown name, or a built-in without that part (one line).
    """
    from brdfkit.models import builtin

    name = _RESOLVERS.get(method)
    return getattr(builtin, name)(spec) if name else os.fspath(spec)


def file_method(path: str | os.PathLike) -> str:
    """The method a model file is for, by the format its header records: ``prior``
    (``brdfkit-prior``), ``ipca`` (``brdfkit-basis``), else ``hypernet`` (whose loader
    then names what is wrong with a file that is none of them)."""
    from brdfkit.methods.prior.prior_file import is_prior_file

    if is_prior_file(path):
        return "prior"
    from brdfkit.errors import FormatError, InputError
    from brdfkit.io.tensorfile import open_safetensors

    try:
        with open_safetensors(os.fspath(path)) as f:
            fmt = (f.metadata() or {}).get("format")
    except (FormatError, InputError, OSError):
        fmt = None
    from brdfkit.basis.basis_file import is_basis_format

    return "ipca" if is_basis_format(fmt) else "hypernet"


def _default_entry():
    from brdfkit.models.builtin import read_manifest

    return next((m for m in read_manifest().installed() if m.default), None)


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
        if method != AUTO and method not in _RESOLVERS:
            return Choice(method, None, None)
        entry = _default_entry()
        if entry is None:
            return Choice("hypernet" if method == AUTO else method, None, None)
        if method == AUTO:
            method = "prior" if entry.prior else "hypernet"
        return Choice(method, resolve_for(method, entry.name), f"{entry.name}, the default built-in")
    from brdfkit.models.builtin import builtin_models, is_path_spec, resolve_model

    spec = os.fspath(spec)
    if method != AUTO:
        return Choice(method, resolve_for(method, spec), spec)
    if is_path_spec(spec):
        return Choice(file_method(spec), spec, spec)
    entry = next((m for m in builtin_models() if m.name == spec), None)
    if entry is None:
        resolve_model(spec)  # raises the unknown-name error listing the installed ones
    method = "prior" if entry.prior else "hypernet"
    return Choice(method, resolve_for(method, spec), spec)
