"""Shared helpers of the bad-input tests (``test_bad_input_*.py``): the error-line
checks, and the builders of bad files of each format (the in-process CLI runner
``run_cli``, ``one_error_line`` and the fixtures that call the builders, ``good``,
``bad_merl``, ``bad_models``, ``bad_embs``, are in ``conftest.py``).

Each case of those tests: exit code 2, exactly one line on stderr that names the input
and the problem, no traceback, no output file and no temporary file left behind.
"""

from __future__ import annotations

import os

from conftest import tmp_leftovers
from helpers_model import material_table


def error_lines(err: str) -> list[str]:
    assert "Traceback" not in err, err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    errors = [ln for ln in lines if ln.startswith("brdfkit: error: ")]
    return errors


def check_line(line: str, path, message: str) -> None:
    """``line`` is ``brdfkit: error: PATH: MESSAGE``; a folder may instead be refused by
    Click's own check of the option (``Invalid value for '-m' ...: File 'PATH' is a
    directory. (see 'brdfkit decode --help')``), also one line naming it."""
    if message.startswith("is a directory") and line.startswith("brdfkit: error: Invalid value for"):
        assert f"'{path}' is a directory" in line, line
    else:
        assert line == f"brdfkit: error: {path}: {message}"


def check_emb_line(line, path, message):
    if "{path}" in message:
        assert line == f"brdfkit: error: {message.format(path=path)}"
    else:
        check_line(line, path, message)


def nothing_written(folder, *outputs):
    for out in outputs:
        assert not os.path.exists(out), out
    assert not tmp_leftovers(folder), tmp_leftovers(folder)


def rewrite_header(raw: bytes, edit) -> bytes:
    import json

    n = int.from_bytes(raw[:8], "little")
    header = json.loads(raw[8:8 + n])
    edit(header)
    new = json.dumps(header).encode()
    new += b" " * (-len(new) % 8)
    return len(new).to_bytes(8, "little") + new + raw[8 + n:]


# MERL tables truncated in every region of the file: in the 12-byte header, at its end,
# in each of the three channel blocks, and one byte short.
def merl_variants(folder, good_bytes: bytes) -> dict:
    import numpy as np

    from brdfkit.geometry import N_CELLS

    ch = 8 * N_CELLS
    cuts = {"empty": 0, "header_4": 4, "header_11": 11, "header_only": 12, "red_1": 13,
            "red_half": 12 + ch // 2, "red_end": 12 + ch, "green_half": 12 + ch + ch // 2,
            "blue_start": 12 + 2 * ch + 8, "one_short": len(good_bytes) - 1}
    out = {}
    for name, n in cuts.items():
        out[name] = folder / f"trunc-{name}.binary"
        out[name].write_bytes(good_bytes[:n])
    out["too_long"] = folder / "too-long.binary"
    out["too_long"].write_bytes(good_bytes + b"\0")
    out["wrong_dims"] = folder / "wrong-dims.binary"
    out["wrong_dims"].write_bytes(np.array([90, 90, 360], "<i4").tobytes() + good_bytes[12:])
    nan = bytearray(good_bytes)
    nan[12 + 8 * 5:12 + 8 * 6] = np.array([np.nan]).tobytes()
    out["nan"] = folder / "nan.binary"
    out["nan"].write_bytes(bytes(nan))
    inf = bytearray(good_bytes)
    inf[12 + 2 * ch + 8 * 9:12 + 2 * ch + 8 * 10] = np.array([-np.inf]).tobytes()
    out["inf"] = folder / "inf.binary"
    out["inf"].write_bytes(bytes(inf))
    out["text"] = folder / "notes.binary"
    out["text"].write_text("theta_h,theta_d,phi_d,r,g,b\n")
    out["missing"] = folder / "missing.binary"
    out["directory"] = folder / "folder.binary"
    out["directory"].mkdir()
    return out


MERL_MESSAGES = {
    "empty": "not a MERL table: 0 bytes, too short for the 12-byte header",
    "header_4": "not a MERL table: 4 bytes, too short for the 12-byte header",
    "header_11": "not a MERL table: 11 bytes, too short for the 12-byte header",
    "header_only": "truncated: 12 bytes, a MERL table has exactly 34992012",
    "red_1": "truncated: 13 bytes, a MERL table has exactly 34992012",
    "red_half": "truncated: 5832012 bytes, a MERL table has exactly 34992012",
    "red_end": "truncated: 11664012 bytes, a MERL table has exactly 34992012",
    "green_half": "truncated: 17496012 bytes, a MERL table has exactly 34992012",
    "blue_start": "truncated: 23328020 bytes, a MERL table has exactly 34992012",
    "one_short": "truncated: 34992011 bytes, a MERL table has exactly 34992012",
    "too_long": "too long: 34992013 bytes, a MERL table has exactly 34992012",
    "wrong_dims": "not a MERL table: header dimensions are (90, 90, 360), expected (90, 90, 180)",
    "nan": "NaN value in the payload (channel R, cell 5); 1 non-finite values in all",
    "inf": "infinite value in the payload (channel B, cell 9); 1 non-finite values in all",
    "text": "not a MERL table: header dimensions are not plausible, expected (90, 90, 180)",
    "missing": "no such file",
    "directory": "is a directory, expected a file",
}


def bad_model_files(folder, good_model: bytes) -> dict:
    """name -> (path, the message after "PATH: ")."""
    import pickle

    import torch

    from brdfkit.hypernet.mapping import save_reference
    from brdfkit.io.merl import write_merl

    def put(name, data):
        (folder / name).write_bytes(data)
        return folder / name

    n = int.from_bytes(good_model[:8], "little")
    torch.save({"w": torch.zeros(2)}, folder / "torch-save.safetensors")
    save_reference(folder / "reference.safetensors", material_table(0))
    write_merl(folder / "table.safetensors", material_table(0))
    (folder / "folder.safetensors").mkdir()
    return {
        "missing": (folder / "missing.safetensors", "no such file"),
        "directory": (folder / "folder.safetensors", "is a directory, expected a file"),
        "empty": (put("empty.safetensors", b""),
                  "not a brdfkit model file: 0 bytes, too short for a safetensors header"),
        "text": (put("text.safetensors", b"a text file, not a model\n"),
                 "not a brdfkit model file: not a safetensors file (bad header length)"),
        "pickle": (put("pickle.safetensors", pickle.dumps({"weights": [1.0, 2.0]})),
                   "not a brdfkit model file: this is a pickle / torch.save file, which brdfkit never "
                   "loads (model files are .safetensors)"),
        "torch_save": (folder / "torch-save.safetensors",
                       "not a brdfkit model file: this is a pickle / torch.save file, which brdfkit never "
                       "loads (model files are .safetensors)"),
        "truncated_header": (put("cut-header.safetensors", good_model[:100]),
                             f"truncated: 100 bytes, the safetensors header alone needs {8 + n}"),
        "truncated_payload": (put("cut-payload.safetensors", good_model[:len(good_model) // 2]),
                              f"truncated: {len(good_model) // 2} bytes, its safetensors header "
                              f"describes {len(good_model)}"),
        "reference_table": (folder / "reference.safetensors",
                            "not a brdfkit model file (format 'brdfkit-reference', expected 'brdfkit-model')"),
        "merl_table": (folder / "table.safetensors",
                       "is a MERL BRDF table, not a brdfkit model file (-m takes the .safetensors file "
                       "written by `brdfkit fit`)"),
    }


def bad_embedding_files(folder, good_doc: dict, other_doc: dict) -> dict:
    """name -> (path, the message after "PATH: ", or a full message without the path)."""
    import json

    def put(name, doc=None, raw=None):
        (folder / name).write_text(raw if raw is not None else json.dumps(doc))
        return folder / name

    fp = good_doc["decoder"]
    (folder / "folder.emb").mkdir()
    return {
        "missing": (folder / "missing.emb", "no such file"),
        "directory": (folder / "folder.emb", "is a directory, expected a file"),
        "empty": (put("empty.emb", raw=""),
                  "not an embedding file: not JSON text (Expecting value: line 1 column 1 (char 0))"),
        "not_json": (put("not-json.emb", raw="values = [1, 2, 3]\n"),
                     "not an embedding file: not JSON text (Expecting value: line 1 column 1 (char 0))"),
        "wrong_version": (put("v3.emb", {**good_doc, "version": 3}),
                          "embedding version 3 is not supported (this brdfkit reads versions 1, 2)"),
        "latent_length": (put("length.emb", {**good_doc, "values": good_doc["values"][:-1]}),
                          f"values has {len(good_doc['values']) - 1} values but size is {good_doc['size']}"),
        "latent_dim": (put("dim.emb", {**good_doc, "size": 5, "values": good_doc["values"][:5]}),
                       f"embedding {{path}} (hypernet, 5 numbers, decoder {fp[:12]}) was not made by the given model "
                       f"{fp[:12]} (latent 7); encode the material again with this model"),
        "other_model": (put("other-model.emb", other_doc),
                        f"embedding {{path}} was made with hypernet decoder {other_doc['decoder'][:12]}, not with "
                        f"model.safetensors ({fp[:12]}); encode the material again with it"),
    }


# --- RGL .bsdf files (issue 30) ---------------------------------------------------------------

RGL_SMALL = dict(resolution=8, theta_i=3, ndf=16, vndf=(4, 8))
"""Settings of the small good .bsdf the bad ones are made from (brdfkit.io.rgl.fit.FitSettings)."""


def good_bsdf(path):
    """Write the small good ``.bsdf`` (a Lambertian table) to ``path``; returns ``path``."""
    from brdfkit.io.rgl_bsdf import FitSettings, write_bsdf
    from brdfkit.testing.examples import lambertian_table

    write_bsdf(path, lambertian_table((0.6, 0.5, 0.4)), FitSettings(**RGL_SMALL), description="good")
    return path


def rgl_variants(folder, good_path) -> dict:
    """name -> (path of a malformed ``.bsdf``, the message after "PATH: ")."""
    import numpy as np

    from brdfkit.io.rgl.container import read_tensor_file, write_tensor_file

    raw = good_path.read_bytes()
    fields = read_tensor_file(good_path)
    out = {}

    def put(name, data, message):
        p = folder / f"{name}.bsdf"
        p.write_bytes(data)
        out[name] = (p, message)

    def edited(name, message, **changes):
        p = folder / f"{name}.bsdf"
        new = {k: v for k, v in fields.items() if changes.get(k, 0) is not None}
        new.update({k: v for k, v in changes.items() if v is not None})
        write_tensor_file(p, new)
        out[name] = (p, message)

    size = len(raw)
    put("empty", b"", "not an RGL .bsdf file: 0 bytes, too short for the 18-byte header")
    put("header_10", raw[:10], "not an RGL .bsdf file: 10 bytes, too short for the 18-byte header")
    put("table_cut", raw[:40], "truncated: 40 bytes, the field table ends inside field 'description'")
    put("data_cut", raw[:size // 2], f"truncated: {size // 2} bytes, field 'rgb' (1, 3, 3, 8, 8) needs {size}")
    put("one_short", raw[:-1], f"truncated: {size - 1} bytes, field 'rgb' (1, 3, 3, 8, 8) needs {size}")
    put("magic", b"tensor_fiel\0" + raw[12:], "not an RGL .bsdf file: no 'tensor_file' magic at the start")
    put("version", raw[:12] + bytes([2, 0]) + raw[14:],
        "tensor file version 2.0 is not supported (this brdfkit reads version 1.0)")
    put("merl", np.array([90, 90, 180], "<i4").tobytes() + b"\0" * 64,
        "not an RGL .bsdf file: no 'tensor_file' magic at the start")
    edited("no_vndf", "not an RGL .bsdf file: missing field 'vndf'", vndf=None)
    edited("no_fields", "not an RGL .bsdf file: missing fields 'theta_i', 'phi_i', 'ndf', 'sigma', 'vndf', "
                        "'luminance', 'rgb', 'description', 'jacobian'",
           **{k: None for k in fields})
    edited("rank", "field 'ndf': float32 of shape (32,), expected float32 of rank 2",
           ndf=fields["ndf"].reshape(-1))
    edited("dtype", "field 'sigma': float64 of shape (2, 16), expected float32 of rank 2",
           sigma=fields["sigma"].astype(np.float64))
    edited("shape", "field 'luminance' has shape (1, 3, 8, 7), expected (1, 3, 8, 8)",
           luminance=fields["luminance"][..., :7])
    edited("theta_count", "field 'vndf' has shape (1, 3, 4, 8), expected (1, 2, 4, 8)",
           theta_i=fields["theta_i"][:2])
    nan = fields["rgb"].copy()
    nan[0, 1, 2, 3, 4] = np.nan
    edited("nan", "field 'rgb' holds NaN values", rgb=nan)
    inf = fields["vndf"].copy()
    inf[0, 0, 1, 1] = np.inf
    edited("inf", "field 'vndf' holds infinite values", vndf=inf)
    edited("negative", "field 'ndf' holds negative values (-1)", ndf=np.full_like(fields["ndf"], -1.0))
    edited("zero_sigma", "field 'sigma' holds zeros: the projected area must be positive",
           sigma=np.zeros_like(fields["sigma"]))
    edited("theta_order", "field 'theta_i' is not strictly increasing", theta_i=fields["theta_i"][::-1].copy())
    spectral = {k: v for k, v in fields.items() if k != "rgb"}
    spectral["spectra"] = np.repeat(fields["rgb"][:, :, :1], 5, axis=2)
    spectral["wavelengths"] = np.linspace(400, 700, 5).astype(np.float32)
    write_tensor_file(folder / "spectral.bsdf", spectral)
    out["spectral"] = (folder / "spectral.bsdf",
                       "spectral .bsdf file (fields 'spectra', 'wavelengths'): brdfkit reads RGB files "
                       "(field 'rgb'; RGL's database offers each material as RGB too)")
    aniso = dict(fields, phi_i=np.linspace(-3.1, 3.1, 4).astype(np.float32))
    for k in ("vndf", "luminance", "rgb"):
        aniso[k] = np.repeat(fields[k], 4, axis=0)
    write_tensor_file(folder / "anisotropic.bsdf", aniso)
    out["anisotropic"] = (folder / "anisotropic.bsdf",
                          "anisotropic material (4 incident azimuths): brdfkit's tables are isotropic; "
                          "this file is refused rather than averaged")
    out["missing"] = (folder / "missing.bsdf", "no such file")
    (folder / "folder.bsdf").mkdir()
    out["directory"] = (folder / "folder.bsdf", "is a directory, expected a file")
    return out
