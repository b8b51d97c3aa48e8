"""``brdfkit material``: one of the real materials brdfkit ships, written as a MERL table
(:func:`brdfkit.materials.nbrdf_networks.write_material`), the one table to try that
``docs/getting-started.md`` starts from."""

from __future__ import annotations

import os
import time

import numpy as np
import pytest

from brdfkit.io.merl import MERL_FILE_SIZE, read_merl
from brdfkit.materials.nbrdf_networks import MATERIAL_NOTES, load_nbrdf_weights, material_names, nbrdf_table

from conftest import brdfkit_command, one_error_line, quiet_env, run_cli, tmp_leftovers

SHIPPED = ["blue-metallic-paint", "teflon", "chrome-steel", "violet-rubber"]


def test_list_names_the_four_shipped_materials(capsys):
    assert material_names() == SHIPPED and sorted(MATERIAL_NOTES) == sorted(SHIPPED)
    code, out, err = run_cli(capsys, ["material", "--list"])
    assert code == 0 and err == ""
    rows = out.splitlines()
    assert [r.split()[0] for r in rows] == SHIPPED
    assert all(MATERIAL_NOTES[r.split()[0]] in r for r in rows)


def test_writes_the_table_the_demo_decodes(tmp_path, capsys):
    out = tmp_path / "teflon.binary"
    code, stdout, err = run_cli(capsys, ["material", "teflon", "-o", out])
    assert code == 0 and stdout == "" and f"wrote {out}" in err.replace("\n", "")
    assert out.stat().st_size == MERL_FILE_SIZE == 34_992_012
    np.testing.assert_allclose(read_merl(out), nbrdf_table(load_nbrdf_weights()["teflon"], device="cpu"),
                               rtol=1e-12, equal_nan=True)
    assert tmp_leftovers(tmp_path) == []


def test_output_folder_and_default_name(tmp_path, capsys, monkeypatch):
    folder = tmp_path / "tables"
    folder.mkdir()
    code, _, err = run_cli(capsys, ["material", "violet-rubber", "-o", folder])
    assert code == 0, err
    assert os.listdir(folder) == ["violet-rubber.binary"]
    monkeypatch.chdir(tmp_path)
    code, _, err = run_cli(capsys, ["material", "chrome-steel"])
    assert code == 0, err
    assert (tmp_path / "chrome-steel.binary").stat().st_size == MERL_FILE_SIZE


@pytest.mark.parametrize("args, message", [
    (["pink-felt", "-o", "{tmp}/x.binary"], "unknown material 'pink-felt'; the shipped ones are "
                                            "blue-metallic-paint, teflon, chrome-steel, violet-rubber"),
    (["teflon", "-o", "{tmp}/t.bsdf"], "t.bsdf: brdfkit material writes a MERL table; name it .binary"),
    (["teflon", "-o", "{tmp}/no/t.binary"], "does not exist"),
    (["teflon", "--list"], "--list lists the shipped materials; give it alone"),
])
def test_bad_name_or_output_is_one_line_and_writes_nothing(tmp_path, capsys, args, message):
    code, _, err = run_cli(capsys, ["material", *[a.format(tmp=tmp_path) for a in args]])
    assert code == 2 and message in one_error_line(err)
    assert os.listdir(tmp_path) == []


def test_no_name_prints_the_help_and_exits_2(capsys):
    code, out, err = run_cli(capsys, ["material"])
    assert code == 2 and out == "" and "Usage: brdfkit material" in err and "--list" in err


@pytest.mark.slow
def test_as_a_user_runs_it_in_seconds(tmp_path):
    """The one subprocess: the console script, start-up and torch's import included."""
    import subprocess

    start = time.perf_counter()
    r = subprocess.run([*brdfkit_command(), "material", "blue-metallic-paint", "-o", tmp_path / "b.binary"],
                       capture_output=True, text=True, timeout=120, env=quiet_env())
    wall = time.perf_counter() - start
    assert r.returncode == 0 and r.stdout == "", r.stderr
    assert (tmp_path / "b.binary").stat().st_size == MERL_FILE_SIZE
    assert wall < 60, f"brdfkit material took {wall:.1f} s"  # a few seconds; generous on a busy machine
