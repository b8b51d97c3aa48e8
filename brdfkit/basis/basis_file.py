"""The PCA basis file (format ``brdfkit-basis``; files of the older name ``brdfkit-ipca``
are read the same): safetensors, never pickle.

Tensors ``cells`` (int64 ``(P,)``, sorted flat MERL indices) or, in compact files,
``cell_mask`` (the grid's cells as a bit mask), ``reference``, ``mean``, ``components``
(float32, or float16 in compact files; or int8 ``components`` with float32
``component_scales``, :func:`~brdfkit.basis.storage.quantize`) and ``sigma`` (float32) as
:class:`~brdfkit.basis.model.PcaBasis`
holds them; metadata the format, its version, ``n_components``, the mapping's ``eps`` and,
for a mapping that resolves the grazing cells, its ``eps_share``
(:class:`~brdfkit.basis.mapping.LogMapping`; absent: Nielsen's mapping),
``phi_d_stride`` (1, or 2 for every other ``phi_d`` cell, :mod:`brdfkit.basis.storage`), ``dtype`` and
the training ``materials`` (JSON). The same tensors and metadata, prefixed, hold the basis
inside a learnt-prior model file (:mod:`brdfkit.prior.prior_file`).
"""

from __future__ import annotations

import json
import os

import numpy as np

from brdfkit.atomic import atomic_path, check_input_file
from brdfkit.errors import FormatError
from brdfkit.geometry import N_CELLS, N_PHI_D, grid_cosine_weight
from brdfkit.basis.mapping import LogMapping
from brdfkit.basis.model import EPS, PcaBasis
from brdfkit.basis.storage import (GRAZING_FULL, INT8_BLOCK, Compact, check_half, compact, dequantize, expand,
                                   expansion, pack_rows, quantize, unpack_rows)

__all__ = ["BASIS_FORMAT", "BASIS_VERSION", "basis_tensors", "is_basis_format", "save_basis", "load_basis",
           "read_basis", "read_components", "storage_of"]

BASIS_FORMAT = "brdfkit-basis"
BASIS_VERSION = "2"
_FORMATS = (BASIS_FORMAT, "brdfkit-ipca")  # the format's first name, when the basis was filed under IPCA
_READS = ("1", "2")  # version 2 adds the optional float16, int8 and half-phi_d storage
_TENSORS = ("cells", "reference", "mean", "components", "sigma")


def is_basis_format(fmt) -> bool:
    """Whether a safetensors header's ``format`` is a basis file's (either of its names)."""
    return fmt in _FORMATS


def save_basis(path: str | os.PathLike, basis: PcaBasis, *, half: bool = False, phi_stride: int = 1,
              int8: bool = False, deflate: bool = False) -> None:
    """Write ``basis`` as one safetensors file (format ``brdfkit-basis``), atomically;
    ``half``, ``phi_stride``, ``int8`` and ``deflate`` as :func:`basis_tensors` takes them."""
    from brdfkit.io.tensorfile import write_safetensors

    tensors, meta = basis_tensors(basis, half=half, phi_stride=phi_stride, int8=int8, deflate=deflate,
                                  where=os.fspath(path))
    with atomic_path(path, verify=load_basis) as tmp:
        write_safetensors(tmp, tensors, meta)


def basis_tensors(basis: PcaBasis, *, half: bool = False, phi_stride: int = 1, int8: bool = False,
                  deflate: bool = False, prefix: str = "", where: str = "basis") -> tuple[dict, dict]:
    """The tensors and metadata of the file of ``basis`` (names prefixed with ``prefix``
    when it is stored inside another model file); ``where`` names it in errors.

    ``half`` stores the per-cell tensors in float16 and ``phi_stride = 2`` only the
    cells of even ``phi_d`` index (:mod:`.storage`): together a quarter of the size, for
    the bases shipped with the package. ``int8`` (with ``half``) stores the components in
    int8 with a scale per block of cells (:func:`~.storage.quantize`): half again. The
    reader restores the full grid the same way every time, so a model trained on the
    restored basis sees exactly what it is shipped with. ``deflate`` (with ``int8``) stores
    the int8 components losslessly deflated, a component at a time
    (:func:`~.storage.pack_rows`: tensors ``components_deflated`` and
    ``component_offsets``): the same decoded bytes in about a third of the space.
    """
    if int8 and not half:
        raise ValueError("int8 storage of a basis goes with half (float16 reference and mean)")
    if deflate and not int8:
        raise ValueError("deflated storage of a basis goes with int8 components")
    cells, per_cell = compact(basis.cells, [basis.reference, basis.mean, basis.components], phi_stride)
    if half:
        check_half(where, per_cell)
    dtype = np.float16 if half else np.float32
    # Compact files name their cells by a bit mask over the grid (0.18 MB), not by
    # int64 indices (4.4 MB for half the grid).
    where_cells = ({"cell_mask": np.packbits(np.isin(np.arange(N_CELLS), cells))} if half or phi_stride != 1
                   else {"cells": np.ascontiguousarray(cells, dtype=np.int64)})
    comps = quantize(per_cell[2]) if int8 else (np.ascontiguousarray(per_cell[2], dtype=dtype), None)
    if deflate:
        blob, offsets = pack_rows(comps[0])
        stored = {"components_deflated": blob, "component_offsets": offsets}
    else:
        stored = {"components": comps[0]}
    tensors = {**where_cells,
               "reference": np.ascontiguousarray(per_cell[0], dtype=dtype),
               "mean": np.ascontiguousarray(per_cell[1], dtype=dtype),
               **stored,
               **({"component_scales": comps[1]} if int8 else {}),
               "sigma": np.ascontiguousarray(basis.sigma, dtype=np.float32)}
    meta = {"format": BASIS_FORMAT, "version": BASIS_VERSION,
            "n_components": str(basis.n_components), "eps": repr(EPS),
            "weight": "cos_i*cos_o" if not basis.w_floor else "max(cos_i*cos_o, w_floor)",
            **({"w_floor": repr(float(basis.w_floor))} if basis.w_floor else {}),
            **basis.mapping.record(),
            "channels": "separate observations, shared basis",
            "phi_d_stride": str(int(phi_stride)),
            "dtype": "int8-deflated" if deflate else "int8" if int8 else "float16" if half else "float32",
            "materials": json.dumps(list(basis.materials))}
    return ({prefix + k: v for k, v in tensors.items()}, {prefix + k: v for k, v in meta.items()})


def storage_of(meta: dict, prefix: str = "") -> dict:
    """How a basis file's metadata (keys ``prefix + name``) says it is stored: the
    ``half``, ``phi_stride`` and ``int8`` arguments of :func:`basis_tensors`."""
    dtype = meta.get(prefix + "dtype")
    return {"half": dtype in ("float16", "int8", "int8-deflated"),
            "phi_stride": int(meta.get(prefix + "phi_d_stride", "1")), "int8": dtype in ("int8", "int8-deflated"),
            "deflate": dtype == "int8-deflated"}


def load_basis(path: str | os.PathLike) -> PcaBasis:
    """Read a basis written by :func:`save_basis`.

    Raises
    ------
    FormatError
        Not a safetensors file, another format or version, missing or inconsistent
        tensors, non-finite values.
    """
    from brdfkit.io.tensorfile import open_safetensors

    path = check_input_file(path)
    with open_safetensors(path) as f:
        return read_basis(f, path)


def read_components(path: str | os.PathLike) -> int:
    """The number of components a basis file holds, from its header alone (the shape of
    its ``sigma``; no tensor is read), its format checked.

    Raises
    ------
    FormatError
        Not a safetensors file, another format, no ``sigma`` of one dimension.

    Examples
    --------
    >>> from brdfkit.testing.examples import tiny_basis_file
    >>> read_components(tiny_basis_file("tiny-basis.safetensors", components=4))
    4
    """
    from brdfkit.io.tensorfile import open_safetensors

    path = check_input_file(path)
    with open_safetensors(path) as f:
        fmt = (f.metadata() or {}).get("format")
        if fmt not in _FORMATS:
            raise FormatError(path, f"not a brdfkit PCA basis (format {fmt!r}, expected {BASIS_FORMAT!r})")
        shape = f.get_slice("sigma").get_shape() if "sigma" in f.keys() else []
    if len(shape) != 1 or shape[0] < 1:
        raise FormatError(path, "PCA basis tensor 'sigma' is missing or not one number a component")
    return int(shape[0])


def read_basis(f, path: str, prefix: str = "") -> PcaBasis:
    """The basis in an open safetensors file ``f`` (tensors and metadata keys named
    ``prefix + name``: a basis stored inside another model file); errors name ``path``."""
    meta = {k[len(prefix):]: v for k, v in (f.metadata() or {}).items() if k.startswith(prefix)}
    if meta.get("format") not in _FORMATS:
        raise FormatError(path, f"not a brdfkit PCA basis (format {meta.get('format')!r}, "
                                f"expected {BASIS_FORMAT!r})")
    if meta.get("version") not in _READS:
        raise FormatError(path, f"PCA basis version {meta.get('version')!r} is not supported "
                                f"(this brdfkit reads versions {', '.join(_READS)})")
    stride = meta.get("phi_d_stride", "1")
    if stride not in ("1", "2"):
        raise FormatError(path, f"PCA basis phi_d_stride {stride!r} is not 1 or 2")
    keys = set(f.keys())
    deflated = meta.get("dtype") == "int8-deflated"
    missing = [k for k in _TENSORS if prefix + k not in keys and not (k == "cells" and prefix + "cell_mask" in keys)
               and not (k == "components" and deflated)]
    if missing:
        raise FormatError(path, f"PCA basis lacks tensor(s) {', '.join(missing)}")
    t = {k: f.get_tensor(prefix + k) for k in _TENSORS if prefix + k in keys}
    if "cells" not in t:
        mask = f.get_tensor(prefix + "cell_mask")
        if mask.dtype != np.uint8 or mask.shape != ((N_CELLS + 7) // 8,):
            raise FormatError(path, "PCA basis cell mask is not a bit mask of the MERL grid")
        t["cells"] = np.flatnonzero(np.unpackbits(mask)[:N_CELLS]).astype(np.int64)
    if deflated:
        t["components"] = _deflated(f, prefix, path, t)
    if meta.get("dtype") in ("int8", "int8-deflated"):
        if prefix + "component_scales" not in keys:
            raise FormatError(path, "an int8 PCA basis lacks tensor 'component_scales'")
        scales, comp = f.get_tensor(prefix + "component_scales"), t["components"]
        if (comp.dtype != np.int8 or comp.ndim != 2 or scales.ndim != 2 or scales.shape[0] != comp.shape[0]
                or scales.shape[1] != -(-comp.shape[1] // INT8_BLOCK)):
            raise FormatError(path, "int8 PCA basis components and their scales have inconsistent types or shapes")
        if not np.isfinite(scales).all():
            raise FormatError(path, "PCA basis tensor 'component_scales' holds non-finite values")
        t["components"] = comp  # int8, dequantized a row block at a time when used
    cells, comp = t["cells"], t["components"]
    p = cells.shape[0] if cells.ndim == 1 else -1
    if (cells.ndim != 1 or comp.ndim != 2 or comp.shape[1] != p or t["reference"].shape != (p,)
            or t["mean"].shape != (p,) or t["sigma"].shape != (comp.shape[0],) or comp.shape[0] < 1):
        raise FormatError(path, "PCA basis tensors have inconsistent shapes")
    if p == 0 or cells.min() < 0 or cells.max() >= N_CELLS or (np.diff(cells) <= 0).any():
        raise FormatError(path, "PCA basis cell indices are not sorted indices of the MERL grid")
    for k in ("reference", "mean", "components", "sigma"):
        if t[k].dtype != np.int8 and not np.isfinite(t[k]).all():
            raise FormatError(path, f"PCA basis tensor {k!r} holds non-finite values")
    if not (t["sigma"] > 0).all():
        raise FormatError(path, "PCA basis tensor 'sigma' must be positive")
    try:
        materials = json.loads(meta.get("materials", "[]"))
    except json.JSONDecodeError:
        raise FormatError(path, "PCA basis metadata 'materials' is not JSON") from None
    # found by benchmarks/fuzz_parsers.py: 'materials' = "5" raised a TypeError below
    if not isinstance(materials, list) or not all(isinstance(m, str) for m in materials):
        raise FormatError(path, "PCA basis metadata 'materials' is not a list of names")
    try:
        w_floor = float(meta.get("w_floor", "0"))
    except ValueError:
        raise FormatError(path, f"PCA basis metadata 'w_floor' is not a number: {meta.get('w_floor')!r}") from None
    if not 0.0 <= w_floor < 1.0:
        raise FormatError(path, f"PCA basis metadata 'w_floor' must be in [0, 1), got {w_floor!r}")
    try:
        mapping = LogMapping.from_record(meta)
    except ValueError as err:
        raise FormatError(path, f"PCA basis metadata: {err} (a share in [0, 1))") from None
    cells = cells.astype(np.int64)
    per_cell = [t["reference"].astype(np.float32), t["mean"].astype(np.float32)]
    stored_cells, packed = cells, None
    if comp.dtype == np.int8:  # int8, or int8 deflated
        scales = f.get_tensor(prefix + "component_scales")

        def stored(k, comp=comp, scales=scales):
            return dequantize(comp[:k], scales[:k])
    else:
        def stored(k, comp=comp):
            return comp[:k].astype(np.float32)
    rows = stored
    if stride == "2":
        odd = (cells % N_PHI_D) % 2 == 1
        if (grid_cosine_weight()[cells[odd]] >= GRAZING_FULL).any():
            raise FormatError(path, "a half-phi_d PCA basis may hold odd phi_d cells only near the horizon "
                                    f"(cosine weight below {GRAZING_FULL})")
        how = expansion(cells)
        packed = Compact(stored, per_cell[1], how)
        cells, per_cell = expand(cells, per_cell, how)

        def rows(k, packed=packed, how=how):
            return expand(stored_cells, [packed.rows(k)], how)[1][0]
    sigma = t["sigma"].astype(np.float32)
    if comp.dtype != np.int8 and stride != "2":  # float32 or float16, all cells
        return PcaBasis(cells, *per_cell, rows(comp.shape[0]), sigma, list(materials), w_floor, mapping)
    # Compact storage: a component is restored when first used (an embedding of 13 of 30
    # components restores 13: 0.3 s of a decode process, not 0.7).
    return PcaBasis.deferred(cells, *per_cell, rows, sigma, list(materials), w_floor,
                             compact=packed, mapping=mapping)



class _DeflatedRows:
    """int8 components ``(K, P)`` stored deflated (:func:`~.storage.pack_rows`): what the
    reader takes of an int8 array (``dtype``, ``ndim``, ``shape``, the leading rows
    ``[:k]``), each leading block of rows inflated when asked for."""

    dtype = np.dtype(np.int8)
    ndim = 2

    def __init__(self, blob, offsets, shape, path):
        self.blob, self.offsets, self.shape, self.path = blob, offsets, shape, path

    def __getitem__(self, rows):
        if not isinstance(rows, slice) or rows.start not in (None, 0) or rows.step not in (None, 1):
            raise TypeError("deflated components are read by their leading rows, [:k]")
        k = min(self.shape[0], self.shape[0] if rows.stop is None else int(rows.stop))
        try:
            return unpack_rows(self.blob, self.offsets, k, self.shape[1])
        except ValueError as e:
            raise FormatError(self.path, f"PCA basis deflated components: {e}") from None


def _deflated(f, prefix: str, path: str, t: dict) -> _DeflatedRows:
    """The deflated components of an open basis file, their layout checked."""
    keys = set(f.keys())
    if prefix + "components_deflated" not in keys or prefix + "component_offsets" not in keys:
        raise FormatError(path, "a deflated PCA basis lacks tensor 'components_deflated' or 'component_offsets'")
    blob, offsets = f.get_tensor(prefix + "components_deflated"), f.get_tensor(prefix + "component_offsets")
    k = t["sigma"].shape[0] if t["sigma"].ndim == 1 else -1
    if (blob.dtype != np.uint8 or blob.ndim != 1 or offsets.dtype != np.int64 or offsets.shape != (k + 1,)
            or offsets[0] != 0 or (np.diff(offsets) <= 0).any() or offsets[-1] != blob.shape[0]):
        raise FormatError(path, "PCA basis deflated components and their offsets have inconsistent types or shapes")
    return _DeflatedRows(blob, offsets, (k, t["cells"].shape[0]), path)
