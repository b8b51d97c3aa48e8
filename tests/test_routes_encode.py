"""The route matrix, compression: every shipped built-in x every kind it offers x every
size, through the CLI and real files: ``encode`` -> ``.emb`` -> ``decode`` -> ``.binary``
-> ``metrics`` against the material's own table, with a floor on the PSNR; and a batch of
two with ``--jobs 2``, byte for byte the encodes alone, each decoded.

The parameters come from the registries (``helpers_routes``): a new built-in, kind, size
or residual member is covered without an edit here. A size other than the kind's default
is encoded without refinement (the projection, or the encoder's pass: the refinement is
the same code at every size, and is taken at the default size and in the batch)."""

from __future__ import annotations

import pytest

from helpers_routes import MATERIALS, encode_routes, floor, kind_routes, materials, ok, psnr
from helpers_view import shipped_models  # noqa: F401  (a fixture)

# The matrix takes minutes in all: CI runs it (the suite), `-m "not slow"` leaves it out.
pytestmark = [pytest.mark.usefixtures("shipped_models"), pytest.mark.slow]


@pytest.fixture(scope="module")
def tables(tmp_path_factory):
    return materials(tmp_path_factory)


@pytest.mark.parametrize("model, kind, size, default", encode_routes())
def test_encode_decode_metrics(tables, tmp_path, capsys, model, kind, size, default):
    """encode -> decode -> metrics at one size, on a material that changes with the size."""
    from brdfkit.io.embedding import read_embedding

    name = MATERIALS[(size // 3) % len(MATERIALS)]
    refine = [] if size == default else ["--no-refine"]
    ok(capsys, ["encode", tables / f"{name}.binary", "-m", model, "--kind", kind, "--size", size, "-o", tmp_path,
                *refine])
    emb = read_embedding(tmp_path / f"{name}.emb")
    assert (emb.kind, emb.size) == (kind, size)
    ok(capsys, ["decode", tmp_path / f"{name}.emb", "-o", tmp_path / "decoded.binary"])
    score = psnr(capsys, tables / f"{name}.binary", tmp_path / "decoded.binary")
    assert score >= floor(size), f"{model} {kind} {size} on {name}: {score:.2f} dB"


@pytest.mark.parametrize("model, kind, default", kind_routes())
def test_a_batch_of_two_in_two_processes(tables, tmp_path, capsys, model, kind, default):
    """``encode --jobs 2`` of two tables gives the bytes of each encoded alone, and each
    decodes to its material (the refinement at a short budget: the bytes, not the score,
    are what a batch could change)."""
    pair = [tables / f"{m}.binary" for m in MATERIALS[:2]]
    for i, t in enumerate(pair):
        ok(capsys, ["encode", t, "-m", model, "--kind", kind, "--steps", "2", "-o", tmp_path / f"alone{i}"])
    ok(capsys, ["encode", *pair, "-m", model, "--kind", kind, "--steps", "2", "--jobs", "2", "-o", tmp_path / "batch"])
    for i, t in enumerate(pair):
        alone = (tmp_path / f"alone{i}" / f"{t.stem}.emb").read_bytes()
        assert (tmp_path / "batch" / f"{t.stem}.emb").read_bytes() == alone, f"{t.stem}: batch differs from alone"
        ok(capsys, ["decode", tmp_path / "batch" / f"{t.stem}.emb", "-o", tmp_path / f"{t.stem}.binary"])
        assert psnr(capsys, t, tmp_path / f"{t.stem}.binary") >= floor(default)
