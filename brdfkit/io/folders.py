"""Finding MERL materials on disk: folders of ``.binary`` files, material names, name lists.

A material is named by its file stem (``teflon.binary`` is ``teflon``). Training
(:func:`collect_materials`) and the benchmark (:func:`list_materials`) both scan folders
with :func:`scan_folder`, so they agree on which files count (``*.binary``, not hidden,
not recursive) and on the names. Name lists (``merl-test.txt`` of ``docs/data.md``: one name a
line, ``#`` comments) are read by :func:`read_exclude_list`.
"""

from __future__ import annotations

import os
from typing import Iterable

from brdfkit.errors import InputError

__all__ = ["MERL_SUFFIX", "material_name", "scan_folder", "collect_materials", "list_materials",
           "read_exclude_list"]

MERL_SUFFIX = ".binary"


def material_name(path: str | os.PathLike) -> str:
    """The material name of a file or a name: its base name without ``.binary`` (or
    without any other extension)."""
    base = os.path.basename(os.fspath(path))
    return base[: -len(MERL_SUFFIX)] if base.endswith(MERL_SUFFIX) else os.path.splitext(base)[0]


def scan_folder(folder: str | os.PathLike) -> dict[str, str]:
    """``{name: path}`` of the MERL files in ``folder`` (``*.binary``, not hidden, not
    recursive), in name order.

    Raises
    ------
    InputError
        The folder holds no ``.binary`` file.
    """
    folder = os.fspath(folder)
    files = {f[:-len(MERL_SUFFIX)]: os.path.join(folder, f) for f in sorted(os.listdir(folder))
             if f.endswith(MERL_SUFFIX) and not f.startswith(".")}
    if not files:
        raise InputError(f"{folder}: folder holds no {MERL_SUFFIX} files")
    return dict(sorted(files.items()))


def collect_materials(data, exclude: Iterable[str] = ()) -> tuple[list[str], list[str], list[str], list[str]]:
    """Expand training inputs into a sorted, deterministic list of MERL files.

    Parameters
    ----------
    data
        A path or a sequence of paths: ``.binary`` files, or folders whose ``*.binary``
        files (not recursive) are all taken.
    exclude
        Material names (file stems, ``.binary`` suffix optional) to hold out.

    Returns
    -------
    tuple
        ``(paths, names, excluded, unknown)``: the training files and their names, both
        sorted by name; the excluded names that were found; the excluded names that
        matched no input (worth a warning: a typo would let a test material in).

    Raises
    ------
    InputError
        A path that does not exist, a folder without ``.binary`` files, two different
        files with the same name, or nothing left to train on.
    """
    if isinstance(data, (str, os.PathLike)):
        data = [data]
    found: dict[str, str] = {}
    for item in data:
        item = os.fspath(item)
        if os.path.isdir(item):
            files = list(scan_folder(item).values())
        elif os.path.exists(item):
            files = [item]
        else:
            raise InputError(f"{item}: no such file or folder")
        for f in files:
            name = material_name(f)
            if name in found and os.path.realpath(found[name]) != os.path.realpath(f):
                raise InputError(f"{f}: material name {name!r} also given as {found[name]}; "
                                 f"names (file stems) must be unique")
            found[name] = f
    wanted_out = {material_name(e.strip()) for e in exclude if e and e.strip()}
    excluded = sorted(wanted_out & set(found))
    unknown = sorted(wanted_out - set(found))
    names = sorted(n for n in found if n not in wanted_out)
    if not names:
        what = "all inputs are excluded" if found else "no materials given"
        raise InputError(f"nothing to train on: {what}")
    return [found[n] for n in names], names, excluded, unknown


def list_materials(folder: str | os.PathLike, names=None) -> list[tuple[str, str]]:
    """``(name, path)`` of the MERL tables in ``folder``, sorted by name, or only those
    named in ``names`` (file stems, ``.binary`` optional; in that order, once each).

    Raises
    ------
    InputError
        No ``.binary`` file in the folder, a named material without a file, or an empty
        ``names``.
    """
    files = scan_folder(folder)
    if names is None:
        return list(files.items())
    wanted = [n[:-len(MERL_SUFFIX)] if n.endswith(MERL_SUFFIX) else n for n in names]
    missing = [n for n in wanted if n not in files]
    if missing:
        raise InputError(f"{os.fspath(folder)}: no table for test material(s) {', '.join(missing)}")
    if not wanted:
        raise InputError("the test list names no material")
    return [(n, files[n]) for n in dict.fromkeys(wanted)]


def read_exclude_list(path: str | os.PathLike) -> list[str]:
    """Material names from a text file: one a line, ``#`` starts a comment, blank lines
    ignored (the format of ``merl-test.txt``, ``docs/data.md``)."""
    from brdfkit.atomic import check_input_file

    path = check_input_file(path)
    try:
        with open(path, encoding="utf-8") as f:
            lines = f.read().splitlines()
    except UnicodeDecodeError:
        raise InputError(f"{path}: exclude list is not UTF-8 text") from None
    names = [ln.split("#", 1)[0].strip() for ln in lines]
    return [n for n in names if n]
