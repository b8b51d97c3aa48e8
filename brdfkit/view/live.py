"""A basis or residual embedding as what a shader decodes: every layout of
``assets/brdfkit_decode.glsl``, written once, here.

The page (``brdfkit view --live``) and an engine (``brdfkit export --glsl``) decode a
material on the GPU with ``assets/brdfkit_decode.glsl``, the same closed form as
:meth:`brdfkit.residual.model.BasisResidual.decode` (a basis embedding: the same without
the correction). The shader states its layouts as defines and uniforms, and this module
makes them, for the page and the export alike (:func:`material_uniforms`):

* the basis's *slots*: per cell its reference ``x_ref``, mean and ``K`` components, four
  slots a texture (:func:`slot_layout`, :func:`basis_textures`). A basis that
  half-``phi_d`` int8 storage holds without loss (the built-ins' bases, which are stored
  so: :mod:`brdfkit.basis.storage`) travels to the page in that storage, 34 bytes a
  stored cell for ``K = 30`` instead of 128 at every cell, and the page's
  ``BasisSlots`` (``assets/live.js``) restores it as the basis file's reader does; any
  other in float32 at every cell (:func:`basis_data`);
* each channel's coefficient of each slot (:func:`coefficient_slots`);
* the mapping's constants (:func:`mapping_constants`), an array indexed by name;
* the residual's hyponet for the channel's coefficients, made by the residual's
  hypernetwork here (:func:`brdfkit.residual.network.hyponet_weights`) and packed as
  :func:`hyponet_layout` says.

Examples
--------
>>> from brdfkit.testing.examples import tiny_basis
>>> data = basis_data(tiny_basis(4), 2, compress=False)
>>> data["k"], data["storage"], data["layout"]
(2, 'float32', [[0, 1, 2, 3]])
>>> hyponet_layout(6)  # rows of 2 vec4: w1 6 rows, b1, w2 8 rows (6 and padding), b2, w3
{'row': 2, 'w1': 0, 'b1': 12, 'w2': 14, 'b2': 30, 'w3': 32, 'b3': 34, 'size': 35}
"""

from __future__ import annotations

import numpy as np

from brdfkit.errors import InputError
from brdfkit.view.textures import blob, encode_planes

__all__ = ["mapping_constants", "slot_layout", "slot_fill", "basis_textures", "coefficient_slots", "hyponet_layout",
           "pack_hyponet", "material_uniforms", "basis_data", "live_material", "LIVE_KINDS", "MAX_COMPONENTS",
           "TEXTURE_SLOTS"]

LIVE_KINDS = ("basis", "residual")
"""The embedding kinds a shader decodes."""
TEXTURE_SLOTS = 4
"""Slots a basis texture holds (RGBA)."""
MAX_COMPONENTS = 30
"""The most components a shader decodes: the reference, the mean and the components in
eight textures (``brdfkit_decode.glsl`` binds ``BRDFKIT_TEXTURES`` samplers; eight fit in
any WebGL2 fragment shader's 16 texture units beside the page's own)."""


def mapping_constants(basis) -> dict:
    """The constants of :func:`brdfkit.basis.mapping.from_mapped`'s inverse and bound for
    ``basis`` (:class:`~brdfkit.basis.model.PcaBasis`), by name, in the order of the
    shader's ``brdfkit_mapping`` array: ``eps``, ``floor``, ``cap``, ``tiny`` and
    ``w_tiny`` (the bound ``min(floor x_ref, cap) + tiny min(w / w_tiny, 1)``, read off
    :func:`~brdfkit.basis.mapping.lower_bound` itself), the basis's ``w_floor``, and its
    mapping's resolution ``share`` (0: Nielsen's mapping) with what a mapping with a share
    decodes by (:class:`~brdfkit.basis.mapping.LogMapping`: ``share_floor``, ``e_min``
    and ``z_max``).

    A constant added here is a define ``BRDFKIT_MAPPING_<NAME>`` (its index) of the
    shader's, which reads it as ``brdfkit_mapping[BRDFKIT_MAPPING_<NAME>]``.
    """
    from brdfkit.basis.mapping import E_MIN, CAP, EPS, FLOOR, SHARE_FLOOR, Z_MAX, lower_bound

    tiny = float(lower_bound(np.float64(0.0), np.float64(1.0)))
    w = 1e-6  # far below w_tiny: the bound's absolute part is tiny w / w_tiny there
    w_tiny = tiny * w / float(lower_bound(np.float64(0.0), np.float64(w)))
    return {"eps": float(EPS), "floor": float(FLOOR), "cap": float(CAP), "tiny": tiny, "w_tiny": w_tiny,
            "w_floor": float(basis.w_floor), "share": float(basis.mapping.share), "share_floor": float(SHARE_FLOOR),
            "e_min": float(E_MIN), "z_max": float(Z_MAX)}


def slot_layout(k: int) -> list[list[int]]:
    """The basis's slots (0: ``x_ref``, 1: the mean, ``2 + j``: component ``j``) of each
    texture, for ``k`` components: ``[[0, 1, 2, 3], [4, ...], ...]``.

    Examples
    --------
    >>> slot_layout(3)
    [[0, 1, 2, 3], [4]]
    """
    n = k + 2
    return [list(range(s, min(s + TEXTURE_SLOTS, n))) for s in range(0, n, TEXTURE_SLOTS)]


def slot_fill(k: int) -> list[float]:
    """Each slot's value off the basis's cells: ``x_ref`` -1 (the shader's "no cell"),
    the others 0."""
    return [-1.0] + [0.0] * (k + 1)


def basis_textures(basis, k: int) -> list[np.ndarray]:
    """The decoder's textures of the ``k`` leading components of ``basis``: float32
    ``(90, 90, 180, 4)`` each (:func:`slot_layout`, :func:`slot_fill`)."""
    from brdfkit.geometry import N_CELLS

    part = basis.leading(k)
    slots, fill = [part.reference, part.mean, *part.components], slot_fill(k)
    out = []
    for texture in slot_layout(k):
        tex = np.zeros((N_CELLS, TEXTURE_SLOTS), np.float32)
        for channel, s in enumerate(texture):
            tex[:, channel] = fill[s]
            tex[part.cells, channel] = slots[s]
        out.append(tex.reshape(90, 90, 180, TEXTURE_SLOTS))
    return out


def coefficient_slots(coefficients) -> list[float]:
    """One channel's ``brdfkit_coefficients``: the coefficient of each slot of each texture
    (``x_ref`` 0, the mean 1, component ``j`` ``c_j``), float32 values."""
    c = np.asarray(coefficients, np.float64)
    layout = slot_layout(c.shape[0])
    out = np.zeros(TEXTURE_SLOTS * len(layout))
    out[1], out[2:2 + c.shape[0]] = 1.0, c
    return [float(x) for x in out.astype(np.float32)]


def hyponet_layout(width: int) -> dict:
    """Where ``brdfkit_net`` holds the hyponet's tensors (vec4 offsets): ``w1`` (6 rows),
    ``b1``, ``w2`` (``width`` rows, then padding rows to a multiple of 4), ``b2``, ``w3``,
    ``b3`` (one vec4), each row ``row`` vec4 (``width`` padded to a multiple of 4), and the
    array's ``size``."""
    r = -(-int(width) // 4)
    out = {"row": r, "w1": 0, "b1": 6 * r, "w2": 7 * r}
    out["b2"] = out["w2"] + 4 * r * r
    out["w3"] = out["b2"] + r
    out["b3"] = out["w3"] + r
    out["size"] = out["b3"] + 1
    return out


def pack_hyponet(weights: list, index: int, layout: dict) -> list[float]:
    """Hyponet ``index`` of ``weights`` (:func:`brdfkit.residual.network.hyponet_weights`)
    as ``brdfkit_net`` (:func:`hyponet_layout`), float32 values."""
    w1, b1, w2, b2, w3, b3 = (np.asarray(w[index], np.float32) for w in weights)
    r = layout["row"]
    net = np.zeros((layout["size"], 4), np.float32)
    rows = net[:layout["b3"]].reshape(-1, 4 * r)  # whole rows up to b3 (every offset is a multiple of r)
    for name, values in (("w1", w1), ("b1", b1[None]), ("w2", w2), ("b2", b2[None]), ("w3", w3[:, 0][None])):
        start = layout[name] // r
        rows[start:start + values.shape[0], :values.shape[1]] = values
    net[layout["b3"], 0] = b3[0]
    return [float(x) for x in net.reshape(-1)]


def _defines(k: int, constants: dict, net_layout: dict | None) -> dict:
    textures = len(slot_layout(k))
    out = {"BRDFKIT_TEXTURES": textures, "BRDFKIT_TAPS": " + ".join(f"BRDFKIT_TAP({t})" for t in range(textures)),
           "BRDFKIT_MAPPING_SIZE": len(constants),
           **{f"BRDFKIT_MAPPING_{name.upper()}": i for i, name in enumerate(constants)},
           "BRDFKIT_WIDTH": 4 * net_layout["row"] if net_layout else 0}
    out.update({f"BRDFKIT_NET_{name.upper()}": v for name, v in (net_layout or {}).items()})
    return out


def material_uniforms(material: dict) -> dict:
    """What the shader needs of a live material (:func:`live_material`): ``defines``
    (name -> value), ``uniforms`` (name -> number or flat list, the same for every colour
    channel) and ``channels`` (each colour channel's own uniforms: its coefficients and,
    with a correction, its hyponet).

    Examples
    --------
    >>> from brdfkit.testing.examples import tiny_basis
    >>> m = {"k": 2, "basis": tiny_basis(4), "coefficients": [0.5] * 6, "gain": 0.0, "net": None}
    >>> u = material_uniforms(m)
    >>> u["defines"]["BRDFKIT_TAPS"], u["channels"][0]["brdfkit_coefficients"]
    ('BRDFKIT_TAP(0)', [0.0, 1.0, 0.5, 0.5])
    """
    k, basis, net = material["k"], material["basis"], material["net"]
    c = np.asarray(material["coefficients"], np.float64).reshape(k, 3)
    constants = mapping_constants(basis)
    channels = [{"brdfkit_coefficients": coefficient_slots(c[:, ch])} for ch in range(3)]
    layout = None
    if net is not None:
        from brdfkit.residual.network import hyponet_weights, net_input

        cfg, state = net
        layout = hyponet_layout(cfg.width)
        z = net_input((c / np.asarray(basis.sigma[:k], np.float64)[:, None]).T, cfg.k_max)
        weights = hyponet_weights(state, cfg, z)
        for ch in range(3):
            channels[ch]["brdfkit_net"] = pack_hyponet(weights, ch, layout)
    uniforms = {"brdfkit_mapping": list(constants.values()), "brdfkit_gain": float(material["gain"]) if net else 0.0}
    return {"defines": _defines(k, constants, layout), "uniforms": uniforms, "channels": channels}


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
    (:class:`~brdfkit.basis.model.PcaBasis`): its slots' storage (``compact`` or
    ``float32``) and blobs, and their textures' ``layout`` and ``fill``
    (:func:`slot_layout`, :func:`slot_fill`)."""
    part = basis.leading(k)
    out = {"k": int(k), "layout": slot_layout(k), "fill": slot_fill(k), "cell_mask": blob(_mask(part.cells), compress)}
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


def live_material(emb, decoder, name: str) -> dict:
    """What the shader needs of one embedding besides its basis:
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
