"""The training data of the learnt prior (:func:`brdfkit.prior.fit.fit_prior`): the
basis, the cells trained on, the held-out fold bases and the tensors on the device.

The fold bases are what makes the residuals the network learns from look like those of
a material no basis has seen (the module docstring of :mod:`brdfkit.prior.fit`):
each fold's basis is fitted without its materials, stored as the main basis is stored,
and rotated onto the main basis (orthogonal Procrustes over the cells) so that a
coefficient means the same in all of them.
"""

from __future__ import annotations

import dataclasses
import os
import tempfile

import numpy as np

from brdfkit.errors import InputError
from brdfkit.geometry import N_CELLS, N_PHI_D, N_THETA_D, cos_theta_i, grid_angles, grid_hd
from brdfkit.basis import PcaBasis, fit_basis, load_basis, save_basis, storage_of

__all__ = ["TrainingTensors", "main_basis", "training_cells", "fold_bases", "to_device"]


def _storage(path: str) -> dict:
    """How the basis file ``path`` stores its basis (:func:`brdfkit.basis.storage_of`)."""
    from brdfkit.io.tensorfile import open_safetensors

    with open_safetensors(path) as f:
        meta = f.metadata() or {}
    return storage_of(meta)


def _as_stored(basis: PcaBasis, storage: dict) -> PcaBasis:
    """The basis as a file with ``storage`` gives it back."""
    if not storage["half"] and storage["phi_stride"] == 1 and not storage.get("int8"):
        return basis
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "basis.safetensors")
        save_basis(path, basis, **storage)
        return load_basis(path)


def _resolve_basis(spec) -> str:
    """The basis file of ``spec``: a path, or a built-in model's name."""
    from brdfkit.models.builtin import resolve_basis

    return resolve_basis(spec)


def main_basis(basis, components, paths, names, say):
    """The model's basis: the file or built-in ``basis``, or one of ``components``
    components fitted to ``paths``. Returns ``(basis, storage, components)``, ``storage``
    how its file stores it (:func:`brdfkit.basis.storage_of`)."""
    if basis is not None:
        bpath = _resolve_basis(basis)
        storage = _storage(bpath)
        full = load_basis(bpath)
        components = full.n_components
    else:
        storage = {"half": False, "phi_stride": 1, "int8": False, "deflate": False}
        say(f"fitting the {components}-component basis to {len(paths)} materials")
        full = fit_basis(paths, components, names=names)  # Nielsen's mapping (w_floor 0): give -O basis= for another
    return full, storage, components


def training_cells(paths, full):
    """The cells measured in every table of ``paths`` and covered by the basis ``full``.

    Returns
    -------
    cells : numpy.ndarray
        int64 ``(P,)`` flat MERL indices.
    values : torch.Tensor
        float32 ``(M, P, 3)`` the tables there, in 1/sr, negatives clipped to 0.
    """
    import torch

    from brdfkit.io.merl import read_merl

    covered = np.zeros(N_CELLS, bool)
    covered[full.cells] = True
    tables = []
    for p in paths:
        t = read_merl(p).reshape(N_CELLS, 3)
        covered &= np.isfinite(t).all(1)
        tables.append(t.astype(np.float32))
    cells = np.flatnonzero(covered)
    if cells.size == 0:
        raise InputError("no cell is measured in every training table and covered by the basis")
    values = torch.from_numpy(np.stack([np.clip(t[cells], 0, None) for t in tables]))  # (M, P, 3)
    return cells, values


def fold_bases(paths, fold_of, folds, full, cells, components, storage, say):
    """Per fold, the basis fitted without its materials, stored as ``storage`` says and
    rotated onto ``full``.

    Returns
    -------
    tabs : numpy.ndarray
        float32 ``(folds, P, 2 + K)``: per fold, its table (:meth:`PcaBasis._table`:
        reference, mean, ``K`` components) at ``cells``, the components rotated.
    sigmas : numpy.ndarray
        float32 ``(folds, K)``: the spread of the rotated coefficients.
    """
    full_comp = full.lookup_table()[cells][:, 2:].astype(np.float64)
    tabs, sigmas = [], []
    for f in range(folds):
        say(f"fitting the basis of fold {f + 1} of {folds}")
        keep = [p for p, fo in zip(paths, fold_of) if fo != f]
        fb = _as_stored(fit_basis(keep, components, w_floor=full.w_floor, mapping=full.mapping), storage)
        tab = fb.lookup_table()[cells].astype(np.float64)
        if not np.isfinite(tab).all():
            tab = np.nan_to_num(tab)  # a cell only the held-out fold measured: the reference
        # Procrustes: one meaning per coefficient in every fold basis.
        u, _, vt = np.linalg.svd(tab[:, 2:].T @ full_comp)
        r = u @ vt
        tabs.append(np.concatenate([tab[:, :2], tab[:, 2:] @ r], 1).astype(np.float32))
        sigmas.append(np.sqrt(np.einsum("ij,i,ij->j", r, fb.sigma.astype(np.float64) ** 2, r)).astype(np.float32))
    return np.stack(tabs), np.stack(sigmas)


@dataclasses.dataclass
class TrainingTensors:
    """The training data on the training device (``M`` materials, ``P`` cells,
    ``F`` folds, ``K`` components).

    Attributes
    ----------
    values
        float32 ``(M, P, 3)`` the tables at the cells, 1/sr.
    hd
        float32 ``(P, 6)`` the cells' network inputs (:func:`brdfkit.geometry.grid_hd`).
    weight
        float32 ``(P,)`` the basis's cell weights (at least 1e-6).
    cos
        float32 ``(P,)`` the cells' ``cos theta_i``, clipped at 0.
    cdf
        float64 ``(P,)`` cumulative distribution of the cells under uniform Rusinkiewicz
        angles, ending at 1.
    fold_tab, fold_sig
        float32 ``(F, P, 2 + K)`` and ``(F, K)``: :func:`fold_bases`.
    mat_fold
        int64 ``(M,)`` each material's fold.
    members
        Per fold, int64 indices of its materials.
    mapping
        The basis's log mapping (:class:`~brdfkit.basis.mapping.LogMapping`).
    """

    values: object
    hd: object
    weight: object
    cos: object
    cdf: object
    fold_tab: object
    fold_sig: object
    mat_fold: object
    members: list
    mapping: object = None

    @property
    def n_materials(self) -> int:
        """``M``."""
        return self.values.shape[0]

    @property
    def n_cells(self) -> int:
        """``P``."""
        return self.values.shape[1]


def to_device(values, cells, full, fold_of, folds, tabs, sigmas, dev) -> TrainingTensors:
    """:class:`TrainingTensors` on ``dev`` from the arrays of :func:`training_cells` and
    :func:`fold_bases`, ``fold_of`` int ``(M,)`` the materials' folds."""
    import torch

    fold_tab = torch.from_numpy(tabs).to(dev)
    fold_sig = torch.from_numpy(sigmas).to(dev)
    values = values.to(dev)
    hd_all = torch.from_numpy(np.ascontiguousarray(grid_hd()[cells], np.float32)).to(dev)
    w_all = torch.from_numpy(np.clip(full.cell_weight(cells), 1e-6, None).astype(np.float32)).to(dev)
    th, td, pd = np.meshgrid(*grid_angles(), indexing="ij")
    cos_all = torch.from_numpy(np.clip(cos_theta_i(th, td, pd).reshape(N_CELLS)[cells], 0, None)
                               .astype(np.float32)).to(dev)
    # Cells weighted by the solid angle a uniform draw over the angles gives each theta_h row.
    row = torch.from_numpy(cells // (N_THETA_D * N_PHI_D)).double()
    cdf = torch.cumsum(2 * row + 1, 0)
    cdf = (cdf / cdf[-1]).to(dev)
    mat_fold = torch.from_numpy(fold_of).to(dev)
    members = [torch.from_numpy(np.flatnonzero(fold_of == f)).to(dev) for f in range(folds)]
    return TrainingTensors(values, hd_all, w_all, cos_all, cdf, fold_tab, fold_sig, mat_fold, members, full.mapping)
