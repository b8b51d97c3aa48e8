"""No absolute path of a development machine in the repository: records, docs, defaults
and docstrings keep paths relative to the repository (``runs/``, ``proxies/merl``) or to
the data folder (``../shared/data``). Scans every text file ``git ls-files`` lists; skips
where the tree is not a git checkout (an unpacked sdist)."""

from __future__ import annotations

import os
import re
import shutil
import subprocess

import pytest

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# An absolute path on a development machine: the project's work and scratch folders, a
# home folder, pytest's temporary folders. Written in pieces so that this file does not
# match itself. Placeholders such as /path/to/ are not matched.
_ROOTS = "|".join(["wo" + "rk", "ro" + "ot", "t" + "mp", "ho" + r"me/[A-Za-z_][\w.-]*", "Us" + r"ers/[A-Za-z_][\w.-]*"])
MACHINE_PATH = re.compile(rf"(?<![\w.~$-])/(?:{_ROOTS})/")
BINARY_SUFFIXES = (".png", ".exr", ".npz", ".safetensors", ".binary", ".bsdf", ".pdf", ".jpg", ".gz")


def tracked_files() -> list[str]:
    if shutil.which("git") is None or not os.path.exists(os.path.join(REPO, ".git")):
        pytest.skip("not a git checkout: no list of tracked files")
    out = subprocess.run(["git", "ls-files", "-z"], cwd=REPO, capture_output=True, check=True).stdout
    return [p for p in out.decode("utf-8").split("\0") if p]


def machine_paths(text: str) -> list[str]:
    """The development-machine paths in ``text``, each with a little context."""
    return [text[max(m.start() - 30, 0):m.end() + 30].replace("\n", " ") for m in MACHINE_PATH.finditer(text)]


def test_the_pattern_finds_machine_paths_and_spares_placeholders():
    root, tmp, home = "/" + "root/", "/" + "tmp/", "/" + "home/"
    for bad in ("--cache " + "/wo" + "rk/runs/bench-cache", '"' + root + 'x.json"', "at " + tmp + "pytest-of-x/y",
                home + "ana/data/merl", "(" + "/wo" + "rk/px/merl)"):
        assert machine_paths(bad), bad
    for fine in ("/path/to/merl", "runs/bench-cache", "../shared/data/merl-test.txt", "~/.cache/brdfkit",
                 "/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1", "proxies/merl", "https://rgl.epfl.ch/materials",
                 "$TMPDIR/x", "a" + tmp + "b"):
        assert not machine_paths(fine), fine


def test_no_development_machine_path_in_tracked_files():
    found = {}
    for rel in tracked_files():
        if rel.endswith(BINARY_SUFFIXES):
            continue
        path = os.path.join(REPO, rel)
        if not os.path.isfile(path):  # deleted in the work tree, not yet committed
            continue
        with open(path, "rb") as f:
            data = f.read()
        if b"\0" in data[:8192]:
            continue
        hits = machine_paths(data.decode("utf-8", errors="replace"))
        if hits:
            found[rel] = hits[:3]
    assert not found, "absolute development-machine paths (write them relative to the repository or " \
                      f"to ../shared): {found}"
