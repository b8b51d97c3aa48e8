"""A basis or residual embedding as what a shader decodes: the basis's components as
textures, the residual's network, and each material's ``3 K`` numbers.

The page (``brdfkit view --live``) and an engine (``brdfkit export --glsl``) decode a
material on the GPU with ``assets/brdfkit_decode.glsl``, the same closed form as
:meth:`brdfkit.residual.model.BasisResidual.decode` (a basis embedding: the same without
the correction). They need:

* the basis: per cell its reference ``x_ref``, mean and ``K`` components. A basis that
  half-``phi_d`` int8 storage holds without loss (the built-ins' bases, which are stored
  so: :mod:`brdfkit.basis.storage`) travels in that storage, 34 bytes a stored cell for
  ``K = 30`` instead of 128 at every cell, and the page restores it as the basis file's
  reader does (``live.js``); any other in float32 at every cell;
* the residual's network for ``K`` components (:mod:`brdfkit.residual.network`): the
  hypernetwork body and head and the hyponet's base weights, float32, from which the page
  makes each channel's hyponet weights;
* the mapping's constants (:mod:`brdfkit.basis.mapping`).

Examples
--------
>>> from brdfkit.testing.examples import tiny_basis
>>> data = basis_data(tiny_basis(4), 2, compress=False)
>>> data["k"], data["storage"], data["sigma"] == [float(s) for s in tiny_basis(4).sigma[:2]]
(2, 'float32', True)
"""

from __future__ import annotations

import numpy as np

from brdfkit.errors import InputError
from brdfkit.view.textures import blob, encode_planes

__all__ = ["mapping_constants", "basis_data", "net_data", "live_material", "LIVE_KINDS", "MAX_COMPONENTS"]

LIVE_KINDS = ("basis", "residual")
"""The embedding kinds a shader decodes."""
MAX_COMPONENTS = 30
"""The most components a shader decodes: the reference, the mean and the components, four
a texture, in the eight textures ``brdfkit_decode.glsl`` declares."""


def mapping_constants(w_floor: float) -> dict:
    """The constants of :func:`brdfkit.basis.mapping.from_mapped`'s inverse and bound:
    ``eps``, ``floor``, ``cap``, ``tiny`` and ``w_tiny`` (the bound
    ``min(floor x_ref, cap) + tiny min(w / w_tiny, 1)``, read off
    :func:`~brdfkit.basis.mapping.lower_bound` itself), and the basis's ``w_floor``."""
    from brdfkit.basis.mapping import CAP, EPS, FLOOR, lower_bound

    tiny = float(lower_bound(np.float64(0.0), np.float64(1.0)))
    w = 1e-6  # far below w_tiny: the bound's absolute part is tiny w / w_tiny there
    w_tiny = tiny * w / float(lower_bound(np.float64(0.0), np.float64(w)))
    return {"eps": float(EPS), "floor": float(FLOOR), "cap": float(CAP), "tiny": tiny, "w_tiny": w_tiny,
            "w_floor": float(w_floor)}


def _mask(cells) -> bytes:
    from brdfkit.geometry import N_CELLS

    flags = np.zeros(N_CELLS, bool)
    flags[np.asarray(cells, np.int64)] = True
    return np.packbits(flags).tobytes()


def _compact(part):
    """``(stored cells, reference f16, mean f16, int8 components, scales)`` when the
    half-``phi_d`` int8 storage restores ``part`` (a basis of ``K`` components) to float32
    rounding, else ``None``."""
    from brdfkit.basis.storage import compact, dequantize, expand, quantize

    cells, (ref, mean, comps) = compact(part.cells, [part.reference, part.mean, part.components], 2)
    ref16, mean16 = np.asarray(ref, np.float16), np.asarray(mean, np.float16)
    q, scales = quantize(comps)
    try:
        out_cells, back = expand(cells, [ref16.astype(np.float32), mean16.astype(np.float32), dequantize(q, scales)])
    except (IndexError, ValueError):
        return None
    same = out_cells.shape == part.cells.shape and np.array_equal(out_cells, part.cells)
    for a, b in zip(back, (part.reference, part.mean, part.components)) if same else ():
        b = np.asarray(b, np.float32)
        same = same and np.allclose(a, b, rtol=2e-7, atol=1e-30 + 2e-7 * float(np.abs(b).max(initial=0.0)))
    return (cells, ref16, mean16, q, scales) if same else None


def basis_data(basis, k: int, compress: bool = True) -> dict:
    """The page's record of the ``k`` leading components of ``basis``
    (:class:`~brdfkit.basis.model.PcaBasis`): its storage (``compact`` or ``float32``)
    and blobs, ``sigma`` and the mapping's constants (:func:`mapping_constants`)."""
    part = basis.leading(k)
    out = {"k": int(k), "sigma": [float(s) for s in np.asarray(part.sigma, np.float64)],
           **mapping_constants(part.w_floor), "cell_mask": blob(_mask(part.cells), compress)}
    packed = _compact(part)
    if packed is not None:
        from brdfkit.basis.storage import INT8_BLOCK

        cells, ref16, mean16, q, scales = packed
        out.update(storage="compact", block=INT8_BLOCK, stored_mask=blob(_mask(cells), compress),
                   reference=blob(encode_planes(ref16), compress, planes=True),
                   mean=blob(encode_planes(mean16), compress, planes=True),
                   components=blob(np.ascontiguousarray(q).tobytes(), compress),
                   scales=blob(np.ascontiguousarray(scales, np.float32).tobytes(), compress))
    else:
        values = np.concatenate([np.asarray(part.reference, np.float32)[None], np.asarray(part.mean, np.float32)[None],
                                 np.asarray(part.components, np.float32)])
        out.update(storage="float32", values=blob(np.ascontiguousarray(values).tobytes(), compress))
    return out


def net_data(cfg, state: dict, compress: bool = True) -> dict:
    """The page's record of a residual network (:class:`brdfkit.residual.network.ResidualConfig`
    and its float32 tensors by name)."""
    names = ["body.0.weight", "body.0.bias", "body.2.weight", "body.2.bias", "head.weight", "head.bias",
             *(f"base.{i}" for i in range(6))]
    return {"k_min": cfg.k_min, "k_max": cfg.k_max, "width": cfg.width, "hidden": cfg.hidden,
            "tensors": {n: blob(np.ascontiguousarray(state[n], np.float32).tobytes(), compress) for n in names}}


def live_material(emb, decoder, name: str) -> dict:
    """What the shader needs of one embedding besides its basis and network:
    ``{"kind", "k", "coefficients" (3 K, component-major), "gain", "basis", "net"}``
    (``basis``: the decoder's basis object, ``net``: ``(cfg, state)`` or ``None``),
    checked against its decoder as ``brdfkit decode`` checks it."""
    if decoder.kind == "residual":
        from brdfkit.residual.brdf import check_embedding

        coefficients, gains = check_embedding(emb, decoder.obj, decoder.digest, name)
        if len(gains) > 1:  # a blend of two materials that chose different members
            raise InputError(f"{name}: a blend of the corrections of members {', '.join(map(str, gains))}; "
                             f"--live decodes one member's: view it without --live")
        member, gain = next(iter(gains.items()), (0, 0.0))
        _, cfg, state = decoder.obj.net_for(coefficients.shape[0], member)
        basis, net = decoder.obj.basis, (cfg, state)
    else:
        from brdfkit.basis.coefficients import check_coefficients

        coefficients, gain, basis, net = check_coefficients(emb, decoder.obj, decoder.digest, name), 0.0, decoder.obj, None
    c = np.asarray(coefficients, np.float32)
    if c.shape[0] > MAX_COMPONENTS:
        raise InputError(f"{name}: an embedding of {c.shape[0]} components per channel; the shader decodes at most "
                         f"{MAX_COMPONENTS}")
    return {"kind": decoder.kind, "k": int(c.shape[0]), "coefficients": [float(x) for x in c.reshape(-1)],
            "gain": float(gain), "basis": basis, "net": net}
