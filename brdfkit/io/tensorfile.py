"""Reading and writing brdfkit's safetensors files (network files, reference tables, PCA
bases, learnt priors, residuals) safely and reproducibly.

`safetensors <https://github.com/huggingface/safetensors>`_ holds tensors and string
metadata and never runs code: brdfkit stores every array it writes this way and never
unpickles. :func:`open_safetensors` is the one place that opens such a file: it checks
that the path is a readable file, optionally diagnoses what a file that is *not*
safetensors looks like (a pickle, a MERL table, a truncated file; :func:`check_header`),
and turns every parser error into a one-line :class:`~brdfkit.errors.FormatError` that
names the file. The format-specific checks (metadata ``format`` / ``version``, tensor
names and shapes) stay with each format's reader; :func:`check_format` checks the
``format`` and ``version`` metadata every brdfkit file carries.

:func:`write_safetensors` is the one writer: the safetensors library's ``save_file``
serialises the metadata in the order of a Rust hash map, which changes from process to
process, so the same tensors gave files of other bytes (and other SHA-256 digests, which
embeddings name their decoders by). This writer orders the header's keys.
"""

from __future__ import annotations

import contextlib
import json
import os
from typing import Iterator

import numpy as np

from brdfkit.atomic import check_input_file
from brdfkit.errors import FormatError

__all__ = ["open_safetensors", "check_header", "check_format", "write_safetensors", "HEADER_LIMIT"]

HEADER_LIMIT = 100 * 1024 * 1024  # safetensors' own limit on the JSON header
_MERL_FILE_SIZE = 34_992_012  # brdfkit.io.merl.MERL_FILE_SIZE, without importing the reader
_DTYPES = {np.dtype(k): v for k, v in (("float64", "F64"), ("float32", "F32"), ("float16", "F16"), ("int64", "I64"),
                                        ("int32", "I32"), ("int16", "I16"), ("int8", "I8"), ("uint8", "U8"),
                                        ("bool", "BOOL"))}


def write_safetensors(path: str | os.PathLike, tensors: dict, metadata: dict | None = None) -> None:
    """Write ``tensors`` (name -> NumPy array, or a CPU torch tensor) and string
    ``metadata`` as a safetensors file at ``path``, the same bytes for the same input:
    header keys sorted, tensors laid out in name order, the header padded with spaces to a
    multiple of 8 bytes (the format's rule). Not atomic: write into
    :func:`brdfkit.atomic.atomic_path`'s temporary name.

    Examples
    --------
    >>> import tempfile, numpy as np
    >>> from safetensors.numpy import load_file
    >>> path = os.path.join(tempfile.mkdtemp(), "t.safetensors")
    >>> write_safetensors(path, {"b": np.arange(3, dtype=np.int64), "a": np.ones((2, 2), np.float32)}, {"k": "v"})
    >>> sorted(load_file(path))
    ['a', 'b']
    """
    arrays = {}
    for name, t in tensors.items():
        a = t.detach().cpu().numpy() if hasattr(t, "detach") else np.asarray(t)
        if a.dtype not in _DTYPES:
            raise ValueError(f"tensor {name}: dtype {a.dtype} has no safetensors name here")
        arrays[name] = np.ascontiguousarray(a, dtype=a.dtype.newbyteorder("<"))
    header, at = {}, 0
    if metadata:
        header["__metadata__"] = {str(k): str(v) for k, v in sorted(metadata.items())}
    for name in sorted(arrays):
        a = arrays[name]
        header[name] = {"dtype": _DTYPES[a.dtype], "shape": list(a.shape), "data_offsets": [at, at + a.nbytes]}
        at += a.nbytes
    text = json.dumps(header, separators=(",", ":"), sort_keys=False).encode("utf-8")
    text += b" " * (-len(text) % 8)
    with open(path, "wb") as f:
        f.write(len(text).to_bytes(8, "little"))
        f.write(text)
        for name in sorted(arrays):
            f.write(arrays[name].tobytes())


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
        The safetensors file.
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
