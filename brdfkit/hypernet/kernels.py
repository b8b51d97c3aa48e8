"""Fused inference kernels: the trained network's layers rearranged for fast CPU inference.

Training runs the modules of :mod:`brdfkit.hypernet.network` as they are. Inference does the
same arithmetic in fewer, larger operators (``docs/notes/performance.md`` has the
measurements):

* **Encoder** (:func:`encode_mean`): the set encoder is a per-sample MLP followed by a
  mean, and its last layer is affine, so ``mean(W h + b) = W mean(h) + b``. The last
  hidden activations are summed per chunk of :data:`ENCODE_CHUNK` samples (float64) and
  the last layer is applied once, to their mean, in float64: the paper's encoder exactly,
  without holding all activations or doing the last layer per sample.
* **Decoder** (:func:`hyponet_weights`): the per-tensor decoder MLPs for one latent, their
  first layers side by side (one ``mm``), the middle ones as one batched product, the
  last ones one ``addmv`` each: 14 operators instead of 50.
* **Hyponet** (:func:`fold_hyponet`, :func:`hyponet_block`): feature-major activations
  (``(width, n)``, ``W^T h``), each bias an extra column of ``W^T`` against a row of ones
  carried by every activation buffer, so a layer is one plain ``mm`` into a preallocated
  buffer (``addmm`` with a broadcast bias cost a third more than the products).

The kernels are built from the network's public layer lists
(:meth:`~brdfkit.hypernet.network.SetEncoder.layers`,
:meth:`~brdfkit.hypernet.network.HyperDecoder.tensor_layers`) and cached per model in its
:class:`~brdfkit.hypernet.loaded.ModelCache`.
"""

from __future__ import annotations

import math

import numpy as np

from brdfkit.hypernet.network import IN_FEATURES, OUT_FEATURES

__all__ = ["DECODE_BLOCK", "ENCODE_CHUNK", "encoder_layers", "encode_mean", "decoder_layers",
           "hyponet_weights", "fold_hyponet", "hyponet_buffers", "hyponet_block", "hyponet_mapped"]

DECODE_BLOCK = 4096
"""Cells per hyponet block in the dense decode: (60 x block) float32 activations (1 MB)
stay in a core's L2 cache (``docs/model.md`` has the measurements)."""
ENCODE_CHUNK = 4096
"""Samples per encoder chunk: bounds memory, and (chunk x 128) float32 activations (2 MB)
near the L2 cache halve the CPU time of a dense encode against 65,536 (``docs/model.md``)."""


def encoder_layers(model):
    """The set encoder's layers for inference, cached per model: every layer but the last
    as ``[W | b]`` (``(out, in + 1)``, the bias a column against a row of ones in the
    feature-major input), the last as float64 ``W``, ``b``."""
    import torch

    key = str(model.device)
    if key not in model.cache.encoder:
        lin = model.net.encoder.layers()
        with torch.no_grad():
            hidden = [torch.cat([m.weight, m.bias[:, None]], dim=1).contiguous() for m in lin[:-1]]
            model.cache.encoder[key] = (hidden, lin[-1].weight.double(), lin[-1].bias.double())
    return model.cache.encoder[key]


def encode_mean(model, hd: np.ndarray, rgb: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """The set encoder's mean over ``N`` samples, in chunks of :data:`ENCODE_CHUNK`
    (with ``pooling="attention"``, the softmax-weighted mean, accumulated with a running
    maximum of the scores so that no chunk overflows).

    Parameters
    ----------
    model
        :class:`~brdfkit.hypernet.loaded.LoadedNetwork`.
    hd
        ``(N, 6)`` HD vectors.
    rgb
        ``(N, 3)`` BRDF values, 1/sr.
    ref
        ``(N, 3)`` ``rho_ref`` at the samples (the mapping's denominator).

    Returns
    -------
    numpy.ndarray
        float32 ``(L,)``, the latent.
    """
    import torch

    from brdfkit.hypernet.mapping import to_mapped

    n = hd.shape[0]
    hidden, w_last, b_last = encoder_layers(model)
    n_in = IN_FEATURES + OUT_FEATURES
    total = torch.zeros(w_last.shape[1], dtype=torch.float64, device=model.device)
    attention = model.net.encoder.attention
    top, weight_sum = -math.inf, 0.0
    with torch.inference_mode():
        for s in range(0, n, ENCODE_CHUNK):
            e = min(n, s + ENCODE_CHUNK)
            x = np.empty((n_in + 1, e - s), dtype=np.float32)
            x[:IN_FEATURES] = hd[s:e].T
            x[IN_FEATURES:n_in] = to_mapped(rgb[s:e], ref[s:e]).T
            x[n_in] = 1.0
            h = torch.from_numpy(x).to(model.device)
            for i, wb in enumerate(hidden):
                out = torch.empty(wb.shape[0] + (i < len(hidden) - 1), e - s, device=model.device)
                torch.mm(wb, h, out=out[:wb.shape[0]])
                out[:wb.shape[0]].relu_()
                if i < len(hidden) - 1:
                    out[-1] = 1.0
                h = out
            if not hidden:  # one affine layer: the mean of the inputs themselves
                h = h[:n_in]
            if attention is None:
                total += h.sum(dim=1, dtype=torch.float64)
                continue
            score = (attention.weight.double() @ h.double())[0] + attention.bias.double()
            new_top = max(top, float(score.max()))
            scale = math.exp(top - new_top) if top > -math.inf else 0.0
            w = torch.exp(score - new_top)
            total = total * scale + h.double() @ w
            weight_sum = weight_sum * scale + float(w.sum())
            top = new_top
        z = torch.addmv(b_last, w_last, total / (n if attention is None else weight_sum))
    return z.float().cpu().numpy()


def decoder_layers(model):
    """The per-tensor decoder MLPs stacked for one latent, cached per model: ``(first,
    mids, lasts, shapes)`` (see the module doc). ``None`` for decoder MLPs without hidden
    layers (run as the module itself)."""
    import torch

    key = str(model.device)
    if key not in model.cache.decoder:
        lins = model.net.decoder.tensor_layers()
        if len(lins[0]) < 2:
            model.cache.decoder[key] = None
        else:
            with torch.no_grad():
                first = (torch.cat([lin[0].weight for lin in lins]).t().contiguous(),
                         torch.cat([lin[0].bias for lin in lins]))
                mids = [(torch.stack([lin[k].weight.t() for lin in lins]).contiguous(),
                         torch.stack([lin[k].bias[None] for lin in lins]).contiguous())
                        for k in range(1, len(lins[0]) - 1)]
                lasts = [(lin[-1].weight.contiguous(), lin[-1].bias) for lin in lins]
            model.cache.decoder[key] = (first, mids, lasts, list(model.net.decoder.shapes))
    return model.cache.decoder[key]


def hyponet_weights(model, z):
    """Hyponet weights for one latent ``z (1, L)``: the same as
    ``model.net.hyponet_weights(z)`` (:class:`~brdfkit.hypernet.network.HyperDecoder`),
    per layer ``W (1, in, out)`` and ``b (1, 1, out)``."""
    import torch

    parts = decoder_layers(model)
    if parts is None:
        return model.net.hyponet_weights(z)
    (w1, b1), mids, lasts, shapes = parts
    h = torch.addmm(b1[None], z, w1).relu_().view(len(lasts), 1, -1)
    for w, b in mids:
        h = torch.baddbmm(b, h, w).relu_()
    outs = [torch.addmv(b, w, h[i, 0]) for i, (w, b) in enumerate(lasts)]
    return [(outs[2 * j].view(1, fi, fo), outs[2 * j + 1].view(1, 1, fo)) for j, (fi, fo) in enumerate(shapes)]


def fold_hyponet(weights):
    """Per hyponet layer ``[W^T | b]`` (``(out, in + 1)``) from one material's weights
    ``[(W (1, in, out), b (1, 1, out)), ...]``."""
    import torch

    return [torch.cat([w[0].t(), b[0, 0][:, None]], dim=1).contiguous() for w, b in weights]


def hyponet_buffers(folded, n: int, device):
    """Activation buffers for a block of ``n``: per layer ``(out (+ 1), n)`` float32, the
    hidden ones with their last row set to ones (the bias row)."""
    import torch

    bufs = []
    for i, wt in enumerate(folded):
        hidden = i < len(folded) - 1
        buf = torch.empty(wt.shape[0] + hidden, n, dtype=torch.float32, device=device)
        if hidden:
            buf[-1] = 1.0
        bufs.append(buf)
    return bufs


def hyponet_block(folded, x1, bufs):
    """One block through the hyponet, feature-major: ``x1 (7, n)`` (HD vectors and a row
    of ones) -> ``bufs[-1] (3, n)`` mapped RGB, each layer one ``mm`` into its buffer."""
    import torch

    last = len(folded) - 1
    h = x1
    for i, (wt, buf) in enumerate(zip(folded, bufs)):
        if i < last:
            torch.mm(wt, h, out=buf[:-1])
            buf[:-1].relu_()
        else:
            torch.mm(wt, h, out=buf)
        h = buf
    return h


def hyponet_mapped(folded, hd, device):
    """The hyponet on ``hd (N, 6)`` float32 (on ``device``) -> mapped RGB ``(N, 3)`` (a
    transposed view), in blocks of :data:`DECODE_BLOCK` like the dense decode."""
    import torch

    n = hd.shape[0]
    x1 = torch.ones(IN_FEATURES + 1, n, dtype=torch.float32, device=device)
    x1[:IN_FEATURES] = hd.t()
    out = torch.empty(OUT_FEATURES, n, dtype=torch.float32, device=device)
    full = hyponet_buffers(folded, min(DECODE_BLOCK, max(n, 1)), device)
    for s in range(0, n, DECODE_BLOCK):
        e = min(n, s + DECODE_BLOCK)
        bufs = full if e - s == full[0].shape[1] else hyponet_buffers(folded, e - s, device)
        out[:, s:e] = hyponet_block(folded, x1[:, s:e], bufs)
    return out.t()
