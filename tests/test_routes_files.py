"""The route matrix, the files that are not a built-in's embeddings: ``convert`` MERL ->
RGL ``.bsdf`` -> MERL; and every file a ``brdfkit fit --method ...`` writes, taken by the
commands that take its part (``encode -m FILE``, ``sparse -m FILE``), through the CLI and
real files. (What the commands do with a built-in's embedding of each kind, interpolate,
view, export, plot, compare, render and convert, is in ``tests/test_routes_encode.py``,
which makes those embeddings.)

The parameters come from the registries (``FITTERS``, ``KINDS`` and ``METHODS`` for the
recipes' files)."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import run_cli_uncaptured, tiny_cli_options
from helpers_routes import FLOOR_DB, MATERIALS, materials, ok, psnr
from helpers_training import synthetic_library

# The matrix takes minutes in all: CI runs it (the suite), `-m "not slow"` leaves it out.
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def tables(tmp_path_factory):
    return materials(tmp_path_factory)


def _read(path):
    from brdfkit.io.merl import read_merl

    return read_merl(path)


def test_convert_merl_to_rgl_and_back(tables, tmp_path, capsys):
    """MERL -> RGL ``.bsdf`` -> MERL: each file read back by the next command, and the
    table back renders as the first."""
    truth = tables / f"{MATERIALS[2]}.binary"
    ok(capsys, ["convert", truth, "-o", tmp_path / "m.bsdf"])
    ok(capsys, ["convert", tmp_path / "m.bsdf", "-o", tmp_path / "back.binary"])
    assert psnr(capsys, truth, tmp_path / "back.binary") >= FLOOR_DB


# --- every file a recipe of `brdfkit fit` writes, taken by the commands that take it ---------

TINY_RECIPES = {
    "hypernet": lambda lib, files: [*tiny_cli_options(), "--steps", "2"],
    "basis": lambda lib, files: ["--components", "3"],
    "prior": lambda lib, files: ["-O", f"basis={files['basis']}", "--steps", "3", "--latent-dim", "4",
                                 "--batch-materials", "2", "-O", "folds=2", "-O", "width=8", "-O", "query_size=64"],
    "residual": lambda lib, files: ["-O", f"basis={files['basis']}", "--steps", "3", "-O", "sizes=3,6",
                                    "-O", "width=8", "-O", "hidden=16", "-O", "batch=2", "-O", "cells=256"],
}
"""A recipe's options that make it tiny (seconds), given the library and the files of the
recipes fitted before it (a prior and a residual name their basis)."""


def _recipes():
    from brdfkit.training import FITTERS

    seen, out = set(), []
    for f in FITTERS.values():
        if f.part not in seen:  # an old name of a recipe makes the same part
            seen.add(f.part)
            out.append(f.name)
    return sorted(out, key=lambda n: n != "basis")  # the basis first: others name it


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    """``{recipe: file}``: each recipe of ``brdfkit fit`` run tiny on a synthetic library."""
    lib = synthetic_library(tmp_path_factory, 4, seed=5)  # the prior's two folds take two tables each
    out = tmp_path_factory.mktemp("recipes")
    files = {}
    for name in _recipes():
        assert name in TINY_RECIPES, f"brdfkit fit --method {name}: give it a tiny recipe in TINY_RECIPES"
        files[name] = out / f"{name}.safetensors"
        code, err = run_cli_uncaptured(["fit", "--method", name, lib, "-o", files[name], "-q",
                                        *TINY_RECIPES[name](lib, files)])
        assert code == 0, f"fit --method {name}: {err}"
    return lib, files


@pytest.mark.parametrize("recipe", _recipes())
def test_every_file_a_recipe_writes_is_taken(fitted, tmp_path, capsys, recipe):
    """The file of ``fit --method RECIPE``: ``encode -m FILE`` -> ``decode`` when its part
    decodes a kind, ``sample`` -> ``sparse -m FILE`` when a method takes its part; each
    written table finite, and at least one command takes it."""
    from brdfkit.embeddings.registry import KINDS
    from brdfkit.methods import METHODS
    from brdfkit.models.parts import file_part

    lib, files = fitted
    path = files[recipe]
    part = file_part(path).name
    table = sorted(lib.glob("*.binary"))[0]
    kinds = [k for k in KINDS if KINDS[k].part == part]
    methods = [m for m in METHODS if METHODS[m].part == part]
    assert kinds or methods, f"nothing takes the {part} that fit --method {recipe} writes"
    for kind in kinds:
        ok(capsys, ["encode", table, "-m", path, "--kind", kind, "--steps", "1", "-o", tmp_path / kind])
        ok(capsys, ["decode", tmp_path / kind / f"{table.stem}.emb", "-m", path, "-o", tmp_path / f"{kind}.binary"])
        assert np.isfinite(_read(tmp_path / f"{kind}.binary")[np.isfinite(_read(table))]).all()
    if methods:
        ok(capsys, ["sample", table, "-n", "200", "-o", tmp_path / "s.csv"])
    for method in methods:
        ok(capsys, ["sparse", tmp_path / "s.csv", "-m", path, "--method", method, "-o", tmp_path / f"{method}.binary"])
        assert np.isfinite(_read(tmp_path / f"{method}.binary")[np.isfinite(_read(table))]).all()

