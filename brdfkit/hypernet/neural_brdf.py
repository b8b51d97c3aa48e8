"""One material's neural BRDF: the hyponet that a model decodes from an embedding.

Gokbudak et al. 2024, Sec. 3: the hypernetwork decoder turns a latent ``z`` into the
weights of a small MLP (the hyponet, ``6 -> 60 x 4 -> 3``) that maps the HD vector of a
direction pair (half and difference vectors, ``phi_h = 0``) to the log-relative mapped
RGB value ``rho'``. :class:`NeuralBRDF` holds those weights and evaluates the BRDF in
physical units by inverting the mapping (:func:`brdfkit.hypernet.mapping.from_mapped`) with the
model's reference table ``rho_ref`` at the query angles
(:meth:`~brdfkit.hypernet.loaded.LoadedNetwork.reference_at`), through the fused kernels of
:mod:`brdfkit.hypernet.kernels`.
"""

from __future__ import annotations

import numpy as np

from brdfkit.io.embedding import Embedding
from brdfkit.errors import InputError, ModelMismatchError
from brdfkit.geometry import N_CELLS, TABLE_SHAPE, grid_hd, half_diff_from_io, hd_vectors
from brdfkit.hypernet import kernels
from brdfkit.hypernet.kernels import fold_hyponet, hyponet_block, hyponet_buffers, hyponet_mapped, hyponet_weights
from brdfkit.hypernet.loaded import interp_reference
from brdfkit.hypernet.network import IN_FEATURES, OUT_FEATURES

__all__ = ["NeuralBRDF", "check_latent"]


def check_latent(emb: Embedding, model, name: str = "") -> None:
    """Refuse an embedding that ``model`` did not make: another kind, another model's
    digest, another latent size (:class:`~brdfkit.errors.ModelMismatchError`, one line
    naming both models)."""
    if emb.kind == "hypernet" and emb.decoder == model.digest and emb.size == int(model.cfg.latent_dim):
        return
    what = f"embedding {name}" if name else "embedding"
    raise ModelMismatchError(
        f"{what} ({emb.kind}, {emb.size} numbers, decoder {emb.decoder[:12]}) was not made by the given model "
        f"{model.digest[:12]} (latent {model.cfg.latent_dim}); encode the material again with this model")


class NeuralBRDF:
    """One material's hyponet, decoded from an embedding.

    Attributes
    ----------
    model
        The :class:`~brdfkit.hypernet.loaded.LoadedNetwork` that decoded it.
    embedding
        The :class:`~brdfkit.io.embedding.Embedding`.
    weights
        Hyponet weights for a batch of one material: per layer ``W (1, in, out)`` and
        ``b (1, 1, out)``, float32 on the model device
        (see :func:`brdfkit.hypernet.network.hyponet_forward`).
    """

    def __init__(self, model, embedding: Embedding, weights, name: str = ""):
        self.model = model
        self.embedding = embedding
        self.weights = weights
        self.name = name or embedding.source or "embedding"
        self._folded_layers = None

    @classmethod
    def from_embedding(cls, model, emb: Embedding, name: str = "") -> "NeuralBRDF":
        """Decode ``emb`` with ``model`` (refused with
        :class:`~brdfkit.errors.ModelMismatchError` if another model made it)."""
        import torch

        check_latent(emb, model, name)
        with torch.no_grad():
            z = torch.from_numpy(np.asarray(emb.values, np.float32).copy()).to(model.device)[None]
            weights = [(w.contiguous(), b.contiguous()) for w, b in hyponet_weights(model, z)]
        return cls(model, emb, weights, name)

    def _refuse_nan(self, vals) -> None:
        """A latent far outside the trained range (``interpolate`` with ``t = 1e20``, a
        hand-edited file) overflows the float32 activations into NaN, which a MERL file
        would store as "not measured": refuse it (``docs/stability.md``)."""
        import torch

        if bool(torch.isnan(vals).any()):
            z = float(np.abs(self.embedding.values).max())
            raise InputError(f"{self.name}: the model's hyponet overflows on this embedding (largest "
                             f"latent value {z:.3g}, far outside the trained range); it cannot be decoded")

    def _folded(self):
        """Per layer ``[W^T | b]`` (:func:`~brdfkit.hypernet.kernels.fold_hyponet`), made once."""
        if self._folded_layers is None:
            self._folded_layers = fold_hyponet(self.weights)
        return self._folded_layers

    def mapped(self, hd):
        """The hyponet on ``hd (N, 6)`` float32 (model device) -> mapped RGB ``rho'``
        ``(N, 3)`` (a transposed view), before the inverse mapping."""
        return hyponet_mapped(self._folded(), hd, self.model.device)

    def _eval_angles(self, hd, th, td, pd):
        import torch

        from brdfkit.hypernet.mapping import from_mapped

        fallback = self.model.reference_torch()[1]
        table = self.model.reference_trilinear()
        out = torch.empty(hd.shape[0], 3, dtype=torch.float32, device=self.model.device)
        with torch.no_grad():
            for s in range(0, hd.shape[0], 1 << 16):
                e = min(hd.shape[0], s + (1 << 16))
                ref = interp_reference(table, fallback, th[s:e], td[s:e], pd[s:e]).float()
                out[s:e] = from_mapped(self.mapped(hd[s:e]), ref)
        self._refuse_nan(out[torch.isfinite(hd).all(1)])
        return out

    def eval_hd(self, hd):
        """BRDF at HD vectors.

        Parameters
        ----------
        hd
            torch ``(N, 6)``: ``(hx, hy, hz, dx, dy, dz)`` with ``phi_h = 0``
            (:func:`brdfkit.geometry.hd_vectors`), any float dtype and device.

        Returns
        -------
        torch.Tensor
            ``(N, 3)`` float32 on ``hd``'s device, BRDF in 1/sr, ``>= 0``: the inverse
            mapping with ``rho_ref`` interpolated trilinearly at the query angles.
        """
        import torch

        dev = self.model.device
        x = hd.to(device=dev, dtype=torch.float32).reshape(-1, IN_FEATURES)
        x64 = x.double()
        th = torch.atan2(x64[:, 0], x64[:, 2])
        td = torch.atan2(torch.sqrt(x64[:, 3] ** 2 + x64[:, 4] ** 2), x64[:, 5])
        pd = torch.atan2(x64[:, 4], x64[:, 3])
        return self._eval_angles(x, th, td, pd).to(hd.device)

    def eval_dirs(self, wi, wo):
        """BRDF for direction pairs, for a renderer.

        Parameters
        ----------
        wi, wo
            ``(N, 3)`` unit vectors in the local frame (``z`` the normal), incident and
            outgoing, both pointing away from the surface: NumPy arrays (the renderer's,
            :mod:`brdfkit.render.quadrature`) or torch tensors.

        Returns
        -------
        numpy.ndarray or torch.Tensor
            ``(N, 3)`` float32 (NumPy for NumPy inputs, else on ``wi``'s device), BRDF in
            1/sr; 0 where either direction is at or below the horizon. ``phi_d`` is
            folded into ``[0, pi)`` (reciprocity), as on the MERL grid the model was
            trained on.
        """
        import math

        import torch

        if isinstance(wi, np.ndarray):
            with torch.no_grad():
                out = self.eval_dirs(torch.from_numpy(np.ascontiguousarray(wi, np.float32)),
                                     torch.from_numpy(np.ascontiguousarray(wo, np.float32)))
            return out.cpu().numpy()
        dev = self.model.device
        wi_ = wi.to(device=dev, dtype=torch.float64).reshape(-1, 3)
        wo_ = wo.to(device=dev, dtype=torch.float64).reshape(-1, 3)
        th, _, td, pd = half_diff_from_io(wi_, wo_)
        pd = torch.remainder(pd, math.pi)
        # phi_d a rounding error below 0 is the grid's phi_d = 0, not one just below pi.
        pd = torch.where(pd > math.pi - 1e-9, pd - math.pi, pd)
        hd = hd_vectors(th, td, pd).float()
        rho = self._eval_angles(hd, th, td, pd)
        above = (wi_[:, 2] > 0) & (wo_[:, 2] > 0)
        return torch.where(above[:, None], rho, torch.zeros_like(rho)).to(wi.device)

    def to_table(self) -> np.ndarray:
        """The dense decode: the BRDF on the MERL grid.

        Only the cells where the model's ``rho_ref`` is measured (the cells above the
        horizon) are evaluated, in blocks of :data:`~brdfkit.hypernet.kernels.DECODE_BLOCK`
        cells, with float32 matrix products and ``rho_ref`` taken at each cell exactly.
        Activations are kept feature-major (``(60, block)``, ``W^T h``): measured 10%
        faster than row-major on the project machine and insensitive to the block size (``docs/model.md``). Each
        activation buffer carries a constant row of ones and each layer's bias is an
        extra column of ``W^T``, so a layer is one plain ``mm`` into a preallocated
        buffer: ``addmm`` with a broadcast bias cost a third more than the products
        themselves (``docs/notes/performance.md``).

        Returns
        -------
        numpy.ndarray
            float64 ``(90, 90, 180, 3)``, 1/sr, ``>= 0``, NaN on the other cells.
        """
        import torch

        from brdfkit.hypernet.mapping import from_mapped

        model = self.model
        dev = model.device
        cache = model.cache.decode_inputs
        key = str(dev)
        if key not in cache:
            idx = model.measured_cells()
            hd1 = np.ones((IN_FEATURES + 1, idx.size), dtype=np.float32)
            hd1[:IN_FEATURES] = grid_hd()[idx].T
            cache[key] = (
                idx,
                torch.from_numpy(hd1).to(dev),
                torch.from_numpy(np.ascontiguousarray(model.rho_ref.reshape(N_CELLS, 3)[idx].T)).to(dev),
            )
        idx, hd1_t, ref_t = cache[key]
        m = idx.size
        folded = self._folded()
        block = kernels.DECODE_BLOCK  # read at call time: benchmarks vary it
        full = hyponet_buffers(folded, min(block, m), dev)
        vals = torch.empty(OUT_FEATURES, m, dtype=torch.float32, device=dev)
        with torch.inference_mode():
            for s in range(0, m, block):
                e = min(m, s + block)
                bufs = full if e - s == full[0].shape[1] else hyponet_buffers(folded, e - s, dev)
                vals[:, s:e] = from_mapped(hyponet_block(folded, hd1_t[:, s:e], bufs), ref_t[:, s:e])
        # from_mapped bounds every value to [0, RHO_MAX], so the sum (one pass, no mask)
        # is NaN exactly when a value is.
        if bool(torch.isnan(vals.sum())):
            self._refuse_nan(vals)
        table = np.full((N_CELLS, 3), np.nan)
        table[idx] = vals.cpu().numpy().T
        return table.reshape(TABLE_SHAPE)
