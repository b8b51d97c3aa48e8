"""The route matrix, compression at the default size and what takes an embedding: every
shipped built-in x every kind it offers at its default size, through the CLI and real
files: ``encode`` (refined) -> ``.emb`` -> ``decode`` -> ``.binary`` -> ``metrics``
against the material's own table, with a floor on the PSNR; a batch of two with
``--jobs 2``, byte for byte the encodes alone, each decoded; two embeddings ->
``interpolate`` -> the blend decoded; ``view``, ``export --glsl`` (or its one-line
refusal, for a kind no shader decodes), ``render`` and ``convert`` of an embedding,
``plot`` and ``compare`` of each built-in's kinds against their truth.

The other sizes, unrefined: ``tests/test_routes_sizes.py``. The parameters come from the
registries (``helpers_routes``): a new built-in, kind or residual member is covered
without an edit here. The default size is refined at a short budget
(``helpers_routes.REFINED``: the route and the bytes, not the score, are what is
checked; the default budget is the same code with more iterations).

The files are made once per module and shared (``helpers_routes.Routes``): the default
size's encodes alone are the ones the batch is compared with and the ones interpolated,
viewed, exported, plotted, compared, rendered and converted; a table decoded once is
scored once. Each test asks for what it needs, so that any one of them runs alone."""

from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import one_error_line, run_cli
from helpers_routes import (MATERIALS, REFINED, encode_routes, floor, kind_routes, model_routes, module_routes,
                            ok, route_material, shipped)
from helpers_view import shipped_models  # noqa: F401  (a fixture)

# The matrix takes minutes in all: CI runs it (the suite), `-m "not slow"` leaves it out.
pytestmark = [pytest.mark.usefixtures("shipped_models"), pytest.mark.slow]


def pair(default: int) -> list[str]:
    """The two materials of a kind's batch and blend: the one before its default route's,
    and that one (teflon and chrome-steel at 39 and 40 numbers; refined 2 steps,
    merl80-l40's hypernet renders blue-metallic-paint at 28.6 dB, under the floor)."""
    i = MATERIALS.index(route_material(default))
    return [MATERIALS[i - 1], MATERIALS[i]]


routes = module_routes("routes")


@pytest.mark.parametrize("model, kind, size, default", encode_routes(at_default=True))
def test_encode_decode_metrics(routes, capsys, model, kind, size, default):
    """encode (refined) -> decode -> metrics at the kind's default size."""
    routes.route(capsys, model, kind, size, default)


@pytest.mark.parametrize("model, kind, default", kind_routes())
def test_a_batch_of_two_in_two_processes(routes, tmp_path, capsys, model, kind, default):
    """``encode --jobs 2`` of two tables gives the bytes of each encoded alone, and each
    decodes to its material (the refinement at a short budget: the bytes, not the score,
    are what a batch could change)."""
    names = pair(default)
    alone = [routes.encode(capsys, model, kind, default, default, m) for m in names]
    ok(capsys, ["encode", *(routes.tables / f"{m}.binary" for m in names), "-m", model, "--kind", kind, "--size",
                default, *REFINED, "--jobs", "2", "-o", tmp_path])
    for name, emb in zip(names, alone):
        assert (tmp_path / f"{name}.emb").read_bytes() == emb.read_bytes(), f"{name}: batch differs from alone"
        score = routes.score(capsys, name, routes.decode(capsys, emb))  # the same bytes: the same table
        assert score >= floor(default), f"{model} {kind} on {name}: {score:.2f} dB"


def _read(path):
    from brdfkit.io.merl import read_merl

    return read_merl(path)


@pytest.mark.parametrize("model, kind, default", kind_routes())
def test_interpolate_and_the_blend_decoded(routes, tmp_path, capsys, model, kind, default):
    """Two embeddings of a kind blended (``interpolate --binary`` and ``decode`` of the
    written blend give the same table), and ``t = 0`` decodes to the first."""
    from brdfkit.io.embedding import read_embedding

    ea, eb = (routes.encode(capsys, model, kind, default, default, m) for m in pair(default))
    ok(capsys, ["interpolate", ea, eb, "--t", "0.5", "-o", tmp_path / "mid.emb", "--binary", tmp_path / "mid.binary"])
    assert read_embedding(tmp_path / "mid.emb").kind == kind
    mid = _read(tmp_path / "mid.binary")
    assert not np.array_equal(mid, _read(routes.decode(capsys, ea)))
    np.testing.assert_array_equal(mid, _read(routes.decode(capsys, tmp_path / "mid.emb")))
    ok(capsys, ["interpolate", ea, eb, "--t", "0", "-o", tmp_path / "zero.emb"])
    np.testing.assert_array_equal(_read(routes.decode(capsys, tmp_path / "zero.emb")),
                                  _read(routes.decode(capsys, ea)))


@pytest.mark.parametrize("model, kind, default", kind_routes())
def test_an_embedding_through_every_command_that_takes_one(routes, tmp_path, capsys, model, kind, default):
    """``view``, ``export --glsl``, ``render`` and ``convert`` of an embedding of each kind
    (the decoder found from the file: no ``-m``); ``convert`` gives ``decode``'s table."""
    from brdfkit.render.image import read_exr
    from brdfkit.view.live import LIVE_KINDS

    emb = routes.encode(capsys, model, kind, default, default, route_material(default))
    ok(capsys, ["view", emb, "-o", tmp_path / "page.html"])
    assert (tmp_path / "page.html").stat().st_size > 1000
    code, _, err = run_cli(capsys, ["export", emb, "--glsl", tmp_path / "glsl"])
    if kind in LIVE_KINDS:
        assert code == 0, err
        doc = json.loads((tmp_path / "glsl" / "material.json").read_text())
        assert doc["kind"] == kind and doc["size"] == default
    else:
        assert code == 2 and "no GLSL decoder" in one_error_line(err) and not (tmp_path / "glsl").exists()
    ok(capsys, ["render", emb, "-o", tmp_path / "emb.exr", "--resolution", "16", "--quiet"])
    assert np.isfinite(read_exr(tmp_path / "emb.exr")).all()
    ok(capsys, ["convert", emb, "-o", tmp_path / "converted.binary"])
    assert (tmp_path / "converted.binary").read_bytes() == routes.decode(capsys, emb).read_bytes()


@pytest.mark.parametrize("model", model_routes())
def test_plot_and_compare_every_kind(routes, tmp_path, capsys, model):
    """``plot`` and ``compare`` of the truth and an embedding of each kind the built-in
    offers (one figure each for all of a material's kinds: the decoders found from the
    files)."""
    kinds = next(k for name, k, _ in shipped() if name == model)
    by_truth: dict = {}
    for kind, (_, default) in kinds.items():
        by_truth.setdefault(route_material(default), []).append(
            routes.encode(capsys, model, kind, default, default, route_material(default)))
    for name, embs in by_truth.items():
        truth = routes.tables / f"{name}.binary"
        ok(capsys, ["plot", truth, *embs, "-o", tmp_path / f"{name}-plot.png"])
        ok(capsys, ["compare", truth, *embs, "-o", tmp_path / f"{name}-sheet.png", "--resolution", "16", "--quiet"])
        for png in ("plot", "sheet"):
            assert (tmp_path / f"{name}-{png}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
