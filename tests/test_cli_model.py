"""The model commands as a user runs them: encode, decode, sparse, interpolate.

A few runs go through a real subprocess (the installed ``brdfkit`` script: exit codes,
one-line errors, no traceback); the rest call the same entry point in-process, which is
faster and exercises the same code.
"""

from __future__ import annotations

import os

import numpy as np
import pytest
import torch

from brdfkit import api
from brdfkit.io.embedding import read_embedding, write_embedding
from brdfkit.io.merl import MERL_FILE_SIZE, read_merl

from conftest import one_error_line, run_cli, run_here, tmp_leftovers
from helpers_model import make_model, material_table, write_inputs




@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("cli-model")
    make_model(d / "model.safetensors", seed=0)
    make_model(d / "other.safetensors", seed=1)
    write_inputs(d, "samples.csv", 300)
    return d


@pytest.fixture(autouse=True)
def _no_model_env(monkeypatch):
    monkeypatch.delenv("BRDFKIT_MODEL", raising=False)


def test_encode_continues_past_bad_files(files, tmp_path, capsys):
    junk = tmp_path / "junk.binary"
    junk.write_bytes(b"not a MERL table")
    out = tmp_path / "embs"
    r = run_here(capsys, ["encode", files / "mat.binary", junk, tmp_path / "missing.binary", files / "samples.csv",
              "-m", files / "model.safetensors", "-o", out, "--no-refine"])
    assert r.returncode == 2, r.stderr
    assert sorted(os.listdir(out)) == ["mat.emb", "samples.emb"]
    errors = [ln for ln in r.stderr.splitlines() if ln.startswith("brdfkit: error: ")]
    assert len(errors) == 2 and "Traceback" not in r.stderr
    assert str(junk) in errors[0] and "not a MERL table" in errors[0]
    assert "missing.binary" in errors[1] and "no such file" in errors[1]
    assert "encoded 2 of 4 files" in r.stderr
    m = api.load_model(files / "model.safetensors", "cpu")
    e = read_embedding(out / "mat.emb")
    np.testing.assert_allclose(e.values, api.encode(material_table(1), m, refine=False).values, atol=1e-6)
    assert e.source == "mat.binary" and e.decoder == m.digest


def test_encode_kind_hypernet_and_its_old_name_latent(files, tmp_path, capsys):
    """``--kind hypernet`` makes the hypernetwork's latent; ``--kind latent``, the kind's
    name before, still makes the same embedding, written with the new name."""
    outs = {}
    for kind in ("hypernet", "latent"):
        code, _, err = run_cli(capsys, ["encode", files / "mat.binary", files / "samples.csv", "-m",
                                        files / "model.safetensors", "--kind", kind, "--no-refine",
                                        "-o", tmp_path / kind])
        assert code == 0, err
        outs[kind] = [(tmp_path / kind / f).read_bytes() for f in ("mat.emb", "samples.emb")]
        e = read_embedding(tmp_path / kind / "mat.emb")
        assert e.kind == "hypernet" and e.decoder == api.load_model(files / "model.safetensors", "cpu").digest
    assert outs["latent"] == outs["hypernet"]
    code, _, err = run_cli(capsys, ["encode", files / "mat.binary", "-m", files / "model.safetensors",
                                    "--kind", "basis", "-o", tmp_path / "b"])
    assert code == 2 and "a network file, not the basis a basis embedding needs" in one_error_line(err)


@pytest.mark.slow
def test_encode_beside_input_and_env_model(files, tmp_path, capsys, monkeypatch):
    src = tmp_path / "copy.binary"
    src.write_bytes((files / "mat.binary").read_bytes())
    monkeypatch.setenv("BRDFKIT_MODEL", str(files / "model.safetensors"))
    code, _, err = run_cli(capsys, ["encode", src])
    assert code == 0, err
    assert read_embedding(tmp_path / "copy.emb").sample_count == int(np.isfinite(material_table(1)).all(-1).sum())


@pytest.mark.slow
def test_encode_same_stem_twice_is_refused(files, tmp_path, capsys):
    (tmp_path / "a").mkdir()
    (tmp_path / "a" / "mat.binary").write_bytes((files / "mat.binary").read_bytes())
    code, _, err = run_cli(capsys, ["encode", files / "mat.binary", tmp_path / "a" / "mat.binary",
                                    "-m", files / "model.safetensors", "-o", tmp_path / "out"])
    assert code == 2 and "already written for" in err
    assert os.listdir(tmp_path / "out") == ["mat.emb"]


def test_encode_without_model(files, capsys):
    code, _, err = run_cli(capsys, ["encode", files / "mat.binary"])
    assert code == 2 and "no model given" in one_error_line(err)


def test_decode_writes_a_merl_file(files, tmp_path, capsys):
    m = api.load_model(files / "model.safetensors", "cpu")
    emb = api.encode(files / "samples.csv", m)
    write_embedding(tmp_path / "x.emb", emb)
    out = tmp_path / "x.binary"
    r = run_here(capsys, ["decode", tmp_path / "x.emb", "-m", files / "model.safetensors", "-o", out])
    assert r.returncode == 0, r.stderr
    assert os.path.getsize(out) == MERL_FILE_SIZE == 34_992_012
    table = read_merl(out)
    unmeasured = ~np.isfinite(m.rho_ref).all(-1)
    np.testing.assert_array_equal(np.isnan(table).any(-1), unmeasured)
    raw = np.fromfile(out, "<f8", offset=12).reshape(3, -1)
    assert (raw[:, unmeasured.reshape(-1)] == -1).all()
    np.testing.assert_allclose(table, api.decode(emb, m), rtol=1e-12, equal_nan=True)
    # Default output: beside the embedding.
    code, _, err = run_cli(capsys, ["decode", tmp_path / "x.emb", "-m", files / "model.safetensors"])
    assert code == 0 and (tmp_path / "x.binary").exists()


def test_decode_other_models_embedding_refused(files, tmp_path, capsys):
    m = api.load_model(files / "model.safetensors", "cpu")
    write_embedding(tmp_path / "x.emb", api.encode(files / "samples.csv", m))
    r = run_here(capsys, ["decode", tmp_path / "x.emb", "-m", files / "other.safetensors", "-o", tmp_path / "y.binary"])
    assert r.returncode == 2
    line = one_error_line(r.stderr)
    assert "x.emb" in line and m.digest[:12] in line and "other.safetensors" in line
    assert not (tmp_path / "y.binary").exists()


@pytest.mark.parametrize("case", ["pickle model", "truncated model", "bad emb", "output is input"])
def test_decode_bad_inputs(files, tmp_path, capsys, case):
    import pickle

    m = api.load_model(files / "model.safetensors", "cpu")
    emb = tmp_path / "x.emb"
    write_embedding(emb, api.encode(files / "samples.csv", m))
    model = files / "model.safetensors"
    out = tmp_path / "y.binary"
    if case == "pickle model":
        model = tmp_path / "m.safetensors"
        model.write_bytes(pickle.dumps({"weights": [1, 2, 3]}))
    elif case == "truncated model":
        model = tmp_path / "m.safetensors"
        model.write_bytes((files / "model.safetensors").read_bytes()[:1000])
    elif case == "bad emb":
        emb.write_text("{not json")
    else:
        out = emb
    code, _, err = run_cli(capsys, ["decode", emb, "-m", model, "-o", out])
    assert code == 2
    line = one_error_line(err)
    assert {"pickle model": "pickle", "truncated model": "truncated", "bad emb": "not JSON",
            "output is input": "refusing to overwrite"}[case] in line
    assert not (tmp_path / "y.binary").exists()


@pytest.mark.slow
def test_sparse(files, tmp_path, capsys):
    out, emb = tmp_path / "s.binary", tmp_path / "s.emb"
    code, _, err = run_cli(capsys, ["sparse", files / "samples.csv", "-m", files / "model.safetensors",
                                    "-o", out, "--emb", emb])
    assert code == 0, err
    m = api.load_model(files / "model.safetensors", "cpu")
    # With --emb the refinement stops at the latent, so that the embedding decodes to the table.
    from brdfkit.methods import get_method
    from brdfkit.io.samples import read_samples

    table, e = get_method("hypernet").sparse(read_samples(files / "samples.csv"), m, refine_target="latent")
    np.testing.assert_allclose(read_merl(out), table, rtol=1e-12, equal_nan=True)
    np.testing.assert_array_equal(read_embedding(emb).values, e.values)
    np.testing.assert_allclose(api.decode(read_embedding(emb), m), table, rtol=1e-6, equal_nan=True)
    assert read_embedding(emb).sample_count == 300
    assert "refined on the samples (latent)" in err


def test_a_failed_emb_leaves_neither_output(files, tmp_path, capsys, monkeypatch):
    """``sparse -o T --emb E``: both outputs or neither (the table was written before an
    embedding its writer refused)."""
    import brdfkit.io.embedding
    from brdfkit.atomic import UnreadableOutput

    def refuse(path, emb):
        raise UnreadableOutput(f"{path}: not written: brdfkit could not read back what it made (a test)")

    monkeypatch.setattr(brdfkit.io.embedding, "write_embedding", refuse)
    code, _, err = run_cli(capsys, ["sparse", files / "samples.csv", "-m", files / "model.safetensors",
                                    "-o", tmp_path / "s.binary", "--emb", tmp_path / "s.emb", "--no-refine"])
    assert code == 2 and "not written" in one_error_line(err)
    assert sorted(p.name for p in tmp_path.iterdir()) == [] and not tmp_leftovers(tmp_path)


def test_sparse_bad_method_and_overwrite(files, tmp_path, capsys):
    code, _, err = run_cli(capsys, ["sparse", files / "samples.csv", "-m", files / "model.safetensors",
                                    "-o", tmp_path / "s.binary", "--method", "magic"])
    assert code == 2 and "magic" in err
    code, _, err = run_cli(capsys, ["sparse", files / "samples.csv", "-m", files / "model.safetensors",
                                    "-o", files / "samples.csv"])
    assert code == 2 and "refusing to overwrite" in one_error_line(err)


@pytest.fixture(scope="module")
def two_embs(files, tmp_path_factory):
    d = tmp_path_factory.mktemp("interp")
    m = api.load_model(files / "model.safetensors", "cpu")
    write_embedding(d / "a.emb", api.encode(files / "mat.binary", m))
    write_embedding(d / "b.emb", api.encode(material_table(0), m, source="white"))
    o = api.load_model(files / "other.safetensors", "cpu")
    write_embedding(d / "o.emb", api.encode(files / "samples.csv", o))
    return d


@pytest.mark.slow
def test_interpolate_t_not_a_number(two_embs, tmp_path, capsys):
    r = run_here(capsys, ["interpolate", two_embs / "a.emb", two_embs / "b.emb", "--t", "abc", "-o", tmp_path / "c.emb"])
    assert r.returncode == 2
    assert "--t: 'abc' is not a number" in one_error_line(r.stderr)
    assert not (tmp_path / "c.emb").exists()


def test_interpolate(files, two_embs, tmp_path, capsys):
    a, b = read_embedding(two_embs / "a.emb"), read_embedding(two_embs / "b.emb")
    for t, want in (("0", a.values), ("1", b.values)):
        code, _, err = run_cli(capsys, ["interpolate", two_embs / "a.emb", two_embs / "b.emb", "--t", t,
                                        "-o", tmp_path / "c.emb"])
        assert code == 0, err
        np.testing.assert_array_equal(read_embedding(tmp_path / "c.emb").values, want)
    code, _, err = run_cli(capsys, ["interpolate", two_embs / "a.emb", two_embs / "b.emb", "--t", "0.3",
                                    "-o", tmp_path / "m.emb", "--binary", tmp_path / "m.binary",
                                    "-m", files / "model.safetensors"])
    assert code == 0, err
    m = api.load_model(files / "model.safetensors", "cpu")
    mix = read_embedding(tmp_path / "m.emb")
    np.testing.assert_allclose(read_merl(tmp_path / "m.binary"), api.decode(mix, m), rtol=1e-12, equal_nan=True)


@pytest.mark.parametrize("args, message", [
    (["--t", "1.5"], "outside [0, 1]"),
    (["--t", "nan"], "not a finite number"),
    (["--t", "0.5", "--binary", "{tmp}/m.binary"], "is not among the installed built-in models; pass the file"),
    (["--t", "0.5", "-o", "{embs}/a.emb"], "refusing to overwrite"),
])
def test_interpolate_refusals(two_embs, tmp_path, capsys, args, message):
    args = [a.format(tmp=tmp_path, embs=two_embs) for a in args]
    if "-o" not in args:
        args += ["-o", str(tmp_path / "c.emb")]
    code, _, err = run_cli(capsys, ["interpolate", two_embs / "a.emb", two_embs / "b.emb", *args])
    assert code == 2 and message in one_error_line(err)
    assert not (tmp_path / "c.emb").exists() and not (tmp_path / "m.binary").exists()


def test_interpolate_extrapolation_and_mismatch(two_embs, tmp_path, capsys):
    code, _, err = run_cli(capsys, ["interpolate", two_embs / "a.emb", two_embs / "b.emb", "--t", "1.5",
                                    "--allow-extrapolation", "-o", tmp_path / "c.emb"])
    assert code == 0, err
    code, _, err = run_cli(capsys, ["interpolate", two_embs / "a.emb", two_embs / "o.emb", "--t", "0.5",
                                    "-o", tmp_path / "d.emb"])
    assert code == 2 and "different decoders" in one_error_line(err)
    assert not (tmp_path / "d.emb").exists()


@pytest.mark.slow
def test_encode_folder_among_inputs_is_one_failure(files, tmp_path, capsys):
    code, _, err = run_cli(capsys, ["encode", tmp_path, files / "mat.binary", "-m", files / "model.safetensors",
                                    "-o", tmp_path / "out"])
    assert code == 2 and "is a directory" in err
    assert os.listdir(tmp_path / "out") == ["mat.emb"]


# --- interpolate --sheet: the strip of blends from A to B ----------------------------------

def _tile_at(png, want) -> bool:
    """Whether the uint8 image ``want`` appears, unresampled, somewhere in ``png``."""
    h, w = want.shape[:2]
    for y in range(png.shape[0] - h + 1):
        for x in range(png.shape[1] - w + 1):
            if np.array_equal(png[y:y + h, x:x + w], want):
                return True
    return False


@pytest.mark.slow
def test_interpolate_strip(files, two_embs, tmp_path, capsys):
    from PIL import Image

    from brdfkit.errors import InputError
    from brdfkit.render.display import display_encode
    from brdfkit.hypernet.neural_brdf import NeuralBRDF
    from brdfkit.render.scene import reference_scene
    from brdfkit.render.quadrature import render
    from brdfkit.figures.interpolation_strip import interpolation_strip

    sheet = tmp_path / "strip.png"
    code, _, err = run_cli(capsys, ["interpolate", two_embs / "a.emb", two_embs / "b.emb", "--steps", "3",
                                    "--sheet", sheet, "--tile", "16", "-m", files / "model.safetensors"])
    assert code == 0, err
    assert "3 materials, t = 0, 0.5, 1" in err
    png = np.asarray(Image.open(sheet).convert("RGB"))
    assert png.shape[0] > 16 and png.shape[1] > 3 * 16

    from brdfkit.embeddings import decoder_for

    a, b = read_embedding(two_embs / "a.emb"), read_embedding(two_embs / "b.emb")
    dec = decoder_for(a, files / "model.safetensors", "cpu")
    m = dec.obj
    tiles = interpolation_strip(dec, a, b, tmp_path / "lib.png", steps=3, size=16, progress=False)
    assert [t for t, _ in tiles] == [0.0, 0.5, 1.0]
    with pytest.raises(InputError, match="steps = 1"):  # the library checks what the CLI checks
        interpolation_strip(dec, a, b, tmp_path / "one.png", steps=1, size=16)
    for (_, img), emb in zip(tiles[::2], (a, b)):  # the ends are A and B themselves
        alone, _ = render(NeuralBRDF.from_embedding(m, emb), reference_scene(16))
        np.testing.assert_array_equal(img, alone)
    assert not np.array_equal(tiles[1][1], tiles[0][1]) and not np.array_equal(tiles[1][1], tiles[2][1])
    from brdfkit.figures.canvas import antialias_silhouette

    blends = [NeuralBRDF.from_embedding(m, emb) for emb in (a, b)]
    for (_, img), drawn in zip(tiles[::2], antialias_silhouette(blends, [t[1] for t in tiles[::2]])):
        # each end drawn pixel for pixel, its silhouette antialiased and its inside as
        # rendered (matplotlib truncates to 8 bits)
        assert np.any(drawn != img, axis=-1).mean() < 0.5  # the rim alone changed
        assert _tile_at(png, np.floor(display_encode(drawn) * 255).astype(np.uint8))


@pytest.mark.parametrize("args, message", [
    (["--steps", "3"], "--steps: options of the strip; add --sheet"),
    (["--steps", "3", "--t", "0.5", "-o", "{tmp}/c.emb"], "--steps: options of the strip"),
    (["--sheet", "{tmp}/s.png", "--t", "0.5"], "--t: --sheet draws the strip from t = 0 to 1"),
    (["--sheet", "{tmp}/s.png", "-o", "{tmp}/c.emb"], "-o: --sheet draws the strip"),
    (["--sheet", "{tmp}/s.png", "--steps", "1"], "'--steps': 1 is not in the range 2<=x<=100"),
    (["--sheet", "{tmp}/s.png", "--tile", "4"], "'--tile': 4 is not in the range 8<=x<=1024"),
    (["--sheet", "{tmp}/s.png", "--tile", "1024", "--steps", "17"], "17,408 px wide, more than 16,384"),
    (["--tile", "16"], "--tile: options of the strip; add --sheet"),
    (["--sheet", "{embs}/a.emb"], "refusing to overwrite"),
    (["--sheet", "{tmp}/s.jpg"], "written as PNG; name it .png"),
    (["--sheet", "/nonexistent/s.png"], "does not exist"),
    ([], "missing --t T -o OUT.emb"),
    (["--t", "0.5"], "missing -o OUT.emb"),
])
def test_interpolate_strip_refusals(two_embs, tmp_path, capsys, args, message):
    args = [a.format(tmp=tmp_path, embs=two_embs) for a in args]
    code, _, err = run_cli(capsys, ["interpolate", two_embs / "a.emb", two_embs / "b.emb", *args])
    assert code == 2 and message in one_error_line(err)
    assert os.listdir(tmp_path) == []


def test_interpolate_strip_of_two_models_refused(files, two_embs, tmp_path, capsys):
    code, _, err = run_cli(capsys, ["interpolate", two_embs / "a.emb", two_embs / "o.emb", "--sheet",
                                    tmp_path / "s.png", "-m", files / "model.safetensors", "--tile", "16"])
    assert code == 2 and "different decoders" in one_error_line(err)
    assert not (tmp_path / "s.png").exists()


def test_interpolate_size_is_the_old_spelling_of_tile(two_embs, tmp_path, capsys, monkeypatch):
    """``--size`` is the numbers per material in ``encode``; the strip's pixels per tile are
    ``--tile``. The old ``interpolate --size`` still works, with one note on stderr."""
    import brdfkit.cli.interpolate as cli_interpolate

    drawn = []
    monkeypatch.setattr(cli_interpolate, "_strip", lambda a, b, sheet, steps, tile, model: drawn.append(tile))
    a, b, sheet = two_embs / "a.emb", two_embs / "b.emb", tmp_path / "s.png"
    for args in (["--size", "16"], ["--tile", "16"], ["--tile", "16", "--size", "16"]):
        code, _, err = run_cli(capsys, ["interpolate", a, b, "--sheet", sheet, *args])
        assert code == 0, err
        assert err.splitlines() == (["note: interpolate --size is now --tile"] if "--size" in args else [])
    assert drawn == [16, 16, 16]
    code, _, err = run_cli(capsys, ["interpolate", a, b, "--sheet", sheet, "--tile", "16", "--size", "32"])
    lines = err.splitlines()
    assert code == 2 and lines[0] == "note: interpolate --size is now --tile" and len(lines) == 2
    assert "--size is the old spelling of --tile; give --tile only" in lines[1]
    code, _, err = run_cli(capsys, ["interpolate", a, b, "--size", "16"])  # a strip option without --sheet
    assert code == 2 and "--tile: options of the strip; add --sheet" in err.splitlines()[-1]
    from brdfkit.cli.interpolate import command

    assert next(p for p in command.params if p.name == "old_tile").hidden
