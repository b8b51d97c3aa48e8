"""A loaded network file: the network, its reference table, and what is derived from them once.

:class:`LoadedNetwork` is what :func:`brdfkit.hypernet.network_file.load_network` returns and what
encoding (:mod:`brdfkit.hypernet.encoding`) and decoding (:class:`brdfkit.hypernet.neural_brdf.NeuralBRDF`)
take. Besides the file's contents it holds a :class:`ModelCache`: data derived from the
model on first use (measured cells, torch copies of ``rho_ref``, the fused inference
layers of :mod:`brdfkit.hypernet.kernels`), kept on the model so that it lives exactly as
long as the model.

The reference table ``rho_ref`` (the denominator of the mapping, Gokbudak et al. 2024,
eq. 1) is looked up here: at a grid cell's own angles exactly, elsewhere trilinearly
(NaN-aware), and where no training material measured the neighbourhood the per-channel
median of ``rho_ref`` over its measured cells is used instead, so that every direction
above the horizon has a mapping.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from brdfkit.errors import InputError
from brdfkit.geometry import N_CELLS, cell_angles, cell_index
from brdfkit.geometry.trilinear import lookup_trilinear

__all__ = ["LoadedNetwork", "NeuralModel", "ModelCache", "interp_reference"]

# A sample within this many radians of a cell's own angles takes that cell's rho_ref.
_GRID_TOL = 1e-7


@dataclasses.dataclass
class ModelCache:
    """Data derived from a :class:`LoadedNetwork` on first use.

    The torch entries are keyed by the device they live on (``str(torch.device)``).

    Attributes
    ----------
    fallback
        float64 ``(3,)``: per-channel median of ``rho_ref`` over its measured cells.
    measured
        int64 flat indices of the cells where ``rho_ref`` is measured (all channels).
    reference
        ``(rho_ref float32 (90, 90, 180, 3), fallback float32 (3,))`` as torch tensors.
    trilinear
        :class:`brdfkit.geometry.trilinear.TrilinearTable` of that ``rho_ref`` (the renders' lookups).
    encoder
        The set encoder's fused layers (:func:`brdfkit.hypernet.kernels.encoder_layers`).
    decoder
        The decoder's fused layers (:func:`brdfkit.hypernet.kernels.decoder_layers`).
    decode_inputs
        ``(cells, [HD | 1] (7, P), rho_ref (3, P))`` of the measured cells, for the
        dense decode.
    screen
        ``rho_ref`` at the pairs of the last :class:`brdfkit.render.screen.Screen`
        rendered with this model, keyed by that screen's id, with a weak reference
        to the screen (an id is reused once its object is freed).
    """

    fallback: np.ndarray | None = None
    measured: np.ndarray | None = None
    reference: dict = dataclasses.field(default_factory=dict)
    trilinear: dict = dataclasses.field(default_factory=dict)
    encoder: dict = dataclasses.field(default_factory=dict)
    decoder: dict = dataclasses.field(default_factory=dict)
    decode_inputs: dict = dataclasses.field(default_factory=dict)
    screen: dict = dataclasses.field(default_factory=dict)


@dataclasses.dataclass
class LoadedNetwork:
    """A loaded network file.

    Attributes
    ----------
    net
        :class:`~brdfkit.hypernet.network.HyperBRDF` in eval mode on ``device``.
    cfg
        Its :class:`~brdfkit.hypernet.network.HyperConfig`.
    rho_ref
        float32 ``(90, 90, 180, 3)`` reference table (1/sr), NaN where unmeasured.
    digest
        sha256 hex of the weights (:func:`~brdfkit.hypernet.network_file.weights_digest`).
    meta
        Training provenance (materials, steps, ...), as saved.
    device
        ``torch.device`` the network lives on.
    path
        The file it was loaded from.
    mapping
        The mapping the model was trained with (:func:`brdfkit.hypernet.mapping.mapping_record`).
    cache
        :class:`ModelCache`, filled on first use.
    """

    net: object
    cfg: object
    rho_ref: np.ndarray
    digest: str
    meta: dict
    device: object
    path: str
    mapping: dict = dataclasses.field(default_factory=lambda: _paper_mapping())
    cache: ModelCache = dataclasses.field(default_factory=ModelCache, repr=False, compare=False)

    @property
    def short_digest(self) -> str:
        return self.digest[:12]

    def reference_fallback(self) -> np.ndarray:
        """Per-channel median of ``rho_ref`` over its measured cells, float64 ``(3,)``.

        Raises
        ------
        InputError
            The reference table has no measured cell.
        """
        if self.cache.fallback is None:
            flat = self.rho_ref.reshape(N_CELLS, 3)
            ok = np.isfinite(flat).all(axis=1)
            if not ok.any():
                raise InputError(f"{self.path}: the model's reference table has no measured cell")
            self.cache.fallback = np.median(flat[ok].astype(np.float64), axis=0)
        return self.cache.fallback

    def measured_cells(self) -> np.ndarray:
        """Flat indices of the cells where ``rho_ref`` is measured (all three channels)."""
        if self.cache.measured is None:
            self.cache.measured = np.flatnonzero(np.isfinite(self.rho_ref.reshape(N_CELLS, 3)).all(axis=1))
        return self.cache.measured

    def reference_torch(self):
        """``(rho_ref, fallback)`` as float32 torch tensors on the model's device
        (``rho_ref`` ``(90, 90, 180, 3)`` with its NaN kept)."""
        import torch

        key = str(self.device)
        if key not in self.cache.reference:
            self.cache.reference[key] = (
                torch.from_numpy(np.ascontiguousarray(self.rho_ref, np.float32)).to(self.device),
                torch.tensor(self.reference_fallback(), dtype=torch.float32, device=self.device))
        return self.cache.reference[key]

    def reference_trilinear(self):
        """:func:`reference_torch`'s ``rho_ref`` as a :class:`brdfkit.geometry.trilinear.TrilinearTable`
        (same lookups, about four times faster; built once per device)."""
        from brdfkit.geometry.trilinear import TrilinearTable

        key = str(self.device)
        if key not in self.cache.trilinear:
            self.cache.trilinear[key] = TrilinearTable(self.reference_torch()[0])
        return self.cache.trilinear[key]

    def reference_at(self, theta_h, theta_d, phi_d) -> np.ndarray:
        """``rho_ref`` at sample angles, float64 ``(N, 3)``.

        A sample at a grid cell's own angles takes that cell's value exactly (the grid
        samples of ``brdfkit sample`` and of dense tables); any other angles, and grid
        cells where ``rho_ref`` is unmeasured, are interpolated trilinearly (NaN-aware).
        Where no neighbouring cell is measured the fallback median is used.
        """
        th, td, pd = (np.asarray(a, dtype=np.float64).reshape(-1) for a in (theta_h, theta_d, phi_d))
        flat = self.rho_ref.reshape(N_CELLS, 3)
        idx = cell_index(th, td, pd)
        ch, cd, cp = cell_angles(idx)
        at_grid = (np.abs(th - ch) < _GRID_TOL) & (np.abs(td - cd) < _GRID_TOL) & \
            (np.abs(np.mod(pd, np.pi) - cp) < _GRID_TOL)
        ref = flat[idx].astype(np.float64)
        redo = ~at_grid | ~np.isfinite(ref).all(axis=1)
        if redo.any():
            ref[redo] = interp_reference(self.rho_ref, self.reference_fallback(), th[redo], td[redo], pd[redo])
        return ref


    def reference_at_pairs(self, theta_h, theta_d, phi_d):
        """``rho_ref`` at torch angles on the model's device, float32 ``(M, 3)``
        (trilinear, NaN-aware, the fallback median where no corner is measured): what a
        render of a hyponet (:class:`brdfkit.render.screen.Screen`) maps back with."""
        fallback = self.reference_torch()[1]
        dev = self.device
        return interp_reference(self.reference_trilinear(), fallback, theta_h.to(dev), theta_d.to(dev),
                                phi_d.to(dev)).float()

    def hyponet_values(self, weights, hd, ref):
        """BRDF values (1/sr) of hyponet ``weights`` (batch of one) at network inputs ``hd``
        ``(M, 6)``, mapped back against ``ref`` ``(M, 3)``; with gradients."""
        from brdfkit.hypernet.mapping import from_mapped
        from brdfkit.hypernet.network import hyponet_forward

        return from_mapped(hyponet_forward(weights, hd[None])[0], ref)


def interp_reference(table, fallback, theta_h, theta_d, phi_d):
    """NaN-aware trilinear ``rho_ref`` at arbitrary angles (NumPy or torch, like
    ``table``); ``fallback`` ``(3,)`` where no corner is measured."""
    v = lookup_trilinear(table, theta_h, theta_d, phi_d)
    if isinstance(v, np.ndarray):
        return np.where(np.isnan(v), fallback, v)
    import torch

    return torch.where(torch.isnan(v), fallback.to(v.dtype), v)


def _paper_mapping() -> dict:
    from brdfkit.hypernet.mapping import mapping_record

    return mapping_record()


NeuralModel = LoadedNetwork
"""The name :class:`LoadedNetwork` had before ("model" now means what ``-m`` takes)."""
