"""The route matrix, what the other commands take: for every shipped built-in x every
kind it offers, two embeddings -> ``interpolate`` -> the blend decoded; ``view``,
``export --glsl`` (or its one-line refusal, for a kind no shader decodes), ``plot``,
``compare``, ``render`` and ``convert`` of an embedding; ``convert`` MERL -> RGL ``.bsdf``
-> MERL; and every file a ``brdfkit fit --method ...`` writes, taken by the commands that
take its part (``encode -m FILE``, ``sparse -m FILE``), through the CLI and real files.

The parameters come from the registries (``helpers_routes``; ``FITTERS``, ``KINDS`` and
``METHODS`` for the recipes' files)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import one_error_line, run_cli, run_cli_uncaptured, tiny_cli_options
from helpers_routes import FLOOR_DB, MATERIALS, kind_routes, materials, ok, psnr
from helpers_training import synthetic_library
from helpers_view import shipped_models  # noqa: F401  (a fixture)

# The matrix takes minutes in all: CI runs it (the suite), `-m "not slow"` leaves it out.
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def tables(tmp_path_factory):
    return materials(tmp_path_factory)


def _read(path):
    from brdfkit.io.merl import read_merl

    return read_merl(path)


@pytest.mark.usefixtures("shipped_models")
@pytest.mark.parametrize("model, kind, default", kind_routes())
def test_interpolate_and_the_blend_decoded(tables, tmp_path, capsys, model, kind, default):
    """Two embeddings of a kind blended (``interpolate --binary`` and ``decode`` of the
    written blend give the same table), and ``t = 0`` decodes to the first."""
    from brdfkit.io.embedding import read_embedding

    a, b = (tables / f"{m}.binary" for m in MATERIALS[:2])
    ok(capsys, ["encode", a, b, "-m", model, "--kind", kind, "--no-refine", "-o", tmp_path])
    ea, eb = tmp_path / f"{a.stem}.emb", tmp_path / f"{b.stem}.emb"
    ok(capsys, ["interpolate", ea, eb, "--t", "0.5", "-o", tmp_path / "mid.emb", "--binary", tmp_path / "mid.binary"])
    assert read_embedding(tmp_path / "mid.emb").kind == kind
    ok(capsys, ["decode", tmp_path / "mid.emb", "-o", tmp_path / "mid-decoded.binary"])
    np.testing.assert_array_equal(_read(tmp_path / "mid.binary"), _read(tmp_path / "mid-decoded.binary"))
    ok(capsys, ["interpolate", ea, eb, "--t", "0", "-o", tmp_path / "zero.emb"])
    ok(capsys, ["decode", tmp_path / "zero.emb", "-o", tmp_path / "zero.binary"])
    ok(capsys, ["decode", ea, "-o", tmp_path / "a.binary"])
    np.testing.assert_array_equal(_read(tmp_path / "zero.binary"), _read(tmp_path / "a.binary"))


@pytest.mark.usefixtures("shipped_models")
@pytest.mark.parametrize("model, kind, default", kind_routes())
def test_an_embedding_through_every_command_that_takes_one(tables, tmp_path, capsys, model, kind, default):
    """``view``, ``export --glsl``, ``plot``, ``compare``, ``render`` and ``convert`` of an
    embedding of each kind (the decoder found from the file: no ``-m``)."""
    from brdfkit.render.image import read_exr
    from brdfkit.view.live import LIVE_KINDS

    truth = tables / f"{MATERIALS[0]}.binary"
    ok(capsys, ["encode", truth, "-m", model, "--kind", kind, "--no-refine", "-o", tmp_path])
    emb = tmp_path / f"{MATERIALS[0]}.emb"
    ok(capsys, ["view", emb, "-o", tmp_path / "page.html"])
    assert (tmp_path / "page.html").stat().st_size > 1000
    code, _, err = run_cli(capsys, ["export", emb, "--glsl", tmp_path / "glsl"])
    if kind in LIVE_KINDS:
        assert code == 0, err
        doc = json.loads((tmp_path / "glsl" / "material.json").read_text())
        assert doc["kind"] == kind and doc["size"] == default
    else:
        assert code == 2 and "no GLSL decoder" in one_error_line(err) and not (tmp_path / "glsl").exists()
    ok(capsys, ["plot", truth, emb, "-o", tmp_path / "plot.png"])
    ok(capsys, ["compare", truth, emb, "-o", tmp_path / "sheet.png", "--resolution", "16", "--quiet"])
    ok(capsys, ["render", emb, "-o", tmp_path / "emb.exr", "--resolution", "16", "--quiet"])
    assert np.isfinite(read_exr(tmp_path / "emb.exr")).all()
    ok(capsys, ["convert", emb, "-o", tmp_path / "converted.binary"])
    assert psnr(capsys, truth, tmp_path / "converted.binary") >= FLOOR_DB
    for png in ("plot.png", "sheet.png"):
        assert (tmp_path / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


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

