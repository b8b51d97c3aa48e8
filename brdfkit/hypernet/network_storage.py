"""Compact storage of a network file's tensors: the reference table at its measured cells,
half precision, and a reference table shared by several network files.

A dense reference table (Gokbudak et al. 2024, eq. 1: ``rho_ref``, the per-cell median
of the training materials) is float32 ``(90, 90, 180, 3)``, 17.5 MB, more than twice the
weights of the default network (1.73 M numbers, 6.9 MB). About a quarter of its cells lie
below the horizon and are never measured (NaN), so a version 2 network file
(``docs/formats.md``) stores it as

* ``rho_ref_mask``: uint8 ``(182250,)``, ``numpy.packbits`` (little bit order) of the
  1,458,000 cells, in flat-index order, that hold a finite value in some channel;
* ``rho_ref_values``: float32 or float16 ``(n, 3)``: the RGB values of those cells, 1/sr
  (NaN kept in a channel that alone is unmeasured);

and optionally in float16 (``half``), weights included. Models trained on the same
materials have the same reference, so a file may instead name a *shared reference file*
beside it (format ``brdfkit-model-reference``) holding those two tensors once.

Every compact reference carries a digest (:func:`reference_digest`) in the network file, so
a damaged or swapped reference is refused like damaged weights.
"""

from __future__ import annotations

import hashlib
import json
import os

import numpy as np

from brdfkit.atomic import atomic_path
from brdfkit.errors import FormatError
from brdfkit.geometry import N_CELLS, TABLE_SHAPE
from brdfkit.io.tensorfile import check_format, open_safetensors

__all__ = ["SHARED_FORMAT", "SHARED_VERSION", "F16_MAX", "half_state", "pack_reference",
           "unpack_reference", "reference_digest", "write_shared_reference", "read_shared_reference",
           "reference_record", "parse_reference_record"]

SHARED_FORMAT = "brdfkit-model-reference"
SHARED_VERSION = "1"
MASK, VALUES = "rho_ref_mask", "rho_ref_values"
# The largest finite float16; a weight or reference value beyond it would become inf.
F16_MAX = float(np.finfo(np.float16).max)
_DTYPES = {"float16": np.float16, "float32": np.float32}


def half_state(state: dict) -> dict:
    """A state dict's tensors rounded to float16 (CPU, contiguous).

    Raises
    ------
    ValueError
        A finite value beyond float16's range (65504), which would become infinite.
    """
    import torch

    out = {}
    for name, t in state.items():
        t = t.detach().cpu().float()
        if bool((t.abs() > F16_MAX).logical_and(torch.isfinite(t)).any()):
            raise ValueError(f"tensor {name} holds values beyond float16's range ({F16_MAX:g}); save it in float32")
        out[name] = t.half().contiguous()
    return out


def reference_digest(mask: np.ndarray, values: np.ndarray) -> str | None:
    """sha256 hex of a packed reference: the mask bytes, the values' dtype name, then the
    values' bytes (C order, little-endian), as stored; ``None`` for arrays of kinds
    brdfkit never writes."""
    if mask.dtype != np.uint8 or values.dtype not in (np.float16, np.float32):
        return None
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(mask).tobytes())
    h.update(values.dtype.name.encode())
    h.update(np.ascontiguousarray(values, dtype=values.dtype.newbyteorder("<")).tobytes())
    return h.hexdigest()


def pack_reference(rho_ref: np.ndarray, half: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """``(mask, values)`` of a reference table: its measured cells only.

    Parameters
    ----------
    rho_ref
        ``(90, 90, 180, 3)`` reference table, 1/sr, NaN where unmeasured.
    half
        Store the values as float16 (relative error at most ``2^-11``, absolute below
        ``6e-8`` 1/sr for tiny values: far below the mapping's ``eps = 0.002``).

    Returns
    -------
    tuple
        uint8 ``(182250,)`` packed cell mask, float32 or float16 ``(n, 3)`` values.

    Raises
    ------
    ValueError
        Another shape, or (``half``) a value beyond float16's range.
    """
    ref = np.asarray(rho_ref, dtype=np.float32)
    if ref.shape != TABLE_SHAPE:
        raise ValueError(f"reference table must have shape {TABLE_SHAPE}, not {ref.shape}")
    flat = ref.reshape(N_CELLS, 3)
    cells = np.isfinite(flat).any(axis=1)
    values = np.ascontiguousarray(flat[cells])
    if half:
        finite = values[np.isfinite(values)]
        if finite.size and float(np.abs(finite).max()) > F16_MAX:
            raise ValueError(f"the reference table holds values beyond float16's range ({F16_MAX:g}); "
                             "save it in float32")
        values = values.astype(np.float16)
    return np.packbits(cells, bitorder="little"), values


def unpack_reference(where: str, mask, values) -> np.ndarray:
    """The dense float32 ``(90, 90, 180, 3)`` table of :func:`pack_reference`'s output.

    Raises
    ------
    FormatError
        (naming ``where``) a mask of another size or dtype, values of another dtype or a
        row count other than the mask's number of cells.
    """
    mask, values = np.asarray(mask), np.asarray(values)
    n_bytes = (N_CELLS + 7) // 8
    if mask.dtype != np.uint8 or mask.shape != (n_bytes,):
        raise FormatError(where, f"tensor {MASK} is {mask.dtype} {mask.shape}, expected uint8 ({n_bytes},)")
    if values.dtype not in (np.float16, np.float32) or values.ndim != 2 or values.shape[1] != 3:
        raise FormatError(where, f"tensor {VALUES} is {values.dtype} {values.shape}, expected float16 or "
                                 f"float32 (n, 3)")
    cells = np.unpackbits(mask, count=N_CELLS, bitorder="little").astype(bool)
    n = int(cells.sum())
    if values.shape[0] != n:
        raise FormatError(where, f"tensor {VALUES} has {values.shape[0]} rows, its mask marks {n} cells")
    out = np.full((N_CELLS, 3), np.nan, dtype=np.float32)
    out[cells] = values.astype(np.float32)
    return out.reshape(TABLE_SHAPE)


def write_shared_reference(path: str | os.PathLike, mask: np.ndarray, values: np.ndarray,
                           materials=()) -> str:
    """Write a shared reference file (format ``brdfkit-model-reference``) atomically and
    return its digest."""
    from brdfkit.io.tensorfile import write_safetensors

    digest = reference_digest(mask, values)
    meta = {"format": SHARED_FORMAT, "version": SHARED_VERSION, "digest": digest,
            "materials": json.dumps(list(materials))}
    with atomic_path(path, verify=read_shared_reference) as tmp:
        write_safetensors(tmp, {MASK: np.ascontiguousarray(mask), VALUES: np.ascontiguousarray(values)}, meta)
    return digest


def read_shared_reference(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray, str]:
    """``(mask, values, digest)`` of a shared reference file, its digest recomputed.

    Raises
    ------
    FormatError
        Not such a file, missing tensors, or contents that do not match the digest it
        records.
    """
    path = os.fspath(path)
    with open_safetensors(path, framework="numpy", diagnose="brdfkit model reference") as f:
        md = check_format(path, f, SHARED_FORMAT, SHARED_VERSION, "brdfkit model reference", "model reference")
        missing = sorted({MASK, VALUES} - set(f.keys()))
        if missing:
            raise FormatError(path, f"missing tensor {missing[0]}")
        mask, values = f.get_tensor(MASK), f.get_tensor(VALUES)
    digest = reference_digest(mask, values)
    if md.get("digest") != digest:
        raise FormatError(path, "contents do not match the recorded digest: the file is damaged or was altered")
    unpack_reference(path, mask, values)  # checks the shapes
    return mask, values, digest


def reference_record(storage: str, values: np.ndarray, digest: str, file: str | None = None) -> str:
    """The ``reference`` metadata entry of a version 2 network file (JSON)."""
    rec = {"storage": storage, "dtype": values.dtype.name, "digest": digest}
    if file is not None:
        rec["file"] = file
    return json.dumps(rec, sort_keys=True)


def parse_reference_record(path: str, text) -> dict:
    """The ``reference`` metadata entry of a version 2 network file, checked.

    Raises
    ------
    FormatError
        Absent, not JSON, an unknown storage, or a shared file named by a path rather
        than a bare file name (a network file may only point beside itself).
    """
    try:
        rec = json.loads(text) if isinstance(text, str) else None
    except ValueError:
        rec = None
    if not isinstance(rec, dict) or rec.get("storage") not in ("cells", "file") \
            or not isinstance(rec.get("digest"), str):
        raise FormatError(path, "bad or missing 'reference' in metadata (a version 2 model file records how "
                                "its reference table is stored)")
    if rec["storage"] == "file":
        name = rec.get("file")
        if not isinstance(name, str) or not name or os.path.basename(name) != name or name in (".", "..") \
                or "/" in name or "\\" in name:
            raise FormatError(path, f"bad shared reference file name {name!r} in metadata (a bare file name "
                                    "beside the model)")
    return rec
