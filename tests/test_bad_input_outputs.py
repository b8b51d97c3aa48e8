"""An output that names an input is refused by every command that writes (issue 6,
docs/errors.md): exit code 2, one line naming the path, nothing touched and nothing new.
(``sample``, ``decode -o EMB``, ``sparse -o SAMPLES`` and ``interpolate -o A`` are in
``test_cli_basics.py`` and ``test_cli_model.py``.)
"""

from __future__ import annotations

import os

import pytest

from conftest import one_error_line, run_cli


OVERWRITES = {  # name -> (arguments given the folder d of copied inputs, the refused path)
    # a MERL table that happens to be named .emb: encode would write d/t.emb over it
    "encode beside": (lambda d: ["encode", d / "t.emb", "-m", d / "model.safetensors"], "t.emb"),
    "encode -o": (lambda d: ["encode", d / "t.emb", "-m", d / "model.safetensors", "-o", d], "t.emb"),
    "decode -o model": (lambda d: ["decode", d / "a.emb", "-m", d / "model.safetensors", "-o",
                                   d / "model.safetensors"], "model.safetensors"),
    "sparse --emb samples": (lambda d: ["sparse", d / "samples.csv", "-m", d / "model.safetensors", "-o",
                                        d / "x.binary", "--emb", d / "samples.csv"], "samples.csv"),
    "sparse -o model": (lambda d: ["sparse", d / "samples.csv", "-m", d / "model.safetensors", "-o",
                                   d / "model.safetensors"], "model.safetensors"),
    "interpolate --binary b": (lambda d: ["interpolate", d / "a.emb", d / "b.emb", "--t", "0.5", "-o", d / "x.emb",
                                          "--binary", d / "b.emb", "-m", d / "model.safetensors"], "b.emb"),
    "interpolate -o model": (lambda d: ["interpolate", d / "a.emb", d / "b.emb", "--t", "0.5", "-o",
                                        d / "model.safetensors", "-m", d / "model.safetensors"],
                             "model.safetensors"),
}


@pytest.mark.parametrize("case", sorted(OVERWRITES))
def test_output_equal_to_an_input_is_refused(good, tmp_path, capsys, case):
    # (sample, decode -o EMB, sparse -o SAMPLES and interpolate -o A are in
    # test_cli_basics.py and test_cli_model.py)
    import shutil

    for name in ("model.safetensors", "samples.csv", "a.emb", "b.emb"):
        shutil.copy(good / name, tmp_path / name)
    shutil.copy(good / "mat.binary", tmp_path / "t.emb")
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    args, victim = OVERWRITES[case]
    code, _, err = run_cli(capsys, args(tmp_path))
    assert code == 2
    assert one_error_line(err) == f"brdfkit: error: {tmp_path / victim}: output path is also an input; " \
                              f"refusing to overwrite it"
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before  # nothing touched, nothing new


def test_fit_output_equal_to_an_input_is_refused(good, tmp_path, capsys):
    import shutil

    shutil.copy(good / "mat.binary", tmp_path / "mat.binary")
    before = (tmp_path / "mat.binary").read_bytes()
    code, _, err = run_cli(capsys, ["fit", tmp_path, "-o", tmp_path / "mat.binary", "--steps", "1", "-q"])
    assert code == 2
    assert one_error_line(err) == f"brdfkit: error: {tmp_path / 'mat.binary'}: output path is also an input; " \
                              f"refusing to overwrite it"
    assert os.listdir(tmp_path) == ["mat.binary"] and (tmp_path / "mat.binary").read_bytes() == before


def test_render_png_equal_to_the_input_is_refused(good, tmp_path, capsys):
    import shutil

    shutil.copy(good / "mat.binary", tmp_path / "mat.binary")
    before = (tmp_path / "mat.binary").read_bytes()
    code, _, err = run_cli(capsys, ["render", tmp_path / "mat.binary", "-o", tmp_path / "x.exr", "--png",
                              tmp_path / "mat.binary", "--resolution", "8", "--quiet"])
    assert code == 2
    assert one_error_line(err) == f"brdfkit: error: {tmp_path / 'mat.binary'}: output path is also an input; " \
                              f"refusing to overwrite it"
    assert os.listdir(tmp_path) == ["mat.binary"] and (tmp_path / "mat.binary").read_bytes() == before
