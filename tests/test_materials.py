"""brdfkit.io.folders: the one scanner of material folders (training and the benchmark)."""

from __future__ import annotations

import pytest

from brdfkit.errors import InputError
from brdfkit.io.folders import list_materials, material_name, scan_folder


def _folder(tmp_path, names):
    for n in names:
        (tmp_path / n).write_bytes(b"")
    return tmp_path


def test_scan_folder_names_and_order(tmp_path):
    d = _folder(tmp_path, ["b.binary", "a.binary", ".hidden.binary", "notes.txt", "c.binary.bak"])
    (tmp_path / "sub.binary").mkdir()
    found = scan_folder(d)
    assert list(found) == ["a", "b", "sub"]  # a folder named *.binary is listed; reading it fails later
    assert found["a"] == str(d / "a.binary")
    assert material_name(d / "a.binary") == "a" and material_name("x.csv") == "x"


def test_list_materials_selects_in_the_order_given(tmp_path):
    d = _folder(tmp_path, ["a.binary", "b.binary", "c.binary"])
    assert [n for n, _ in list_materials(d)] == ["a", "b", "c"]
    assert list_materials(d, ["c", "a.binary", "c"]) == [("c", str(d / "c.binary")), ("a", str(d / "a.binary"))]
    with pytest.raises(InputError, match="no table for test material\\(s\\) x, y"):
        list_materials(d, ["a", "x", "y"])
    with pytest.raises(InputError, match="the test list names no material"):
        list_materials(d, [])


def test_empty_folder_refused(tmp_path):
    with pytest.raises(InputError, match="folder holds no .binary files"):
        scan_folder(tmp_path)
    with pytest.raises(InputError, match="folder holds no .binary files"):
        list_materials(tmp_path)
