"""The route matrix, sparse reconstruction: every shipped built-in x every sparse method,
through the CLI and real files: ``sample`` -> ``.csv`` -> ``sparse`` -> ``.binary`` ->
``metrics`` against the material's own table where the built-in serves the method (and
``--emb`` -> ``decode`` where the method makes an embedding, ``Method.embedding_kind``,
and ``--emb`` refused in one line where it makes none), a one-line refusal with
exit code 2 and nothing written where it does not.

The parameters come from the registries (``helpers_routes``)."""

from __future__ import annotations

import pytest

from conftest import one_error_line, run_cli, tmp_leftovers
from helpers_routes import FLOOR_DB, floor, materials, method_routes, ok, psnr
from helpers_view import shipped_models  # noqa: F401  (a fixture)

# The matrix takes minutes in all: CI runs it (the suite), `-m "not slow"` leaves it out.
pytestmark = [pytest.mark.usefixtures("shipped_models"), pytest.mark.slow]

SAMPLES = 400
"""Samples of each reconstruction (``brdfkit sample -n``, uniform over the angles, seed 0)."""


QUICK = {"nbrdf": ["-O", "steps=300"]}
"""Options that keep a method's fit short in the matrix (the default NBRDF fit takes
minutes; 300 steps render blue-metallic-paint from 400 samples at 31.4 dB, IPCA at 44-46,
the learnt prior at 46-48); the route is the same."""


@pytest.fixture(scope="module")
def measured(tmp_path_factory):
    tables = materials(tmp_path_factory)
    out = tmp_path_factory.mktemp("sparse-samples") / "samples.csv"
    from conftest import run_cli_uncaptured

    code, err = run_cli_uncaptured(["sample", tables / "blue-metallic-paint.binary", "-n", SAMPLES, "-o", out])
    assert code == 0, err
    return tables / "blue-metallic-paint.binary", out


@pytest.mark.parametrize("model, method, served", method_routes())
def test_sparse_route(measured, tmp_path, capsys, model, method, served):
    from brdfkit.methods import METHODS

    truth, samples = measured
    out = tmp_path / "out.binary"
    kind = METHODS[method].embedding_kind
    emb = ["--emb", tmp_path / "out.emb"] if kind else []
    given = ["-m", model] if model else []
    args = ["sparse", samples, *given, "--method", method, "-o", out, *emb, *QUICK.get(method, [])]
    if not served:
        code, _, err = run_cli(capsys, args)
        line = one_error_line(err)
        assert code == 2 and model in line, line
        assert sorted(p.name for p in tmp_path.iterdir()) == [] and not tmp_leftovers(tmp_path)
        return
    if not kind:  # --emb refused in one line before any work, nothing written
        code, _, err = run_cli(capsys, [*args, "--emb", tmp_path / "out.emb"])
        assert code == 2 and "makes no embedding" in one_error_line(err)
        assert sorted(p.name for p in tmp_path.iterdir()) == [] and not tmp_leftovers(tmp_path)
    ok(capsys, args)
    score = psnr(capsys, truth, out)
    assert score >= FLOOR_DB, f"{model} {method}: {score:.2f} dB"
    if emb:
        from brdfkit.io.embedding import read_embedding

        assert read_embedding(tmp_path / "out.emb").kind == kind
        ok(capsys, ["decode", tmp_path / "out.emb", "-o", tmp_path / "emb.binary"])
        assert psnr(capsys, out, tmp_path / "emb.binary") >= floor(40)
