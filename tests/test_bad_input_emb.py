"""Bad embedding files (.emb) through every command that reads them: decode, interpolate,
render (issue 6, docs/errors.md).

Each case: exit code 2, exactly one line on stderr that names the file and the problem,
no traceback, no output file and no temporary file left behind (the library-level checks
live in ``test_embedding.py``). The bad embeddings: the ``bad_embs`` fixture of
``conftest.py`` (``helpers_bad_input.bad_embedding_files``).
"""

from __future__ import annotations

import os

import pytest

from conftest import one_error_line, run_cli
from helpers_bad_input import check_emb_line


@pytest.mark.parametrize("name", ["missing", "directory", "empty", "not_json", "wrong_version",
                                  "latent_length", "latent_dim", "other_model"])
def test_bad_embedding_through_decode(good, bad_embs, tmp_path, capsys, name):
    path, message = bad_embs[name]
    out = tmp_path / "x.binary"
    code, _, err = run_cli(capsys, ["decode", path, "-m", good / "model.safetensors", "-o", out])
    assert code == 2
    check_emb_line(one_error_line(err), path, message)
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize("position", ["a", "b"])
@pytest.mark.parametrize("name", ["missing", "directory", "empty", "not_json", "wrong_version",
                                  "latent_length", "other_model"])
def test_bad_embedding_through_interpolate(good, bad_embs, tmp_path, capsys, name, position):
    path, message = bad_embs[name]
    a, b = (path, good / "a.emb") if position == "a" else (good / "a.emb", path)
    code, _, err = run_cli(capsys, ["interpolate", a, b, "--t", "0.5", "-o", tmp_path / "x.emb"])
    assert code == 2
    line = one_error_line(err)
    if name == "other_model":  # without a model: the two embeddings disagree
        assert "cannot interpolate embeddings of different decoders" in line and str(path) in line
    else:
        check_emb_line(line, path, message)
    assert os.listdir(tmp_path) == []


def test_embedding_of_another_latent_size_through_interpolate_binary(good, bad_embs, tmp_path, capsys):
    # two embeddings of the same (wrong) size: interpolated, then refused by the model
    path, _ = bad_embs["latent_dim"]
    code, _, err = run_cli(capsys, ["interpolate", path, path, "--t", "0.5", "-o", tmp_path / "x.emb",
                              "--binary", tmp_path / "x.binary", "-m", good / "model.safetensors"])
    assert code == 2
    assert "(hypernet, 5 numbers, decoder" in one_error_line(err)
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize("name", ["missing", "directory", "empty", "not_json", "wrong_version",
                                  "latent_length", "latent_dim", "other_model"])
def test_bad_embedding_through_render(good, bad_embs, tmp_path, capsys, name):
    path, message = bad_embs[name]
    code, _, err = run_cli(capsys, ["render", path, "-m", good / "model.safetensors", "-o", tmp_path / "x.exr",
                              "--resolution", "8", "--quiet"])
    assert code == 2
    check_emb_line(one_error_line(err), path, message)
    assert os.listdir(tmp_path) == []
