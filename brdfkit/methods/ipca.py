"""The PCA baseline of Nielsen, Jensen and Ramamoorthi 2015, "On Optimal, Minimal BRDF
Sampling for Reflectance Acquisition" (SIGGRAPH Asia), as compared against in Gokbudak et
al. 2024: a linear basis of log-mapped measured BRDFs, fitted to sparse samples by
regularised least squares.

What is mapped
--------------
Each training table is cosine weighted and log-relative mapped, following the authors'
published code (``MapBRDF`` of brdf.compute.dtu.dk)::

    x    = rho * w,                w = cos(theta_i) cos(theta_o)
    x'   = ln((x + eps) / (x_ref + eps)),   eps = 0.001

with ``x_ref`` the per-cell median of the cosine-weighted training values (over every
material *and* channel, see below). This is deliberately not
:func:`brdfkit.mapping.to_mapped`, the hypernetwork paper's variant
``ln((rho + 0.002) / (rho_ref + 0.002) + 1)``: its ``+ 1`` flattens every value below
the reference towards 0, which throws away the dark half of the data a linear basis has
to model. The inverse is ``rho = ((exp(x') (x_ref + eps) - eps) / w``, clamped at 0.

Channels
--------
As in Nielsen et al., the three colour channels of a material are three separate
observations of one shared basis: ``M`` training materials give ``3 M`` vectors (so the
reference is one value per cell, the median over all ``3 M``). A sample set is fitted
channel by channel with the same basis.

Basis
-----
PCA over the cells measured by at least one training table (a training table missing a
cell counts as the reference there, ``x' = 0``); the ``3 M x P`` matrix is centred and
decomposed through its ``3 M x 3 M`` Gram matrix, so the cost is one pass of matrix
products (seconds for 80 materials) and the memory the float32 matrix itself
(``4 * 3 M * P`` bytes, about 1.1 GB for 80 MERL materials).

Reconstruction
--------------
The mean, components and reference are interpolated trilinearly at each sample's angles
(:func:`brdfkit.geometry.lookup_trilinear`; a sample on a cell's own angles reads that
cell exactly), the sample is mapped with its exact ``w``, and the coefficients solve::

    min_z || A diag(sigma) z - b ||^2 + lam ||z||^2,      c = sigma * z

with ``A`` the components at the samples, ``b`` the mapped samples minus the mean and
``sigma_k`` the standard deviation of the training coefficients of component ``k``: a
ridge on coefficients measured in training standard deviations, i.e. a Gaussian prior
fitted to the training set (Nielsen et al. regularise the singular-value-scaled
components with one fixed ``eta`` in the same way). ``lam`` is :data:`DEFAULT_LAMBDA`
unless given (see ``docs/baselines.md`` for how it was chosen).
"""

from __future__ import annotations

import dataclasses
import json
import os
from typing import Iterable, Sequence

import numpy as np

from ..atomic import atomic_path, check_input_file
from ..errors import FormatError, InputError
from ..geometry import GRID_SHAPE, N_CELLS, N_PHI_D, grid_cosine_weight, io_from_half_diff, lookup_trilinear
from .method import Method, MethodOptions

__all__ = ["IpcaModel", "IpcaOptions", "fit_ipca", "fit_ipca_files", "load_ipca", "METHOD", "IPCA_FORMAT",
           "IPCA_VERSION", "read_ipca", "EPS", "DEFAULT_LAMBDA", "DEFAULT_COMPONENTS", "cosine_weight"]

IPCA_FORMAT = "brdfkit-ipca"
IPCA_VERSION = "2"
_READS = ("1", "2")  # version 2 adds the optional float16 and half-phi_d storage
EPS = 0.001
DEFAULT_COMPONENTS = 8
DEFAULT_LAMBDA = 0.1
_TENSORS = ("cells", "reference", "mean", "components", "sigma")


def cosine_weight(theta_h, theta_d, phi_d) -> np.ndarray:
    """Nielsen's cosine weight ``max(cos theta_i, 0) * max(cos theta_o, 0)`` at
    Rusinkiewicz angles (radians, broadcastable); float64 of the broadcast shape."""
    wi, wo = io_from_half_diff(theta_h, theta_d, phi_d)
    return np.clip(wi[..., 2], 0.0, None) * np.clip(wo[..., 2], 0.0, None)


@dataclasses.dataclass
class IpcaModel:
    """A PCA basis of cosine-weighted, log-mapped BRDF tables.

    Attributes
    ----------
    cells
        int64 ``(P,)``, sorted flat MERL indices of the cells the basis covers.
    reference
        float32 ``(P,)``, per-cell median of the cosine-weighted training values.
    mean
        float32 ``(P,)``, mean of the mapped training vectors.
    components
        float32 ``(K, P)``, orthonormal principal directions, strongest first.
    sigma
        float32 ``(K,)``, standard deviation of the training coefficients along each
        component.
    materials
        Names of the training materials.
    """

    cells: np.ndarray
    reference: np.ndarray
    mean: np.ndarray
    components: np.ndarray
    sigma: np.ndarray
    materials: list = dataclasses.field(default_factory=list)
    _dense: np.ndarray | None = dataclasses.field(default=None, repr=False, compare=False)

    @property
    def n_components(self) -> int:
        return int(self.components.shape[0])

    def save(self, path: str | os.PathLike, *, half: bool = False, phi_stride: int = 1) -> None:
        """Write the basis as one safetensors file (format ``brdfkit-ipca``), atomically;
        ``half`` and ``phi_stride`` as :meth:`tensors` takes them."""
        from safetensors.numpy import save_file

        tensors, meta = self.tensors(half=half, phi_stride=phi_stride, where=os.fspath(path))
        with atomic_path(path) as tmp:
            save_file(tensors, tmp, metadata=meta)

    def tensors(self, *, half: bool = False, phi_stride: int = 1, prefix: str = "",
                where: str = "basis") -> tuple[dict, dict]:
        """The tensors and metadata of the basis's file (names prefixed with ``prefix``
        when it is stored inside another model file).

        ``half`` stores the per-cell tensors in float16 and ``phi_stride = 2`` only the
        cells of even ``phi_d`` index (:mod:`brdfkit.methods.basis_storage`): together a
        quarter of the size, for the bases shipped with the package. The reader restores
        the full grid the same way every time, so a model trained on the restored basis
        sees exactly what it is shipped with.
        """
        from .basis_storage import check_half, compact

        cells, per_cell = compact(self.cells, [self.reference, self.mean, self.components], phi_stride)
        if half:
            check_half(where, per_cell)
        dtype = np.float16 if half else np.float32
        # Compact files name their cells by a bit mask over the grid (0.18 MB), not by
        # int64 indices (4.4 MB for half the grid).
        where_cells = ({"cell_mask": np.packbits(np.isin(np.arange(N_CELLS), cells))} if half or phi_stride != 1
                       else {"cells": np.ascontiguousarray(cells, dtype=np.int64)})
        tensors = {**where_cells,
                   "reference": np.ascontiguousarray(per_cell[0], dtype=dtype),
                   "mean": np.ascontiguousarray(per_cell[1], dtype=dtype),
                   "components": np.ascontiguousarray(per_cell[2], dtype=dtype),
                   "sigma": np.ascontiguousarray(self.sigma, dtype=np.float32)}
        meta = {"format": IPCA_FORMAT, "version": IPCA_VERSION,
                "n_components": str(self.n_components), "eps": repr(EPS),
                "weight": "cos_i*cos_o", "channels": "separate observations, shared basis",
                "phi_d_stride": str(int(phi_stride)), "dtype": "float16" if half else "float32",
                "materials": json.dumps(list(self.materials))}
        return ({prefix + k: v for k, v in tensors.items()}, {prefix + k: v for k, v in meta.items()})

    def _table(self) -> np.ndarray:
        """Dense ``(N_CELLS, K + 2)`` float32 ``[reference, mean, components...]``, NaN
        off the basis cells, built once for trilinear lookups."""
        if self._dense is None:
            dense = np.full((N_CELLS, self.n_components + 2), np.nan, dtype=np.float32)
            dense[self.cells, 0] = self.reference
            dense[self.cells, 1] = self.mean
            dense[self.cells, 2:] = self.components.T
            self._dense = dense
        return self._dense

    def coefficients(self, samples, lam: float | None = None) -> np.ndarray:
        """Fit the basis to a sample set: coefficients ``(K, 3)``, one column per channel.

        Parameters
        ----------
        samples
            :class:`brdfkit.samples.SampleSet`; BRDF values in 1/sr.
        lam
            Ridge weight (``>= 0``; default :data:`DEFAULT_LAMBDA`), on coefficients in
            units of the training standard deviations.
        """
        lam = DEFAULT_LAMBDA if lam is None else float(lam)
        if not lam >= 0 or not np.isfinite(lam):
            raise InputError(f"ridge lambda must be a finite number >= 0, got {lam}")
        if len(samples) == 0:
            raise InputError(f"{samples.source or 'samples'}: no samples to fit")
        at = lookup_trilinear(self._table().reshape(GRID_SHAPE + (-1,)),
                              samples.theta_h, samples.theta_d, samples.phi_d)
        w = cosine_weight(samples.theta_h, samples.theta_d, samples.phi_d)
        # Samples no basis cell reaches, with no weight (on the horizon), or unmeasured
        # (NaN, MERL's convention) say nothing.
        measured = samples.measured()
        use = np.isfinite(at).all(axis=1) & (w > 0) & measured
        if not use.any():
            what = ("no sample has a measured (non-NaN) value" if not measured.any()
                    else "no sample lies on a cell the PCA basis covers")
            raise InputError(f"{samples.source or 'samples'}: {what}")
        at, w = at[use], w[use]
        ref, mean, comp = at[:, 0], at[:, 1], at[:, 2:]
        x = np.clip(np.asarray(samples.rgb, np.float64)[use], 0.0, None) * w[:, None]
        b = np.log((x + EPS) / (ref[:, None] + EPS)) - mean[:, None]
        a = comp * self.sigma.astype(np.float64)[None, :]
        lhs = a.T @ a + lam * np.eye(self.n_components)
        z = np.linalg.lstsq(lhs, a.T @ b, rcond=None)[0] if lam == 0 else np.linalg.solve(lhs, a.T @ b)
        return z * self.sigma.astype(np.float64)[:, None]

    def decode(self, coefficients: np.ndarray) -> np.ndarray:
        """Dense table from coefficients ``(K, 3)``: float64 ``(90, 90, 180, 3)``, 1/sr,
        ``>= 0``, NaN off the basis cells."""
        c = np.asarray(coefficients, np.float32)
        mapped = self.mean[:, None] + self.components.T @ c  # (P, 3), float32
        ref = self.reference[:, None].astype(np.float64)
        # expm1 form of exp(x') (x_ref + eps) - eps: exact where x' ~ 0 and x_ref ~ 0.
        x = np.expm1(mapped.astype(np.float64)) * (ref + EPS) + ref
        w = grid_cosine_weight()[self.cells]
        out = np.full((N_CELLS, 3), np.nan)
        out[self.cells] = np.clip(x / w[:, None], 0.0, None)
        return out.reshape(GRID_SHAPE + (3,))

    def reconstruct(self, samples, lam: float | None = None) -> np.ndarray:
        """Dense table fitted to a sample set (see :meth:`coefficients`, :meth:`decode`)."""
        return self.decode(self.coefficients(samples, lam))

    def project(self, table: np.ndarray) -> np.ndarray:
        """Least-squares coefficients ``(K, 3)`` of a dense table over all basis cells it
        measures (no regulariser): the best this basis can do for that material."""
        flat = np.asarray(table, np.float64).reshape(N_CELLS, 3)[self.cells]
        w = grid_cosine_weight()[self.cells]
        ok = np.isfinite(flat).all(axis=1)
        b = np.log((np.clip(flat[ok], 0, None) * w[ok, None] + EPS) /
                   (self.reference[ok, None].astype(np.float64) + EPS)) - self.mean[ok, None]
        a = self.components[:, ok].T.astype(np.float64)
        return np.linalg.lstsq(a, b, rcond=None)[0]


def _load_table(item) -> tuple[np.ndarray, str | None]:
    from ..merl import read_merl

    if isinstance(item, (str, os.PathLike)):
        return read_merl(item), os.path.splitext(os.path.basename(os.fspath(item)))[0]
    arr = np.asarray(item)
    if arr.shape != GRID_SHAPE + (3,):
        raise InputError(f"a training table has shape {arr.shape}, expected (90, 90, 180, 3)")
    return arr, None


def fit_ipca(tables_or_paths: Iterable, n_components: int = DEFAULT_COMPONENTS,
             names: Sequence[str] | None = None, chunk: int = 1 << 16) -> IpcaModel:
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

    Returns
    -------
    IpcaModel
    """
    items = list(tables_or_paths)
    if not items:
        raise InputError("fitting a PCA basis needs at least one training table")
    n_components = int(n_components)
    if n_components < 1:
        raise InputError(f"number of PCA components must be at least 1, got {n_components}")
    rows = 3 * len(items)
    if n_components > rows - 1:
        raise InputError(f"{n_components} PCA components need at least {n_components + 1} training "
                         f"channel vectors (3 per material), got {len(items)} material(s)")
    w_all = grid_cosine_weight()
    cand = np.flatnonzero(w_all > 0)  # cells where both directions are above the horizon
    w = w_all[cand].astype(np.float32)
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
    import warnings
    for s in range(0, p, chunk):
        block = data[:, s:s + chunk]
        if np.isnan(block).any():
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                reference[s:s + chunk] = np.nanmedian(block, axis=0)
        else:
            reference[s:s + chunk] = np.median(block, axis=0)
        ref = reference[s:s + chunk]
        np.log((block + np.float32(EPS)) / (ref + np.float32(EPS)), out=block)
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
    return IpcaModel(cand.astype(np.int64), reference, mean, components, sigma, materials)


def load_ipca(path: str | os.PathLike) -> IpcaModel:
    """Read a basis written by :meth:`IpcaModel.save`.

    Raises
    ------
    FormatError
        Not a safetensors file, another format or version, missing or inconsistent
        tensors, non-finite values.
    """
    from ..tensorfile import open_safetensors

    path = check_input_file(path)
    with open_safetensors(path) as f:
        return read_ipca(f, path)


def read_ipca(f, path: str, prefix: str = "") -> IpcaModel:
    """The basis in an open safetensors file ``f`` (tensors and metadata keys named
    ``prefix + name``: a basis stored inside another model file); errors name ``path``."""
    meta = {k[len(prefix):]: v for k, v in (f.metadata() or {}).items() if k.startswith(prefix)}
    if meta.get("format") != IPCA_FORMAT:
        raise FormatError(path, f"not a brdfkit PCA basis (format {meta.get('format')!r}, "
                                f"expected {IPCA_FORMAT!r})")
    if meta.get("version") not in _READS:
        raise FormatError(path, f"PCA basis version {meta.get('version')!r} is not supported "
                                f"(this brdfkit reads versions {', '.join(_READS)})")
    stride = meta.get("phi_d_stride", "1")
    if stride not in ("1", "2"):
        raise FormatError(path, f"PCA basis phi_d_stride {stride!r} is not 1 or 2")
    keys = set(f.keys())
    missing = [k for k in _TENSORS if prefix + k not in keys and not (k == "cells" and prefix + "cell_mask" in keys)]
    if missing:
        raise FormatError(path, f"PCA basis lacks tensor(s) {', '.join(missing)}")
    t = {k: f.get_tensor(prefix + k) for k in _TENSORS if prefix + k in keys}
    if "cells" not in t:
        mask = f.get_tensor(prefix + "cell_mask")
        if mask.dtype != np.uint8 or mask.shape != ((N_CELLS + 7) // 8,):
            raise FormatError(path, "PCA basis cell mask is not a bit mask of the MERL grid")
        t["cells"] = np.flatnonzero(np.unpackbits(mask)[:N_CELLS]).astype(np.int64)
    cells, comp = t["cells"], t["components"]
    p = cells.shape[0] if cells.ndim == 1 else -1
    if (cells.ndim != 1 or comp.ndim != 2 or comp.shape[1] != p or t["reference"].shape != (p,)
            or t["mean"].shape != (p,) or t["sigma"].shape != (comp.shape[0],) or comp.shape[0] < 1):
        raise FormatError(path, "PCA basis tensors have inconsistent shapes")
    if p == 0 or cells.min() < 0 or cells.max() >= N_CELLS or (np.diff(cells) <= 0).any():
        raise FormatError(path, "PCA basis cell indices are not sorted indices of the MERL grid")
    for k in ("reference", "mean", "components", "sigma"):
        if not np.isfinite(t[k]).all():
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
    cells = cells.astype(np.int64)
    per_cell = [t["reference"].astype(np.float32), t["mean"].astype(np.float32), comp.astype(np.float32)]
    if stride == "2":
        if ((cells % N_PHI_D) % 2).any():
            raise FormatError(path, "a half-phi_d PCA basis may hold only cells of even phi_d index")
        from .basis_storage import expand
        cells, per_cell = expand(cells, per_cell)
    return IpcaModel(cells, *per_cell, t["sigma"].astype(np.float32), list(materials))


def fit_ipca_files(data, output, *, exclude=(), progress: bool = True,
                   components: int = DEFAULT_COMPONENTS, half: bool = False, phi_stride: int = 1) -> str:
    """Fit a basis to the MERL tables ``data`` (files or folders, as
    :func:`brdfkit.materials.collect_materials` reads them) less the materials named in
    ``exclude``, and save it to ``output`` (``brdfkit fit --method ipca``; ``half`` and
    ``phi_stride``, ``-O half=true -O phi_stride=2``, store it as the package ships
    bases, :meth:`IpcaModel.tensors`). Returns ``output``."""
    import sys

    from ..materials import collect_materials

    paths, names, _, unknown = collect_materials(data, exclude)
    if unknown:
        print(f"brdfkit: warning: excluded name(s) matched no input: {', '.join(unknown)}", file=sys.stderr)
    if not isinstance(half, bool) or phi_stride not in (1, 2):
        raise InputError(f"--method ipca: options half (true/false) and phi_stride (1 or 2), got "
                         f"{half!r} and {phi_stride!r}")
    fit_ipca(paths, components, names=names).save(output, half=half, phi_stride=phi_stride)
    print(f"wrote PCA basis ({components} components, {len(names)} materials) to {output}", file=sys.stderr)
    return output


@dataclasses.dataclass(frozen=True)
class IpcaOptions(MethodOptions):
    """``lam``: the ridge weight of :meth:`IpcaModel.coefficients`."""

    lam: float = DEFAULT_LAMBDA

    def __post_init__(self):
        if not (isinstance(self.lam, (int, float)) and self.lam >= 0 and np.isfinite(self.lam)):
            raise InputError(f"ipca option lam (ridge lambda) must be a finite number >= 0, got {self.lam!r}")


def _load(path, device):
    from ..model.builtin import resolve_basis

    return load_ipca(resolve_basis(path))


def _reconstruct(samples, model, options, *, seed, device):
    return model.reconstruct(samples, lam=options.lam), None


def _compress(model, table, name):
    return model.decode(model.project(table))


def _describe(model, path):
    return f"ipca {model.n_components} components", model.n_components, set(model.materials)


METHOD = Method("ipca", "PCA basis of log-mapped tables fitted by ridge regression (Nielsen et al. 2015)",
                "PCA basis (.safetensors from `brdfkit fit --method ipca`)", options=IpcaOptions,
                load_model=_load, reconstruct_fn=_reconstruct, fit_fn=fit_ipca_files,
                fit_options=("components", "half", "phi_stride"), compress_fn=_compress, describe_fn=_describe,
                bench_option="ipca")
