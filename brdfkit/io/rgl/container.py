"""Mitsuba's tensor file: the container of RGL ``.bsdf`` files.

The layout (Mitsuba 3 ``src/core/tensor.cpp``, ``mitsuba.tensor_io``; the reference
``powitacq`` loader of Dupuy and Jakob 2018), little-endian:

======================= ===================================================================
bytes                   what
======================= ===================================================================
12                      the magic ``b"tensor_file\\0"``
2                       version ``(1, 0)``
uint32                  number of fields
per field               uint16 name length, the UTF-8 name, uint16 rank, uint8 dtype code,
                        uint64 byte offset of the data, ``rank`` x uint64 shape
data                    each field's values, C order, at its offset (8-byte aligned here)
======================= ===================================================================

The dtype codes are those of :data:`DTYPES` (uint8 = 1 ... float64 = 11).
:func:`read_tensor_file` checks everything a malformed file can get wrong (magic,
version, a field table or data running past the end, unknown codes, repeated names) and
refuses it in one line; :func:`write_tensor_file` writes atomically.

May import: the ground floor and numpy.
"""

from __future__ import annotations

import struct

import numpy as np

from brdfkit.atomic import atomic_path, check_input_file
from brdfkit.errors import FormatError

__all__ = ["MAGIC", "VERSION", "DTYPES", "read_tensor_file", "write_tensor_file"]

MAGIC = b"tensor_file\0"
VERSION = (1, 0)
DTYPES = {1: np.uint8, 2: np.int8, 3: np.uint16, 4: np.int16, 5: np.uint32, 6: np.int32,
          7: np.uint64, 8: np.int64, 9: np.float16, 10: np.float32, 11: np.float64}
"""Tensor-file dtype code -> NumPy dtype (Mitsuba's ``Struct::Type`` numbering)."""
_CODES = {np.dtype(t).newbyteorder("<"): c for c, t in DTYPES.items()}
_HEAD = len(MAGIC) + 2 + 4
MAX_RANK = 16
MAX_FIELDS = 4096


def _unpack(raw: bytes, pos: int, fmt: str, path: str, what: str):
    size = struct.calcsize(fmt)
    if pos + size > len(raw):
        raise FormatError(path, f"truncated: {len(raw)} bytes, the field table ends inside {what}")
    return struct.unpack_from(fmt, raw, pos), pos + size


def read_tensor_file(path, kind: str = "a tensor file") -> dict:
    """Read a tensor file.

    Parameters
    ----------
    path
        The file.
    kind
        What the file should be, for the messages (``"an RGL .bsdf file"``).

    Returns
    -------
    dict
        Field name -> NumPy array of its dtype and shape (a copy: the file is closed).

    Raises
    ------
    FormatError
        Too short, another magic or version, a field table or data past the end of the
        file, an unknown dtype code, a name that is not UTF-8 or given twice.
    """
    path = check_input_file(path)
    with open(path, "rb") as f:
        raw = f.read()
    if len(raw) < _HEAD:
        raise FormatError(path, f"not {kind}: {len(raw)} bytes, too short for the {_HEAD}-byte header")
    if raw[:len(MAGIC)] != MAGIC:
        raise FormatError(path, f"not {kind}: no 'tensor_file' magic at the start")
    version = tuple(raw[12:14])
    if version != VERSION:
        raise FormatError(path, f"tensor file version {version[0]}.{version[1]} is not supported "
                                f"(this brdfkit reads version {VERSION[0]}.{VERSION[1]})")
    (n_fields,), pos = _unpack(raw, 14, "<I", path, "the header")
    if n_fields > MAX_FIELDS:
        raise FormatError(path, f"not {kind}: {n_fields} fields in its header")
    fields = {}
    for i in range(n_fields):
        (n_name,), pos = _unpack(raw, pos, "<H", path, f"field {i}")
        if pos + n_name > len(raw):
            raise FormatError(path, f"truncated: {len(raw)} bytes, the field table ends inside field {i}")
        try:
            name = raw[pos:pos + n_name].decode("utf-8")
        except UnicodeDecodeError:
            raise FormatError(path, f"not {kind}: the name of field {i} is not UTF-8") from None
        pos += n_name
        shown = name if name.isprintable() else repr(name)
        (rank, code, offset), pos = _unpack(raw, pos, "<HBQ", path, f"field {shown!r}")
        if rank > MAX_RANK:
            raise FormatError(path, f"field {shown!r}: rank {rank}, at most {MAX_RANK} expected")
        shape, pos = _unpack(raw, pos, f"<{rank}Q", path, f"field {shown!r}")
        if code not in DTYPES:
            raise FormatError(path, f"field {shown!r}: unknown dtype code {code}")
        if name in fields:
            raise FormatError(path, f"field {shown!r} is given twice")
        if any(int(n) > len(raw) for n in shape):  # an empty field may not claim any shape
            raise FormatError(path, f"field {shown!r}: shape {tuple(int(n) for n in shape)} is larger than "
                                    f"the file ({len(raw)} bytes)")
        dtype = np.dtype(DTYPES[code]).newbyteorder("<")
        count = 1
        for n in shape:
            count *= int(n)
        end = offset + count * dtype.itemsize
        if end > len(raw):
            raise FormatError(path, f"truncated: {len(raw)} bytes, field {shown!r} "
                                    f"{tuple(int(n) for n in shape)} needs {end}")
        fields[name] = np.frombuffer(raw, dtype, count, offset).reshape(tuple(int(n) for n in shape)).copy()
    return fields


def write_tensor_file(path, fields: dict, align: int = 8) -> None:
    """Write ``fields`` (name -> array, or ``str`` stored as uint8 UTF-8) as a tensor file,
    atomically (a temporary file beside ``path``, renamed when complete).

    Parameters
    ----------
    path
        Output file.
    fields
        In the order they are to be stored; arrays of a dtype of :data:`DTYPES`.
    align
        Byte alignment of each field's data.
    """
    arrays = {}
    for name, value in fields.items():
        if isinstance(value, str):
            value = np.frombuffer(value.encode("utf-8"), np.uint8)
        arrays[name] = np.ascontiguousarray(value, dtype=np.dtype(value.dtype).newbyteorder("<"))
    table_size = _HEAD + sum(2 + len(n.encode()) + 2 + 1 + 8 + 8 * a.ndim for n, a in arrays.items())
    offsets, pos = {}, table_size
    for name, a in arrays.items():
        pos = (pos + align - 1) // align * align
        offsets[name] = pos
        pos += a.nbytes
    out = bytearray(pos)
    out[:_HEAD] = MAGIC + bytes(VERSION) + struct.pack("<I", len(arrays))
    at = _HEAD
    for name, a in arrays.items():
        label = name.encode("utf-8")
        entry = struct.pack("<H", len(label)) + label + struct.pack("<HBQ", a.ndim, _CODES[a.dtype], offsets[name])
        entry += struct.pack(f"<{a.ndim}Q", *a.shape)
        out[at:at + len(entry)] = entry
        at += len(entry)
        out[offsets[name]:offsets[name] + a.nbytes] = a.tobytes()
    with atomic_path(path, verify=read_tensor_file) as tmp:
        with open(tmp, "wb") as f:
            f.write(out)
    return None

