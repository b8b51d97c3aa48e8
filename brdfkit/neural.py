"""One material's neural BRDF: the hyponet that a model decodes from an embedding.

Gokbudak et al. 2024, Sec. 3: the hypernetwork decoder turns a latent ``z`` into the
weights of a small MLP (the hyponet, ``6 -> 60 x 4 -> 3``) that maps the HD vector of a
direction pair (half and difference vectors, ``phi_h = 0``) to the log-relative mapped
RGB value ``rho'``. :class:`NeuralBRDF` holds those weights and evaluates the BRDF in
physical units by inverting the mapping (:func:`brdfkit.mapping.from_mapped`) with the
model's reference table ``rho_ref`` at the query angles.

This module also holds the encoding side (:func:`encode_samples`, :func:`encode_table`):
sample values go through :func:`brdfkit.mapping.to_mapped` with ``rho_ref`` at the
samples' own angles, and the set encoder averages over all of them.

Where ``rho_ref`` is undefined (no training material measured that cell, or all corners
of a trilinear lookup unmeasured) the median of ``rho_ref`` over its measured cells is
used instead, so every direction above the horizon has a mapping.
"""

from __future__ import annotations

import numpy as np

from .embedding import Embedding, check_compatible
from .errors import InputError
from .geometry import N_CELLS, TABLE_SHAPE, cell_angles, cell_index, grid_hd, half_diff_from_io, \
    hd_vectors, lookup_trilinear

__all__ = ["NeuralBRDF", "encode_samples", "encode_table", "grid_hd", "DECODE_BLOCK",
           "ENCODE_CHUNK"]

# Cells per hyponet block in the dense decode: (60 x block) float32 activations (1 MB)
# stay in a core's L2 cache (docs/model.md has the measurements).
DECODE_BLOCK = 4096
# Samples per encoder chunk: bounds memory, and (chunk x 128) float32 activations (2 MB)
# near the L2 cache halve the CPU time of a dense encode against 65,536 (docs/model.md).
ENCODE_CHUNK = 4096
# A sample within this many radians of a cell's own angles takes that cell's rho_ref.
_GRID_TOL = 1e-7

def _model_cache(model) -> dict:
    """Per-model derived data (measured cells, torch copies of rho_ref), kept on the
    model object so that it lives exactly as long as the model."""
    cache = getattr(model, "_brdfkit_cache", None)
    if cache is None:
        cache = {}
        model._brdfkit_cache = cache
    return cache


def _ref_fallback(model) -> np.ndarray:
    """Per-channel median of ``rho_ref`` over its measured cells, float64 ``(3,)``."""
    cache = _model_cache(model)
    if "fallback" not in cache:
        flat = model.rho_ref.reshape(N_CELLS, 3)
        ok = np.isfinite(flat).all(axis=1)
        if not ok.any():
            raise InputError(f"{model.path}: the model's reference table has no measured cell")
        cache["fallback"] = np.median(flat[ok].astype(np.float64), axis=0)
    return cache["fallback"]


def _ref_measured(model) -> np.ndarray:
    """Flat indices of the cells where ``rho_ref`` is measured (all three channels)."""
    cache = _model_cache(model)
    if "measured" not in cache:
        cache["measured"] = np.flatnonzero(np.isfinite(model.rho_ref.reshape(N_CELLS, 3)).all(axis=1))
    return cache["measured"]


def _ref_torch(model):
    """``rho_ref`` (float32, NaN kept) and the fallback as torch tensors on the model
    device."""
    import torch

    cache = _model_cache(model)
    key = ("ref_torch", str(model.device))
    if key not in cache:
        cache[key] = (torch.from_numpy(np.ascontiguousarray(model.rho_ref, np.float32)).to(model.device),
                      torch.tensor(_ref_fallback(model), dtype=torch.float32, device=model.device))
    return cache[key]


def _interp_ref(table, fallback, theta_h, theta_d, phi_d):
    """NaN-aware trilinear ``rho_ref`` at arbitrary angles (NumPy or torch, like
    ``table``); the fallback where no corner is measured."""
    v = lookup_trilinear(table, theta_h, theta_d, phi_d)
    if isinstance(v, np.ndarray):
        return np.where(np.isnan(v), fallback, v)
    import torch

    return torch.where(torch.isnan(v), fallback.to(v.dtype), v)


def reference_at(model, theta_h, theta_d, phi_d) -> np.ndarray:
    """``rho_ref`` at sample angles, float64 ``(N, 3)``.

    A sample at a grid cell's own angles takes that cell's value exactly (the grid
    samples of ``brdfkit sample`` and of dense tables); any other angles, and grid cells
    where ``rho_ref`` is unmeasured, are interpolated trilinearly (NaN-aware). Where no
    neighbouring cell is measured the fallback median is used.
    """
    th, td, pd = (np.asarray(a, dtype=np.float64).reshape(-1) for a in (theta_h, theta_d, phi_d))
    flat = model.rho_ref.reshape(N_CELLS, 3)
    idx = cell_index(th, td, pd)
    ch, cd, cp = cell_angles(idx)
    at_grid = (np.abs(th - ch) < _GRID_TOL) & (np.abs(td - cd) < _GRID_TOL) & \
        (np.abs(np.mod(pd, np.pi) - cp) < _GRID_TOL)
    ref = flat[idx].astype(np.float64)
    redo = ~at_grid | ~np.isfinite(ref).all(axis=1)
    if redo.any():
        ref[redo] = _interp_ref(model.rho_ref, _ref_fallback(model), th[redo], td[redo], pd[redo])
    return ref


def _linear_stack(seq):
    """The ``nn.Linear`` layers of an MLP built by ``hypernet._mlp`` (Linear, ReLU, ...,
    Linear), or ``None`` if ``seq`` has another structure."""
    from torch import nn

    mods = list(seq)
    lin = mods[0::2]
    if not all(isinstance(m, nn.Linear) for m in lin) or \
            not all(isinstance(m, nn.ReLU) for m in mods[1::2]) or len(mods) != 2 * len(lin) - 1:
        return None
    return lin


def _encoder_inference(model):
    """The set encoder's layers for inference, cached per model: every layer but the last
    as ``[W | b]`` (``(out, in + 1)``, the bias a column against a row of ones in the
    feature-major input), the last as float64 ``W``, ``b``. ``None`` if the encoder is
    not a plain MLP."""
    import torch

    cache = _model_cache(model)
    key = ("encoder", str(model.device))
    if key not in cache:
        lin = _linear_stack(model.net.encoder.net)
        if lin is None or len(lin) < 2:
            cache[key] = None
        else:
            with torch.no_grad():
                hidden = [torch.cat([m.weight, m.bias[:, None]], dim=1).contiguous() for m in lin[:-1]]
                cache[key] = (hidden, lin[-1].weight.double(), lin[-1].bias.double())
    return cache[key]


def _encode_arrays(model, hd: np.ndarray, rgb: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Set-encoder mean over ``N`` samples, chunked. Returns float32 ``(L,)``.

    The encoder is a per-sample MLP followed by a mean, and its last layer is affine, so
    ``mean(W h + b) = W mean(h) + b``: the last hidden activations are summed per chunk
    (float64) and the last layer is applied once, to their mean, in float64. This is
    the paper's encoder exactly (not an approximation), without holding all activations
    and without the last layer's per-sample products (a fifth of the encoder's work).
    The hidden layers run feature-major with each bias folded into its matrix, like the
    dense decode (``docs/performance.md``).
    """
    import torch

    from .mapping import to_mapped

    n = hd.shape[0]
    layers = _encoder_inference(model)
    if layers is None:  # not a plain MLP: the module itself
        mlp = model.net.encoder.net
        total = torch.zeros(model.cfg.latent_dim, dtype=torch.float64, device=model.device)
        with torch.inference_mode():
            for s in range(0, n, ENCODE_CHUNK):
                e = min(n, s + ENCODE_CHUNK)
                mapped = to_mapped(rgb[s:e], ref[s:e]).astype(np.float32)
                x = np.concatenate([hd[s:e].astype(np.float32, copy=False), mapped], axis=1)
                total += mlp(torch.from_numpy(x).to(model.device)).sum(dim=0, dtype=torch.float64)
        return (total / n).float().cpu().numpy()
    hidden, w_last, b_last = layers
    n_in = hidden[0].shape[1] - 1
    total = torch.zeros(w_last.shape[1], dtype=torch.float64, device=model.device)
    with torch.inference_mode():
        for s in range(0, n, ENCODE_CHUNK):
            e = min(n, s + ENCODE_CHUNK)
            x = np.empty((n_in + 1, e - s), dtype=np.float32)
            x[:6] = hd[s:e].T
            x[6:n_in] = to_mapped(rgb[s:e], ref[s:e]).T
            x[n_in] = 1.0
            h = torch.from_numpy(x).to(model.device)
            for i, wb in enumerate(hidden):
                out = torch.empty(wb.shape[0] + (i < len(hidden) - 1), e - s, device=model.device)
                torch.mm(wb, h, out=out[:wb.shape[0]])
                out[:wb.shape[0]].relu_()
                if i < len(hidden) - 1:
                    out[-1] = 1.0
                h = out
            total += h.sum(dim=1, dtype=torch.float64)
        z = torch.addmv(b_last, w_last, total / n)
    return z.float().cpu().numpy()


def _decoder_inference(model):
    """The ten per-tensor decoder MLPs stacked for one latent, cached per model: the first
    layers side by side (one ``mm``), the middle layers as one batched product, the last
    layers (different widths) one ``addmv`` each: 14 operators instead of 50, which at
    one latent cost more than the arithmetic. ``None`` for another structure."""
    import torch

    cache = _model_cache(model)
    key = ("decoder", str(model.device))
    if key not in cache:
        dec = model.net.decoder
        nets = [n for pair in zip(dec.weight_nets, dec.bias_nets) for n in pair]
        lins = [_linear_stack(n) for n in nets]
        if any(lin is None for lin in lins) or len({len(lin) for lin in lins}) != 1 or len(lins[0]) < 2:
            cache[key] = None
        else:
            with torch.no_grad():
                first = (torch.cat([lin[0].weight for lin in lins]).t().contiguous(),
                         torch.cat([lin[0].bias for lin in lins]))
                mids = [(torch.stack([lin[k].weight.t() for lin in lins]).contiguous(),
                         torch.stack([lin[k].bias[None] for lin in lins]).contiguous())
                        for k in range(1, len(lins[0]) - 1)]
                lasts = [(lin[-1].weight.contiguous(), lin[-1].bias) for lin in lins]
            cache[key] = (first, mids, lasts, list(dec.shapes))
    return cache[key]


def _hyponet_weights(model, z):
    """Hyponet weights for one latent ``z (1, L)``: the same as
    ``model.net.hyponet_weights(z)`` (:class:`brdfkit.hypernet.HyperDecoder`)."""
    import torch

    parts = _decoder_inference(model)
    if parts is None:
        return model.net.hyponet_weights(z)
    (w1, b1), mids, lasts, shapes = parts
    h = torch.addmm(b1[None], z, w1).relu_().view(len(lasts), 1, -1)
    for w, b in mids:
        h = torch.baddbmm(b, h, w).relu_()
    outs = [torch.addmv(b, w, h[i, 0]) for i, (w, b) in enumerate(lasts)]
    return [(outs[2 * j].view(1, fi, fo), outs[2 * j + 1].view(1, 1, fo)) for j, (fi, fo) in enumerate(shapes)]


def encode_samples(model, samples, source: str = "") -> Embedding:
    """Embedding of a :class:`~brdfkit.samples.SampleSet` (any ``N >= 1``, any order).

    Parameters
    ----------
    model
        :class:`~brdfkit.modelfile.NeuralModel`.
    samples
        The measurements (angles in radians, RGB in 1/sr).
    source
        Provenance; defaults to ``samples.source``.
    """
    n = len(samples)
    if n < 1:
        raise InputError(f"{source or samples.source or 'samples'}: no samples to encode")
    hd = np.asarray(samples.hd(), dtype=np.float64)
    ref = reference_at(model, samples.theta_h, samples.theta_d, samples.phi_d)
    latent = _encode_arrays(model, hd, np.asarray(samples.rgb, dtype=np.float64), ref)
    return Embedding(latent, model.fingerprint, source or samples.source, n)


def encode_table(model, table: np.ndarray, source: str = "") -> Embedding:
    """Embedding of a dense ``(90, 90, 180, 3)`` table (1/sr, NaN where unmeasured) from
    all its measured cells; ``sample_count`` records how many."""
    arr = np.asarray(table)
    if arr.shape != TABLE_SHAPE:
        raise InputError(f"{source or 'table'}: shape {arr.shape}, expected {TABLE_SHAPE}")
    flat = arr.reshape(N_CELLS, 3)
    idx = np.flatnonzero(np.isfinite(flat).all(axis=1))
    if idx.size == 0:
        raise InputError(f"{source or 'table'}: no measured cells to encode")
    ref = model.rho_ref.reshape(N_CELLS, 3)[idx].astype(np.float64)
    bad = ~np.isfinite(ref)
    if bad.any():
        ref = np.where(bad, _ref_fallback(model)[None, :], ref)
    latent = _encode_arrays(model, grid_hd()[idx], flat[idx].astype(np.float64, copy=False), ref)
    return Embedding(latent, model.fingerprint, source, int(idx.size))


class NeuralBRDF:
    """One material's hyponet, decoded from an embedding.

    Attributes
    ----------
    model
        The :class:`~brdfkit.modelfile.NeuralModel` that decoded it.
    embedding
        The :class:`~brdfkit.embedding.Embedding`.
    weights
        Hyponet weights for a batch of one material: per layer ``W (1, in, out)`` and
        ``b (1, 1, out)``, float32 on the model device
        (see :func:`brdfkit.hypernet.hyponet_forward`).
    """

    def __init__(self, model, embedding: Embedding, weights, name: str = ""):
        self.model = model
        self.embedding = embedding
        self.weights = weights
        self.name = name or embedding.source or "embedding"

    @classmethod
    def from_embedding(cls, model, emb: Embedding, name: str = "") -> "NeuralBRDF":
        """Decode ``emb`` with ``model`` (refused with
        :class:`~brdfkit.errors.ModelMismatchError` if another model made it)."""
        import torch

        check_compatible(emb, model, name)
        with torch.no_grad():
            z = torch.from_numpy(np.asarray(emb.latent, np.float32).copy()).to(model.device)[None]
            weights = [(w.contiguous(), b.contiguous()) for w, b in _hyponet_weights(model, z)]
        return cls(model, emb, weights, name)

    def _refuse_nan(self, vals) -> None:
        """A latent far outside the trained range (``interpolate`` with ``t = 1e20``, a
        hand-edited file) overflows the float32 activations into NaN, which a MERL file
        would store as "not measured": refuse it (``docs/stability.md``)."""
        import torch

        if bool(torch.isnan(vals).any()):
            z = float(np.abs(self.embedding.latent).max())
            raise InputError(f"{self.name}: the model's hyponet overflows on this embedding (largest "
                             f"latent value {z:.3g}, far outside the trained range); it cannot be decoded")

    def _folded(self):
        """Per layer ``[W^T | b]`` (``(out, in + 1)``), made once per NeuralBRDF."""
        import torch

        if getattr(self, "_folded_layers", None) is None:
            self._folded_layers = [torch.cat([w[0].t(), b[0, 0][:, None]], dim=1).contiguous()
                                   for w, b in self.weights]
        return self._folded_layers

    def _hyponet_block(self, x1, bufs):
        """One block through the hyponet, feature-major: ``x1 (7, n)`` (HD vectors and a
        row of ones) -> ``bufs[-1] (3, n)`` mapped RGB. ``bufs`` from :meth:`_buffers`:
        every hidden buffer carries a row of ones, so each layer is one plain ``mm`` with
        the bias folded into its matrix (``addmm`` with a broadcast bias cost a third
        more than the products themselves, ``docs/performance.md``)."""
        import torch

        layers = self._folded()
        last = len(layers) - 1
        h = x1
        for i, (wt, buf) in enumerate(zip(layers, bufs)):
            if i < last:
                torch.mm(wt, h, out=buf[:-1])
                buf[:-1].relu_()
            else:
                torch.mm(wt, h, out=buf)
            h = buf
        return h

    def _buffers(self, n):
        import torch

        layers = self._folded()
        bufs = []
        for i, wt in enumerate(layers):
            hidden = i < len(layers) - 1
            buf = torch.empty(wt.shape[0] + hidden, n, dtype=torch.float32, device=self.model.device)
            if hidden:
                buf[-1] = 1.0
            bufs.append(buf)
        return bufs

    def _mapped(self, hd):
        """Hyponet on ``hd (N, 6)`` float32 (model device) -> mapped RGB ``(N, 3)`` (a
        transposed view), in blocks of :data:`DECODE_BLOCK` like the dense decode."""
        import torch

        n = hd.shape[0]
        x1 = torch.ones(7, n, dtype=torch.float32, device=self.model.device)
        x1[:6] = hd.t()
        out = torch.empty(3, n, dtype=torch.float32, device=self.model.device)
        full = self._buffers(min(DECODE_BLOCK, max(n, 1)))
        for s in range(0, n, DECODE_BLOCK):
            e = min(n, s + DECODE_BLOCK)
            bufs = full if e - s == full[0].shape[1] else self._buffers(e - s)
            out[:, s:e] = self._hyponet_block(x1[:, s:e], bufs)
        return out.t()

    def _eval_angles(self, hd, th, td, pd):
        import torch

        from .mapping import from_mapped

        table, fallback = _ref_torch(self.model)
        out = torch.empty(hd.shape[0], 3, dtype=torch.float32, device=self.model.device)
        with torch.no_grad():
            for s in range(0, hd.shape[0], 1 << 16):
                e = min(hd.shape[0], s + (1 << 16))
                ref = _interp_ref(table, fallback, th[s:e], td[s:e], pd[s:e]).float()
                out[s:e] = from_mapped(self._mapped(hd[s:e]), ref)
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
        x = hd.to(device=dev, dtype=torch.float32).reshape(-1, 6)
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
            torch ``(N, 3)`` unit vectors in the local frame (``z`` the normal), incident
            and outgoing, both pointing away from the surface.

        Returns
        -------
        torch.Tensor
            ``(N, 3)`` float32 on ``wi``'s device, BRDF in 1/sr; 0 where either
            direction is at or below the horizon. ``phi_d`` is folded into ``[0, pi)``
            (reciprocity), as on the MERL grid the model was trained on.
        """
        import math

        import torch

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
        horizon) are evaluated, in blocks of :data:`DECODE_BLOCK` cells, with float32
        matrix products and ``rho_ref`` taken at each cell exactly. Activations are kept
        feature-major (``(60, block)``, ``W^T h``): measured 10% faster than row-major on
        the project machine and insensitive to the block size (``docs/model.md``). Each
        activation buffer carries a constant row of ones and each layer's bias is an
        extra column of ``W^T``, so a layer is one plain ``mm`` into a preallocated
        buffer: ``addmm`` with a broadcast bias cost a third more than the products
        themselves (``docs/performance.md``).

        Returns
        -------
        numpy.ndarray
            float64 ``(90, 90, 180, 3)``, 1/sr, ``>= 0``, NaN on the other cells.
        """
        import torch

        from .mapping import from_mapped

        model = self.model
        dev = model.device
        cache = _model_cache(model)
        key = ("decode_inputs", str(dev))
        if key not in cache:
            idx = _ref_measured(model)
            hd1 = np.ones((7, idx.size), dtype=np.float32)
            hd1[:6] = grid_hd()[idx].T
            cache[key] = (
                idx,
                torch.from_numpy(hd1).to(dev),
                torch.from_numpy(np.ascontiguousarray(model.rho_ref.reshape(N_CELLS, 3)[idx].T)).to(dev),
            )
        idx, hd1_t, ref_t = cache[key]
        m = idx.size
        full = self._buffers(min(DECODE_BLOCK, m))
        vals = torch.empty(3, m, dtype=torch.float32, device=dev)
        with torch.inference_mode():
            for s in range(0, m, DECODE_BLOCK):
                e = min(m, s + DECODE_BLOCK)
                bufs = full if e - s == full[0].shape[1] else self._buffers(e - s)
                vals[:, s:e] = from_mapped(self._hyponet_block(hd1_t[:, s:e], bufs), ref_t[:, s:e])
        # from_mapped bounds every value to [0, RHO_MAX], so the sum (one pass, no mask)
        # is NaN exactly when a value is.
        if bool(torch.isnan(vals.sum())):
            self._refuse_nan(vals)
        table = np.full((N_CELLS, 3), np.nan)
        table[idx] = vals.cpu().numpy().T
        return table.reshape(TABLE_SHAPE)
