"""``brdfkit export x.emb --glsl DIR``: a basis or residual embedding's decoder as GLSL
for an engine, with its textures and the material's defines and uniforms.

The folder holds:

* ``brdfkit_decode.glsl`` and ``brdfkit_bake.frag``: the decoder (``brdfkit_cell``, the
  closed form of the basis plus the residual's hyponet) and the pass that bakes the
  decoded table into a 3D texture, one ``theta_h`` layer and one channel a draw;
* ``brdfkit_eval.glsl``: ``vec3 brdfkit_eval(vec3 wi, vec3 wo)``, the BRDF (1/sr) at a
  pair of local directions, looked up in that texture as ``brdfkit render`` looks tables
  up;
* ``brdfkit_grid.glsl``: the MERL grid, which both need (each file names the files it
  needs in a line ``#pragma brdfkit require(FILE)``);
* ``brdfkit_basis<T>.bin``: the basis as ``T`` 3D textures, RGBA float32
  little-endian, 180 x 90 x 90 (``phi_d``, ``theta_d``, ``theta_h``);
* ``material.json``: the defines, the uniforms (those of every colour channel, and each
  channel's own) and the embedding's own numbers (:func:`brdfkit.view.live.material_uniforms`,
  what the page of ``brdfkit view --live`` sets too);
* ``view.html``: the page of ``brdfkit view --live`` for this material, its shaders
  these very files (open it to see the export render);
* ``README.md``: how to bind them.

The folder is new or empty: one that holds files is refused, unless ``force`` (then the
export's own files are written over, an earlier export's textures that this one does not
have are removed, and nothing else is touched).
"""

from __future__ import annotations

import json
import os
import re

import numpy as np

from brdfkit.errors import InputError

__all__ = ["EXPORT_SHADERS", "MATERIAL_FORMAT", "export_glsl", "export_files"]

EXPORT_SHADERS = ("brdfkit_bake.frag", "brdfkit_eval.glsl")
"""The GLSL an export is for: the bake pass and the lookup, with the files they require
(:func:`brdfkit.view.page.glsl_files`)."""
_TEXTURE = re.compile(r"brdfkit_basis[0-9]+\.bin")
MATERIAL_FORMAT = {"format": "brdfkit-glsl-material", "version": 2}
"""``material.json``'s format (version 2: the defines and uniforms of
:func:`brdfkit.view.live.material_uniforms`, the basis a sampler array)."""


def _shader_files() -> list[str]:
    from brdfkit.view.page import glsl_files

    out: list[str] = []
    for name in EXPORT_SHADERS:
        out += [f for f in glsl_files(name) if f not in out]
    return out


def _readme(name: str, material: dict, info: dict, textures: int) -> str:
    from brdfkit.view.page import GLSL_HEADER, asset

    defines = "\n".join(f"#define {k} {v}" for k, v in info["defines"].items())
    return (asset("export_readme.md").replace("{{NAME}}", name).replace("{{KIND}}", material["kind"])
            .replace("{{K}}", str(material["k"])).replace("{{SIZE}}", str(3 * material["k"]))
            .replace("{{TEXTURES}}", str(textures)).replace("{{LAST}}", str(textures - 1))
            .replace("{{HEADER}}", GLSL_HEADER.rstrip("\n")).replace("{{DEFINES}}", defines)
            .replace("{{ORDER}}", ", ".join(f"`{f}`" for f in _shader_files())))


def export_files(path, material: dict) -> dict:
    """The export's files of a live material (:func:`brdfkit.view.live.live_material`) read
    from ``path``: ``{name: bytes}``, ``view.html`` aside."""
    from brdfkit.view.live import basis_textures, material_uniforms
    from brdfkit.view.page import asset

    info = material_uniforms(material)
    textures = basis_textures(material["basis"], material["k"])
    files = {f: asset(f).encode() for f in _shader_files()}
    for t, tex in enumerate(textures):
        files[f"brdfkit_basis{t}.bin"] = np.ascontiguousarray(tex, "<f4").tobytes()
    doc = {**MATERIAL_FORMAT, "source": os.path.basename(path), "kind": material["kind"],
           "size": 3 * material["k"], "values": material["coefficients"], **info,
           "textures": [{"file": f"brdfkit_basis{t}.bin", "uniform": f"brdfkit_basis[{t}]", "width": 180, "height": 90,
                         "depth": 90, "format": "RGBA32F", "type": "float32 little-endian"}
                        for t in range(len(textures))]}
    files["material.json"] = (json.dumps(doc, indent=1) + "\n").encode()
    name = os.path.splitext(os.path.basename(path))[0]
    files["README.md"] = _readme(name, material, info, len(textures)).encode()
    return files


def _remove_stale_textures(folder: str, files: dict) -> None:
    """Remove the textures of an earlier export of more components from ``folder``
    (``--force``): ``material.json`` lists the textures to bind, and a stale
    ``brdfkit_basis<T>.bin`` beside them would be taken for part of this export."""
    for f in os.listdir(folder):
        if _TEXTURE.fullmatch(f) and f not in files:
            os.unlink(os.path.join(folder, f))


def _check_folder(folder: str, force: bool) -> None:
    if os.path.exists(folder) and not os.path.isdir(folder):
        raise InputError(f"{folder}: exists and is not a folder")
    if not force and os.path.isdir(folder) and os.listdir(folder):
        raise InputError(f"{folder}: the folder holds files; export into a new or empty folder, or add --force to "
                         f"write the export's files over those of the same names")


def export_glsl(path, folder, *, model_path=None, force: bool = False) -> dict:
    """Write the GLSL export of the embedding ``path`` into ``folder`` (created; files
    written atomically).

    Parameters
    ----------
    path
        A basis or residual embedding (``.emb``).
    folder
        The output folder: new or empty, unless ``force``.
    model_path
        Its decoder (default: the installed built-in part it names).
    force
        Write into a folder that holds files (the export's own files over those of the
        same names).

    Returns
    -------
    dict
        ``{"folder", "files": [(name, bytes)], "kind", "size"}``.
    """
    from brdfkit.atomic import atomic_open, check_input_file
    from brdfkit.files.brdf_file import EmbeddingDecoders, file_type
    from brdfkit.io.embedding import read_embedding
    from brdfkit.view.live import LIVE_KINDS, live_material
    from brdfkit.view.page import write_page

    path, folder = os.fspath(check_input_file(path)), os.fspath(folder)
    if file_type(path) != "embedding":
        raise InputError(f"{path}: brdfkit export takes an embedding (.emb) of kind {' or '.join(LIVE_KINDS)}")
    _check_folder(folder, force)
    emb = read_embedding(path)
    decoder = EmbeddingDecoders(model_path).decoder(emb, path) if emb.kind in LIVE_KINDS else None
    if decoder is None or decoder.kind not in LIVE_KINDS:
        raise InputError(f"{path}: a {emb.kind} embedding has no GLSL decoder (export takes "
                         f"{' or '.join(LIVE_KINDS)} embeddings)")
    material = live_material(emb, decoder, path)
    files = export_files(path, material)
    os.makedirs(folder, exist_ok=True)
    for f, data in files.items():
        with atomic_open(os.path.join(folder, f), "wb") as out:
            out.write(data)
    _remove_stale_textures(folder, files)
    shaders = {f: files[f].decode() for f in _shader_files()}
    page = write_page([path], os.path.join(folder, "view.html"), model_path=model_path, live=True, shaders=shaders)
    listed = [(f, len(d)) for f, d in files.items()] + [("view.html", page["bytes"])]
    return {"folder": folder, "files": listed, "kind": material["kind"], "size": 3 * material["k"]}
