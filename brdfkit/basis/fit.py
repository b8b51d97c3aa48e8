"""Fitting the PCA basis of :mod:`brdfkit.basis.model` to training tables (``brdfkit fit --method basis``).

PCA over the cells measured by at least one training table (a training table missing a
cell counts as the reference there, ``x' = 0``); the ``3 M x P`` matrix is centred and
decomposed through its ``3 M x 3 M`` Gram matrix, so the cost is one pass of matrix
products (seconds for 80 materials) and the memory the float32 matrix itself
(``4 * 3 M * P`` bytes, about 1.1 GB for 80 MERL materials).
"""

from __future__ import annotations

import os
import warnings
from typing import Iterable, Sequence

import numpy as np

from brdfkit.errors import InputError
from brdfkit.geometry import GRID_SHAPE, N_CELLS, grid_cosine_weight
from brdfkit.basis.basis_file import save_basis
from brdfkit.basis.mapping import NIELSEN, LogMapping
from brdfkit.basis.model import DEFAULT_COMPONENTS, PcaBasis

__all__ = ["fit_basis", "fit_basis_files"]


def _load_table(item) -> tuple[np.ndarray, str | None]:
    from brdfkit.io.merl import read_merl

    if isinstance(item, (str, os.PathLike)):
        return read_merl(item), os.path.splitext(os.path.basename(os.fspath(item)))[0]
    arr = np.asarray(item)
    if arr.shape != GRID_SHAPE + (3,):
        raise InputError(f"a training table has shape {arr.shape}, expected (90, 90, 180, 3)")
    return arr, None


def fit_basis(tables_or_paths: Iterable, n_components: int = DEFAULT_COMPONENTS,
             names: Sequence[str] | None = None, chunk: int = 1 << 16, w_floor: float = 0.0,
             mapping: LogMapping = NIELSEN) -> PcaBasis:
    """Fit the PCA basis to training tables.

    Parameters
    ----------
    tables_or_paths
        ``(90, 90, 180, 3)`` arrays (1/sr, NaN where not measured) or MERL file paths,
        read one at a time.
    n_components
        Number of principal components ``K`` kept (8 in Nielsen et al.); at most
        ``3 M - 1`` for ``M`` tables.
    names
        Names of the materials for the file's metadata (default: file stems, or
        ``table-<i>`` for arrays).
    chunk
        Cells per block in the median and matrix-product passes.
    w_floor
        Lower bound of the mapping's cosine weight (:class:`PcaBasis`; 0, Nielsen's,
        by default), in ``[0, 1)``.
    mapping
        The log mapping (:class:`~brdfkit.basis.mapping.LogMapping`; Nielsen's by
        default).

    Returns
    -------
    PcaBasis
    """
    items = list(tables_or_paths)
    if not items:
        raise InputError("fitting a PCA basis needs at least one training table")
    n_components = int(n_components)
    if n_components < 1:
        raise InputError(f"number of PCA components must be at least 1, got {n_components}")
    w_floor = float(w_floor)
    if not 0.0 <= w_floor < 1.0:
        raise InputError(f"w_floor must be in [0, 1), got {w_floor!r}")
    rows = 3 * len(items)
    if n_components > rows - 1:
        raise InputError(f"{n_components} PCA components need at least {n_components + 1} training "
                         f"channel vectors (3 per material), got {len(items)} material(s)")
    w_all = grid_cosine_weight()
    cand = np.flatnonzero(w_all > 0)  # cells where both directions are above the horizon
    w = np.maximum(w_all[cand], w_floor).astype(np.float32)
    data = np.empty((rows, cand.size), dtype=np.float32)
    materials = []
    for i, item in enumerate(items):
        table, stem = _load_table(item)
        materials.append(names[i] if names is not None else (stem or f"table-{i}"))
        vals = np.asarray(table, np.float64).reshape(N_CELLS, 3)[cand]
        data[3 * i:3 * i + 3] = (np.clip(vals, 0.0, None).T * w).astype(np.float32)
        del table, vals
    seen = np.isfinite(data).any(axis=0)
    if not seen.all():
        cand, data = cand[seen], data[:, seen]
    if cand.size == 0:
        raise InputError("the training tables have no measured cell in common with the MERL grid")
    p = cand.size
    reference = np.empty(p, dtype=np.float32)
    mean = np.empty(p, dtype=np.float32)
    for s in range(0, p, chunk):
        block = data[:, s:s + chunk]
        if np.isnan(block).any():
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                reference[s:s + chunk] = np.nanmedian(block, axis=0)
        else:
            reference[s:s + chunk] = np.median(block, axis=0)
        ref = reference[s:s + chunk]
        mapping.to_mapped(block, np.float32(1.0), ref, out=block)  # block holds weighted values already
        np.nan_to_num(block, copy=False, nan=0.0)  # a missing value counts as the reference
        mean[s:s + chunk] = block.mean(axis=0, dtype=np.float64)
        block -= mean[s:s + chunk]
    gram = np.zeros((rows, rows), dtype=np.float64)
    for s in range(0, p, chunk):
        block = data[:, s:s + chunk]
        gram += (block @ block.T).astype(np.float64)
    evals, evecs = np.linalg.eigh(gram)
    order = np.argsort(evals)[::-1][:n_components]
    evals, evecs = np.clip(evals[order], 0.0, None), evecs[:, order]
    if evals[-1] <= 1e-12 * max(evals[0], 1e-30):
        raise InputError(f"the training tables span fewer than {n_components} independent directions; "
                         f"use fewer components or more materials")
    components = np.empty((n_components, p), dtype=np.float32)
    proj = (evecs / np.sqrt(evals)).astype(np.float32).T  # (K, rows)
    for s in range(0, p, chunk):
        components[:, s:s + chunk] = proj @ data[:, s:s + chunk]
    del data
    sigma = np.sqrt(evals / max(rows - 1, 1)).astype(np.float32)
    return PcaBasis(cand.astype(np.int64), reference, mean, components, sigma, materials, w_floor, mapping)


def fit_basis_files(data, output, *, exclude=(), progress: bool = True,
                   components: int = DEFAULT_COMPONENTS, half: bool = False, phi_stride: int = 1,
                   w_floor: float = 0.0, int8: bool = False, eps_share: float = 0.0, deflate: bool = False) -> str:
    """Fit a basis to the MERL tables ``data`` (files or folders, as
    :func:`brdfkit.io.folders.collect_materials` reads them) less the materials named in
    ``exclude``, and save it to ``output`` (``brdfkit fit --method basis``; ``half`` and
    ``phi_stride``, ``-O half=true -O phi_stride=2``, store it as the package ships
    bases, :func:`~.basis_file.basis_tensors`; ``w_floor``, ``-O w_floor=0.05``, bounds the mapping's
    weight, :class:`PcaBasis`; ``int8``, ``-O int8=true`` with ``half``, stores the components in
    int8, :func:`~.storage.quantize`; ``deflate``, ``-O deflate=true`` with ``int8``, deflates them
    losslessly, :func:`~.storage.pack_rows`; ``eps_share``, ``-O eps_share=0.1``, the mapping's
    resolution share at grazing cells, :class:`~brdfkit.basis.mapping.LogMapping`).
    Returns ``output``."""
    import sys

    from brdfkit.io.folders import collect_materials

    paths, names, _, unknown = collect_materials(data, exclude)
    if unknown:
        print(f"brdfkit: warning: excluded name(s) matched no input: {', '.join(unknown)}", file=sys.stderr)
    if not isinstance(half, bool) or phi_stride not in (1, 2) or not _fraction(w_floor) or not isinstance(int8, bool) \
            or (int8 and not half) or not _fraction(eps_share) or not isinstance(deflate, bool) or (deflate and not int8):
        raise InputError(f"--method basis: options half (true/false), phi_stride (1 or 2), w_floor (in [0, 1)), "
                         f"int8 (true/false, with half=true), deflate (true/false, with int8=true) and eps_share "
                         f"(in [0, 1)), got {half!r}, {phi_stride!r}, {w_floor!r}, {int8!r}, {deflate!r} and "
                         f"{eps_share!r}")
    basis = fit_basis(paths, components, names=names, w_floor=w_floor, mapping=LogMapping(float(eps_share)))
    save_basis(output, basis, half=half, phi_stride=phi_stride, int8=int8, deflate=deflate)
    print(f"wrote PCA basis ({components} components, {len(names)} materials) to {output}", file=sys.stderr)
    return output


def _fraction(x) -> bool:
    """Whether ``x`` is a number in ``[0, 1)`` (not a bool)."""
    return not isinstance(x, bool) and isinstance(x, (int, float)) and 0 <= x < 1
