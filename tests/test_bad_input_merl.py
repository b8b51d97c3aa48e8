"""Bad MERL tables through every command that reads them: encode, fit, render (issue 6,
docs/errors.md).

Each case: exit code 2, exactly one line on stderr that names the file and the problem,
no traceback, no output file and no temporary file left behind (the library-level checks
live in ``test_merl.py``; ``brdfkit sample`` gets every malformed table there). The bad
tables: the ``bad_merl`` fixture of ``conftest.py`` (``helpers_bad_input.merl_variants``).
"""

from __future__ import annotations

import os

import pytest

from conftest import one_error_line, run_cli
from helpers_bad_input import MERL_MESSAGES, check_line, error_lines, nothing_written


@pytest.mark.slow
def test_bad_merl_tables_through_encode(good, bad_merl, tmp_path, capsys):
    # One run over all of them: each reported in its own line, the good one still encoded.
    # (`brdfkit sample` gets every malformed table in test_merl.py::test_cli_sample_on_bad_file.)
    names = sorted(bad_merl)
    code, _, err = run_cli(capsys, ["encode", *[bad_merl[n] for n in names], good / "mat.binary",
                              "-m", good / "model.safetensors", "-o", tmp_path / "out"])
    assert code == 2
    errors = error_lines(err)
    assert len(errors) == len(names)
    assert errors == [f"brdfkit: error: {bad_merl[n]}: {MERL_MESSAGES[n]}" for n in names]
    assert os.listdir(tmp_path / "out") == ["mat.emb"]
    assert f"encoded 1 of {len(names) + 1} files" in err


@pytest.mark.parametrize("name", ["header_11", "green_half", "nan"])
def test_bad_merl_table_alone_through_encode(good, bad_merl, tmp_path, capsys, name):
    code, _, err = run_cli(capsys, ["encode", bad_merl[name], "-m", good / "model.safetensors", "-o", tmp_path])
    assert code == 2
    assert one_error_line(err) == f"brdfkit: error: {bad_merl[name]}: {MERL_MESSAGES[name]}"
    nothing_written(tmp_path, tmp_path / f"{bad_merl[name].stem}.emb")


FIT_MESSAGES = {**MERL_MESSAGES, "missing": "no such file or folder",
                "directory": "folder holds no .binary files"}


@pytest.mark.parametrize("name", sorted(MERL_MESSAGES))
def test_bad_merl_table_through_fit(bad_merl, tmp_path, capsys, name):
    out = tmp_path / "m.safetensors"
    code, _, err = run_cli(capsys, ["fit", bad_merl[name], "-o", out, "--steps", "1", "-q"])
    assert code == 2
    assert one_error_line(err) == f"brdfkit: error: {bad_merl[name]}: {FIT_MESSAGES[name]}"
    assert os.listdir(tmp_path) == []  # no model, no checkpoint, no temporary file


def test_bad_merl_tables_through_render(bad_merl, tmp_path, capsys):
    for name in sorted(MERL_MESSAGES):
        code, _, err = run_cli(capsys, ["render", bad_merl[name], "-o", tmp_path / "x.exr", "--resolution", "8",
                                  "--quiet"])
        assert code == 2, name
        check_line(one_error_line(err), bad_merl[name], MERL_MESSAGES[name])
        assert os.listdir(tmp_path) == [], name
