"""``brdfkit export x.emb --glsl DIR``: a basis or residual embedding's decoder as GLSL
for an engine, with its textures and the material's uniforms.

The folder holds:

* ``brdfkit_decode.glsl`` and ``brdfkit_bake.frag``: the decoder (``brdfkit_cell``, the
  closed form of the basis plus the residual's hyponet) and the pass that bakes the
  decoded table into a 3D texture, one ``theta_h`` layer and one channel a draw;
* ``brdfkit_eval.glsl``: ``vec3 brdfkit_eval(vec3 wi, vec3 wo)``, the BRDF (1/sr) at a
  pair of local directions, looked up in that texture as ``brdfkit render`` looks tables
  up;
* ``brdfkit_basis<T>.bin``: the basis as ``T`` 3D textures, RGBA float32
  little-endian, 180 x 90 x 90 (``phi_d``, ``theta_d``, ``theta_h``);
* ``material.json``: the defines, the uniforms per channel (coefficients, the hyponet's
  weights that the residual's hypernetwork makes of them, the mapping's constants) and
  the embedding's own numbers;
* ``view.html``: the page of ``brdfkit view --live`` for this material, its shaders
  these very files (open it to see the export render);
* ``README.md``: how to bind them.

The same GLSL decodes the page's live materials (:mod:`brdfkit.view.live`), which
computes the hyponet's weights in JavaScript from the ``3 K`` numbers instead.
"""

from __future__ import annotations

import json
import os

import numpy as np

from brdfkit.errors import InputError

__all__ = ["EXPORT_SHADERS", "basis_textures", "material_uniforms", "export_glsl"]

EXPORT_SHADERS = {"eval": "brdfkit_eval.glsl", "decode": "brdfkit_decode.glsl", "bake": "brdfkit_bake.frag"}
"""The GLSL files an export writes, by the name the page knows them by."""


def basis_textures(basis, k: int) -> list[np.ndarray]:
    """The decoder's textures of the ``k`` leading components of ``basis``: float32
    ``(90, 90, 180, 4)`` each, slots ``x_ref, mean, U_0, U_1``, then ``U_2 .. U_5``, ...;
    ``x_ref = -1`` off the basis's cells."""
    from brdfkit.geometry import N_CELLS

    part = basis.leading(k)
    slots = [part.reference, part.mean, *part.components]
    out = []
    for t in range(-(-len(slots) // 4)):
        tex = np.zeros((N_CELLS, 4), np.float32)
        if t == 0:
            tex[:, 0] = -1.0
        for s, values in enumerate(slots[4 * t:4 * t + 4]):
            tex[part.cells, s] = values
        out.append(tex.reshape(90, 90, 180, 4))
    return out


def _pack_hyponet(weights: list, row: int, width: int) -> np.ndarray:
    """One channel's hyponet tensors (:func:`brdfkit.residual.network.hyponet_weights`)
    as ``brdfkit_net``: w1 (6 rows), b1, w2 (W rows), b2, w3, b3, each row padded to
    ``width`` (a multiple of 4), float32 ``(n, 4)``."""
    w1, b1, w2, b2, w3, b3 = (np.asarray(w[row], np.float32) for w in weights)
    w = b1.shape[0]

    def pad(v):
        out = np.zeros(width, np.float32)
        out[:w] = v
        return out

    rows = [pad(r) for r in w1] + [pad(b1)] + [pad(r) for r in w2] + [np.zeros(width, np.float32)] * (width - w)
    rows += [pad(b2), pad(w3[:, 0]), np.array([b3[0], 0.0, 0.0, 0.0], np.float32)]
    return np.concatenate(rows).reshape(-1, 4)


def material_uniforms(material: dict) -> dict:
    """``material.json``'s ``defines`` and ``uniforms`` (per channel where they differ) of
    a live material (:func:`brdfkit.view.live.live_material`)."""
    from brdfkit.view.live import mapping_constants

    k, basis = material["k"], material["basis"]
    c = np.asarray(material["coefficients"], np.float64).reshape(k, 3)
    textures = -(-(k + 2) // 4)
    m = mapping_constants(basis.w_floor)
    net = material["net"]
    width = 4 * (-(-net[0].width // 4)) if net is not None else 0
    coefficients, nets = [], []
    for ch in range(3):
        slots = np.zeros(4 * textures)
        slots[1], slots[2:2 + k] = 1.0, c[:, ch]
        coefficients.append([float(x) for x in slots.astype(np.float32)])
    if net is not None:
        from brdfkit.residual.network import hyponet_weights, net_input

        cfg, state = net
        z = net_input((c / np.asarray(basis.sigma[:k], np.float64)[:, None]).T, cfg.k_max)
        weights = hyponet_weights(state, cfg, z)
        nets = [[float(x) for x in _pack_hyponet(weights, ch, width).reshape(-1)] for ch in range(3)]
    uniforms = {"brdfkit_coefficients": coefficients, "brdfkit_mapping": [m["eps"], m["floor"], m["cap"], m["w_floor"]],
                "brdfkit_tiny": [m["tiny"], m["w_tiny"]], "brdfkit_gain": material["gain"] if net else 0.0,
                "brdfkit_scale": 1.0}
    if nets:
        uniforms["brdfkit_net"] = nets
    return {"defines": {"BRDFKIT_TEXTURES": textures, "BRDFKIT_WIDTH": width}, "uniforms": uniforms}


def _readme(name: str, material: dict, info: dict, textures: int) -> str:
    from brdfkit.view.page import asset

    text = asset("export_readme.md")
    return (text.replace("{{NAME}}", name).replace("{{KIND}}", material["kind"]).replace("{{K}}", str(material["k"]))
            .replace("{{SIZE}}", str(3 * material["k"])).replace("{{TEXTURES}}", str(textures))
            .replace("{{LAST}}", str(textures - 1)).replace("{{WIDTH}}", str(info["defines"]["BRDFKIT_WIDTH"]))
            .replace("{{GAIN}}", f"{material['gain'] if material['net'] else 0.0:g}"))


def export_glsl(path, folder, *, model_path=None) -> dict:
    """Write the GLSL export of the embedding ``path`` into ``folder`` (created; files
    written atomically).

    Parameters
    ----------
    path
        A basis or residual embedding (``.emb``).
    folder
        The output folder.
    model_path
        Its decoder (default: the installed built-in part it names).

    Returns
    -------
    dict
        ``{"folder", "files": [(name, bytes)], "kind", "size"}``.
    """
    from brdfkit.atomic import atomic_open, check_input_file
    from brdfkit.files.brdf_file import EmbeddingDecoders, file_type
    from brdfkit.io.embedding import read_embedding
    from brdfkit.view.live import LIVE_KINDS, live_material
    from brdfkit.view.page import asset, write_page

    path, folder = os.fspath(check_input_file(path)), os.fspath(folder)
    if file_type(path) != "embedding":
        raise InputError(f"{path}: brdfkit export takes an embedding (.emb) of kind {' or '.join(LIVE_KINDS)}")
    if os.path.exists(folder) and not os.path.isdir(folder):
        raise InputError(f"{folder}: exists and is not a folder")
    emb = read_embedding(path)
    decoder = EmbeddingDecoders(model_path).decoder(emb, path) if emb.kind in LIVE_KINDS else None
    if decoder is None or decoder.kind not in LIVE_KINDS:
        raise InputError(f"{path}: a {emb.kind} embedding has no GLSL decoder (export takes "
                         f"{' or '.join(LIVE_KINDS)} embeddings)")
    material = live_material(emb, decoder, path)
    os.makedirs(folder, exist_ok=True)
    info = material_uniforms(material)
    textures = basis_textures(material["basis"], material["k"])
    files = {f: asset(f).encode() for f in EXPORT_SHADERS.values()}
    for t, tex in enumerate(textures):
        files[f"brdfkit_basis{t}.bin"] = np.ascontiguousarray(tex, "<f4").tobytes()
    doc = {"format": "brdfkit-glsl-material", "version": 1, "source": os.path.basename(path), "kind": material["kind"],
           "size": 3 * material["k"], "values": material["coefficients"], **info,
           "textures": [{"file": f"brdfkit_basis{t}.bin", "uniform": f"brdfkit_basis{t}", "width": 180, "height": 90,
                         "depth": 90, "format": "RGBA32F", "type": "float32 little-endian"}
                        for t in range(len(textures))]}
    files["material.json"] = (json.dumps(doc, indent=1) + "\n").encode()
    name = os.path.splitext(os.path.basename(path))[0]
    files["README.md"] = _readme(name, material, info, len(textures)).encode()
    for f, data in files.items():
        with atomic_open(os.path.join(folder, f), "wb") as out:
            out.write(data)
    shaders = {k: files[f].decode() for k, f in EXPORT_SHADERS.items()}
    page = write_page([path], os.path.join(folder, "view.html"), model_path=model_path, live=True, shaders=shaders)
    listed = [(f, len(d)) for f, d in files.items()] + [("view.html", page["bytes"])]
    return {"folder": folder, "files": listed, "kind": material["kind"], "size": 3 * material["k"]}
