"""Reading brdfkit's safetensors files (model files, reference tables, PCA bases) safely.

`safetensors <https://github.com/huggingface/safetensors>`_ holds tensors and string
metadata and never runs code: brdfkit stores every array it writes this way and never
unpickles. :func:`open_safetensors` is the one place that opens such a file: it checks
that the path is a readable file, optionally diagnoses what a file that is *not*
safetensors looks like (a pickle, a MERL table, a truncated file; :func:`check_header`),
and turns every parser error into a one-line :class:`~brdfkit.errors.FormatError` that
names the file. The format-specific checks (metadata ``format`` / ``version``, tensor
names and shapes) stay with each format's reader; :func:`check_format` checks the
``format`` and ``version`` metadata every brdfkit file carries.
"""

from __future__ import annotations

import contextlib
import json
import os
from typing import Iterator

from brdfkit.atomic import check_input_file
from brdfkit.errors import FormatError

__all__ = ["open_safetensors", "check_header", "check_format", "HEADER_LIMIT"]

HEADER_LIMIT = 100 * 1024 * 1024  # safetensors' own limit on the JSON header
_MERL_FILE_SIZE = 34_992_012  # brdfkit.io.merl.MERL_FILE_SIZE, without importing the reader


def check_header(path: str, kind: str, merl_hint: str = "") -> None:
    """Refuse a file that is not safetensors before the parser sees it, with a message
    that says what it looks like.

    Parameters
    ----------
    path
        A readable file.
    kind
        What the file should be, for the messages (``"brdfkit model file"``).
    merl_hint
        Appended to the message for a MERL table given instead (which option takes what).

    Raises
    ------
    FormatError
        Too short, a pickle / ``torch.save`` file, a MERL table, a bad header length, a
        header that is not safetensors JSON, or a file shorter than its header says.
    """
    size = os.path.getsize(path)
    with open(path, "rb") as f:
        head = f.read(8)
        if size < 8:
            raise FormatError(path, f"not a {kind}: {size} bytes, too short for a safetensors header")
        # A safetensors header is a JSON object right after its 8-byte length, whose low
        # byte is 0x80 (the pickle opcode PROTO) in one file of 32: not a pickle then.
        if (head[:1] == b"\x80" or head[:2] == b"PK") and f.read(1) != b"{":
            raise FormatError(path, f"not a {kind}: this is a pickle / torch.save file, which brdfkit "
                                    f"never loads ({kind.removeprefix('brdfkit ')}s are .safetensors)")
        n = int.from_bytes(head, "little")
        if head[:4] == b"\x5a\x00\x00\x00" and size == _MERL_FILE_SIZE:
            raise FormatError(path, f"is a MERL BRDF table, not a {kind}{merl_hint}")
        if n > HEADER_LIMIT or n < 2:
            raise FormatError(path, f"not a {kind}: not a safetensors file (bad header length)")
        if 8 + n > size:
            raise FormatError(path, f"truncated: {size} bytes, the safetensors header alone needs {8 + n}")
        try:
            f.seek(8)
            header = json.loads(f.read(n))
            ends = [int(v["data_offsets"][1]) for k, v in header.items() if k != "__metadata__"]
        except (ValueError, TypeError, KeyError, IndexError, AttributeError, UnicodeDecodeError):
            raise FormatError(path, f"not a {kind}: not a safetensors file (header is not "
                                    f"safetensors JSON)") from None
    need = 8 + n + max(ends, default=0)
    if size < need:
        raise FormatError(path, f"truncated: {size} bytes, its safetensors header describes {need}")


@contextlib.contextmanager
def open_safetensors(path: str | os.PathLike, *, framework: str = "numpy", diagnose: str | None = None,
                     merl_hint: str = "") -> Iterator:
    """Open a safetensors file for reading, every failure a one-line ``FormatError``.

    Parameters
    ----------
    path
        The file.
    framework
        ``"numpy"`` or ``"pt"`` (tensors come back as NumPy arrays or torch tensors, on
        the CPU).
    diagnose
        When given (what the file should be, ``"brdfkit model file"``), run
        :func:`check_header` first, so that a pickle, a MERL table or a truncated file
        is named as such rather than by the parser's words.
    merl_hint
        See :func:`check_header`.

    Yields
    ------
    safetensors.safe_open
        The open file (``metadata()``, ``keys()``, ``get_tensor(name)``). A
        ``FormatError`` raised inside the block passes unchanged; a parser, OS or value
        error becomes ``FormatError(path, "not a valid safetensors file (...)")``.

    Raises
    ------
    InputError
        The path is missing or not a regular file.
    """
    from safetensors import SafetensorError, safe_open

    path = check_input_file(path)
    if diagnose:
        check_header(path, diagnose, merl_hint)
    try:
        with safe_open(path, framework=framework, device="cpu") as f:
            yield f
    except FormatError:  # the caller's own (a ValueError too): not to be wrapped again
        raise
    except (SafetensorError, OSError, ValueError) as e:
        first = (str(e).splitlines() or [type(e).__name__])[0]
        raise FormatError(path, f"not a valid safetensors file ({first})") from None


def check_format(path: str, f, fmt: str, version: str, kind: str, short: str) -> dict:
    """The metadata of an open file (:func:`open_safetensors`), after checking that its
    ``format`` is ``fmt`` and its ``version`` is ``version``.

    Parameters
    ----------
    kind, short
        The format's name in messages: ``"brdfkit model file"`` (another format) and
        ``"model file"`` (another version).

    Raises
    ------
    FormatError
        Another format, or a version this brdfkit does not read.
    """
    md = f.metadata() or {}
    if md.get("format") != fmt:
        raise FormatError(path, f"not a {kind} (format {md.get('format')!r}, expected {fmt!r})")
    if md.get("version") != version:
        raise FormatError(path, f"{short} version {md.get('version')!r} is not supported "
                                f"(this brdfkit reads version {version})")
    return md
