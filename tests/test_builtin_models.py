"""Built-in models (``brdfkit.models.builtin``, ``brdfkit models``, ``-m NAME``) and the
compact model files they ship as (``save_network(compact=True, half=True,
reference_file=...)``).

The built-in folder of every test is a temporary one named by ``$BRDFKIT_BUILTIN_MODELS``
(conftest points it at an empty folder by default), holding tiny untrained models packed
with the real :func:`brdfkit.hypernet.packing.pack_network` and a manifest written with the
real :func:`~brdfkit.models.builtin.write_manifest`.
"""

from __future__ import annotations

import json
import os
import re
import shutil

import numpy as np
import pytest
import torch

from brdfkit import api
from brdfkit.io.embedding import read_embedding, write_embedding
from brdfkit.errors import FormatError, InputError
from brdfkit.io.merl import read_merl, write_merl
from brdfkit.models import builtin
from brdfkit.hypernet import packing
from brdfkit.hypernet.network_file import load_network, save_network, state_digest
from brdfkit.hypernet.network import HyperBRDF, HyperConfig

from conftest import TINY_CONFIG, one_error_line, quiet_env, run_brdfkit, run_cli
from helpers_model import make_model, material_table, pack_tiny_builtins, write_inputs

F16_EPS = 2.0 ** -11  # float16's relative rounding error


def _tiny_net(seed: int) -> HyperBRDF:
    torch.manual_seed(seed)
    return HyperBRDF(HyperConfig(**TINY_CONFIG))


@pytest.fixture(scope="module")
def shelf(tmp_path_factory):
    """A built-in folder: ``tiny-a`` (the default) and ``tiny-b``, sharing one reference
    file, and a folder of inputs (a table, a sample set)."""
    src = tmp_path_factory.mktemp("trained")
    folder = tmp_path_factory.mktemp("builtin")
    entries = pack_tiny_builtins(src, folder, (("tiny-a", 0), ("tiny-b", 1)), validation={40: 0.3, 400: 0.2},
                                 materials_list="stiff")
    builtin.write_manifest(folder, entries, default="tiny-a")
    return folder, write_inputs(tmp_path_factory.mktemp("inputs"))


# --- compact model files ---------------------------------------------------------------------

@pytest.mark.slow
def test_compact_and_half_round_trip(tmp_path):
    net, ref = _tiny_net(0), material_table(0).astype(np.float32)
    fp_dense = save_network(tmp_path / "dense.safetensors", net, ref)
    fp_cells = save_network(tmp_path / "cells.safetensors", net, ref, compact=True)
    fp_half = save_network(tmp_path / "half.safetensors", net, ref, half=True)
    assert fp_cells == fp_dense  # float32 weights: the same network, the same digest
    half_weights = {k: v.half() for k, v in net.state_dict().items()}
    assert fp_half == state_digest(half_weights) != fp_dense
    sizes = {n: os.path.getsize(tmp_path / f"{n}.safetensors") for n in ("dense", "cells", "half")}
    assert sizes["half"] < sizes["cells"] < sizes["dense"]

    dense = load_network(tmp_path / "dense.safetensors", "cpu")
    cells = load_network(tmp_path / "cells.safetensors", "cpu")
    half = load_network(tmp_path / "half.safetensors", "cpu")
    np.testing.assert_array_equal(cells.rho_ref, dense.rho_ref)  # NaN where NaN, bit for bit
    assert half.rho_ref.dtype == np.float32 and half.digest == fp_half
    np.testing.assert_array_equal(np.isnan(half.rho_ref), np.isnan(ref))
    np.testing.assert_allclose(half.rho_ref, ref, rtol=F16_EPS, atol=6e-8, equal_nan=True)
    for name, t in net.state_dict().items():
        loaded = half.net.state_dict()[name]
        assert loaded.dtype == torch.float32
        torch.testing.assert_close(loaded, t, rtol=F16_EPS, atol=6e-8)

    # Saved again, half or not, the loaded half model keeps its digest.
    assert save_network(tmp_path / "again.safetensors", half.net, half.rho_ref, half=True) == fp_half
    assert save_network(tmp_path / "again32.safetensors", half.net, half.rho_ref) == fp_half
    assert load_network(tmp_path / "again.safetensors", "cpu").digest == fp_half


def test_half_refuses_values_beyond_float16(tmp_path):
    ref = material_table(0).astype(np.float32).copy()
    ref[0, 0, 0, 0] = 1e5
    with pytest.raises(ValueError, match="float16"):
        save_network(tmp_path / "m.safetensors", _tiny_net(0), ref, half=True)
    net = _tiny_net(0)
    with torch.no_grad():
        next(net.parameters()).view(-1)[0] = 7e4
    with pytest.raises(ValueError, match="float16"):
        save_network(tmp_path / "m.safetensors", net, material_table(0), half=True)
    assert not (tmp_path / "m.safetensors").exists()


def test_shared_reference(tmp_path):
    ref = material_table(0)
    fa = save_network(tmp_path / "a.safetensors", _tiny_net(0), ref, half=True, reference_file="r.safetensors")
    fb = save_network(tmp_path / "b.safetensors", _tiny_net(1), ref, half=True, reference_file="r.safetensors")
    a, b = load_network(tmp_path / "a.safetensors", "cpu"), load_network(tmp_path / "b.safetensors", "cpu")
    assert (a.digest, b.digest) == (fa, fb)
    np.testing.assert_array_equal(a.rho_ref, b.rho_ref)
    assert os.path.getsize(tmp_path / "a.safetensors") < os.path.getsize(tmp_path / "r.safetensors")

    with pytest.raises(ValueError, match="another reference table"):
        save_network(tmp_path / "c.safetensors", _tiny_net(2), ref * 2, half=True,
                   reference_file="r.safetensors")
    with pytest.raises(ValueError, match="bare file name"):
        save_network(tmp_path / "c.safetensors", _tiny_net(2), ref, reference_file="../r.safetensors")

    # The model file alone, away from its reference, and a damaged reference, are refused.
    (tmp_path / "alone").mkdir()
    shutil.copy(tmp_path / "a.safetensors", tmp_path / "alone" / "a.safetensors")
    with pytest.raises(FormatError, match="shared reference table r.safetensors is missing"):
        load_network(tmp_path / "alone" / "a.safetensors", "cpu")
    data = bytearray((tmp_path / "r.safetensors").read_bytes())
    data[-10] ^= 0xFF
    (tmp_path / "r.safetensors").write_bytes(bytes(data))
    with pytest.raises(FormatError, match="damaged"):
        load_network(tmp_path / "a.safetensors", "cpu")


def test_damaged_compact_reference_refused(tmp_path):
    from safetensors import safe_open
    from safetensors.torch import load_file, save_file

    save_network(tmp_path / "m.safetensors", _tiny_net(0), material_table(0), half=True)
    with safe_open(str(tmp_path / "m.safetensors"), framework="pt") as f:
        meta = f.metadata()
    tensors = load_file(str(tmp_path / "m.safetensors"))
    tensors["rho_ref_values"] = tensors["rho_ref_values"].clone()
    tensors["rho_ref_values"][5, 0] *= 2
    save_file(tensors, str(tmp_path / "bad.safetensors"), metadata=meta)
    with pytest.raises(FormatError, match="does not match the digest"):
        load_network(tmp_path / "bad.safetensors", "cpu")
    tensors.pop("rho_ref_mask")
    save_file(tensors, str(tmp_path / "nomask.safetensors"), metadata=meta)
    with pytest.raises(FormatError, match="missing tensor 'rho_ref_mask'"):
        load_network(tmp_path / "nomask.safetensors", "cpu")
    for record, message in ((None, "bad or missing 'reference'"), ("[1]", "bad or missing 'reference'"),
                            (json.dumps({"storage": "file", "file": "../r.safetensors", "digest": "0"}),
                             "bad shared reference file name")):
        md = {k: v for k, v in meta.items() if k != "reference"}
        if record is not None:
            md["reference"] = record
        save_file(tensors, str(tmp_path / "rec.safetensors"), metadata=md)
        with pytest.raises(FormatError, match=re.escape(message)):
            load_network(tmp_path / "rec.safetensors", "cpu")


# --- the built-in folder ---------------------------------------------------------------------

def test_package_manifest_reads(monkeypatch):
    monkeypatch.delenv(builtin.BUILTIN_ENV)
    import brdfkit

    man = builtin.read_manifest()
    assert os.path.samefile(man.folder, os.path.join(os.path.dirname(brdfkit.__file__), "models"))
    assert man.default == "merl-rgl-l40"
    assert man.installed()
    for m in man.installed():
        assert m.part("network") is not None
        for part in m.parts.values():
            assert os.path.isfile(part.path)


def test_listing_and_resolution(installed):
    folder, _ = installed
    models = builtin.installed_bundles()
    assert [m.name for m in models] == ["tiny-a", "tiny-b"]
    assert [m.default for m in models] == [True, False]
    a = models[0]
    assert a.latent_dim == TINY_CONFIG["latent_dim"] and a.materials == 1 and a.steps == 0
    assert a.validation == {40: 0.3, 400: 0.2} and a.command == "brdfkit fit (tiny-a)"
    assert list(a.parts) == ["network"] and a.part("basis") is None and a.part("prior") is None
    assert a.part("network") == builtin.PartEntry("tiny-a.safetensors", str(folder / "tiny-a.safetensors"),
                                                  a.part("network").digest)
    assert builtin.resolve_network("tiny-b") == str(folder / "tiny-b.safetensors")
    assert builtin.resolve_part("tiny-b", "network") == str(folder / "tiny-b.safetensors")
    assert builtin.default_bundle() == a
    assert packing.load_builtin("tiny-a", device="cpu").digest == a.part("network").digest
    assert builtin.find_by_digest(a.part("network").digest) == str(folder / "tiny-a.safetensors")
    assert builtin.is_builtin_part(folder / "tiny-a.safetensors", "network")
    assert not builtin.is_builtin_part(folder / "tiny-a.safetensors", "basis")
    # Paths stay paths, even missing ones, when they look like paths.
    for spec in ("x.safetensors", "dir/x", str(folder / "tiny-a.safetensors")):
        assert builtin.resolve_network(spec) == spec
    with pytest.raises(InputError, match=r"unknown model 'tiny-c'.*built-in: tiny-a, tiny-b"):
        builtin.resolve_network("tiny-c")
    with pytest.raises(InputError, match=r"built-in model 'tiny-a' ships no PCA basis"):
        builtin.resolve_basis("tiny-a")


def test_unknown_name_is_one_line_exit_2(installed, capsys):
    _, inputs = installed
    code, _, err = run_cli(capsys, ["encode", inputs / "mat.binary", "-m", "nope", "-o", inputs / "out"])
    line = one_error_line(err)
    assert code == 2 and "unknown model 'nope'" in line and "tiny-a, tiny-b" in line


def test_no_builtin_no_model_error(capsys, tmp_path):
    write_merl(tmp_path / "mat.binary", material_table(1))
    code, _, err = run_cli(capsys, ["encode", tmp_path / "mat.binary"])
    line = one_error_line(err)
    assert code == 2 and "no model given" in line and "brdfkit models" in line
    code, _, err = run_cli(capsys, ["encode", tmp_path / "mat.binary", "-m", "merl-rgl-l40"])
    assert code == 2 and "no built-in models are installed" in one_error_line(err)


@pytest.mark.slow
def test_default_and_env_resolution(installed, capsys, monkeypatch, tmp_path):
    folder, inputs = installed
    fps = {m.name: m.part("network").digest for m in builtin.installed_bundles()}
    # which model encodes is the question, not the refinement (--no-refine: the encoder's pass)
    code, _, err = run_cli(capsys, ["encode", inputs / "mat.binary", "-o", tmp_path / "d", "--no-refine"])
    assert code == 0, err
    assert read_embedding(tmp_path / "d" / "mat.emb").decoder == fps["tiny-a"]
    monkeypatch.setenv("BRDFKIT_MODEL", "tiny-b")
    code, _, err = run_cli(capsys, ["encode", inputs / "mat.binary", "-o", tmp_path / "e", "--no-refine"])
    assert code == 0, err
    assert read_embedding(tmp_path / "e" / "mat.emb").decoder == fps["tiny-b"]
    monkeypatch.delenv("BRDFKIT_MODEL")
    code, _, err = run_cli(capsys, ["sparse", inputs / "s.csv", "-o", tmp_path / "s.binary",
                                    "--emb", tmp_path / "s.emb"])
    assert code == 0, err
    assert read_embedding(tmp_path / "s.emb").decoder == fps["tiny-a"]


def test_other_methods_get_no_builtin(installed, capsys, tmp_path):
    _, inputs = installed
    code, _, err = run_cli(capsys, ["sparse", inputs / "s.csv", "--method", "ipca", "-o", tmp_path / "x.binary"])
    line = one_error_line(err)  # ipca takes the default built-in's basis, and tiny-a ships none
    assert code == 2 and "built-in model 'tiny-a' ships no PCA basis" in line
    assert not (tmp_path / "x.binary").exists()


@pytest.mark.slow
def test_embedding_picks_its_builtin(installed, capsys, tmp_path):
    folder, inputs = installed
    b = api.load_model(folder / "tiny-b.safetensors", "cpu")
    write_embedding(tmp_path / "x.emb", api.encode(inputs / "mat.binary", b))
    write_embedding(tmp_path / "y.emb", api.encode(inputs / "s.csv", b))
    assert builtin.find_by_digest(read_embedding(tmp_path / "x.emb").decoder) == str(folder / "tiny-b.safetensors")
    code, _, err = run_cli(capsys, ["decode", tmp_path / "x.emb", "-o", tmp_path / "x.binary"])  # not the default
    assert code == 0, err
    np.testing.assert_allclose(read_merl(tmp_path / "x.binary"), api.decode(tmp_path / "x.emb", b), rtol=1e-12,
                               equal_nan=True)  # through the MERL scales and back
    code, _, err = run_cli(capsys, ["interpolate", tmp_path / "x.emb", tmp_path / "y.emb", "--t", "0.5",
                                    "-o", tmp_path / "m.emb", "--binary", tmp_path / "m.binary"])
    assert code == 0, err
    assert (tmp_path / "m.binary").exists()
    # An embedding of a model that is not built in: refused, naming its decoder's digest.
    make_model(tmp_path / "own.safetensors", seed=5)
    own = api.load_model(tmp_path / "own.safetensors", "cpu")
    write_embedding(tmp_path / "own.emb", api.encode(inputs / "s.csv", own))
    code, _, err = run_cli(capsys, ["decode", tmp_path / "own.emb", "-o", tmp_path / "own.binary"])
    assert code == 2 and own.digest[:12] in one_error_line(err)


def test_damaged_builtin_refused(shelf, monkeypatch, capsys, tmp_path):
    folder = tmp_path / "builtin"
    shutil.copytree(shelf[0], folder)
    monkeypatch.setenv(builtin.BUILTIN_ENV, str(folder))
    # One weight flipped: the file no longer matches the digest it (and the manifest) records.
    path = folder / "tiny-a.safetensors"
    data = bytearray(path.read_bytes())
    data[-3] ^= 0x40
    path.write_bytes(bytes(data))
    code, _, err = run_cli(capsys, ["encode", shelf[1] / "mat.binary", "-m", "tiny-a", "-o", tmp_path / "o"])
    assert code == 2 and "damaged" in one_error_line(err)
    # Another valid model under a built-in's name: its recorded digest is not the manifest's.
    shutil.copy(folder / "tiny-b.safetensors", path)
    code, _, err = run_cli(capsys, ["encode", shelf[1] / "mat.binary", "-o", tmp_path / "o"])
    line = one_error_line(err)
    assert code == 2 and "built-in model 'tiny-a'" in line and "the manifest" in line


def test_bad_manifest_refused(monkeypatch, capsys, tmp_path):
    monkeypatch.setenv(builtin.BUILTIN_ENV, str(tmp_path))
    (tmp_path / "manifest.json").write_text('{"format": "brdfkit-builtin-models", "version": 1, '
                                            '"models": [{"name": "a b", "file": "x.safetensors"}]}')
    code, _, err = run_cli(capsys, ["models"])
    assert code == 2 and "manifest.json: model 'a b'" in one_error_line(err)
    # The same in a version 2 manifest, and a part of a name no bundle has.
    (tmp_path / "manifest.json").write_text('{"format": "brdfkit-builtin-models", "version": 2, '
                                            '"bundles": [{"name": "a b", "parts": {}}]}')
    code, _, err = run_cli(capsys, ["models"])
    assert code == 2 and "manifest.json: model 'a b'" in one_error_line(err)
    (tmp_path / "manifest.json").write_text(json.dumps(
        {"format": "brdfkit-builtin-models", "version": 2, "bundles": [
            {"name": "a", "latent_dim": 7, "parts": {"decoder": {"file": "x.safetensors", "digest": "0" * 64}}}]}))
    code, _, err = run_cli(capsys, ["models"])
    assert code == 2 and "unknown part 'decoder'" in one_error_line(err)
    (tmp_path / "manifest.json").write_text('{"format": "brdfkit-builtin-models", "version": 3, "bundles": []}')
    code, _, err = run_cli(capsys, ["models"])
    assert code == 2 and "manifest version 3 is not supported" in one_error_line(err)


def _as_version_1(doc: dict) -> dict:
    """A version 2 manifest document written as version 1 was (``models``, each entry's
    network as ``file`` / ``fingerprint``, its prior and basis as ``prior`` /
    ``prior_fingerprint``, ``basis`` / ``basis_fingerprint``)."""
    models = []
    for e in doc["bundles"]:
        e = dict(e)
        parts = e.pop("parts")
        old = {"name": e.pop("name"), "file": parts["network"]["file"], "fingerprint": parts["network"]["digest"]}
        for key in ("prior", "basis"):
            if key in parts:
                old.update({key: parts[key]["file"], f"{key}_fingerprint": parts[key]["digest"]})
        models.append({**old, **e})
    return {"format": doc["format"], "version": 1, "default": doc["default"], "models": models}


@pytest.mark.slow
def test_version_1_manifest_still_reads(shelf, monkeypatch, capsys, tmp_path):
    """A manifest written before bundles (version 1: ``models``, ``file``, ``fingerprint``)
    reads as the same bundles, and every job takes its models as before."""
    folder = tmp_path / "builtin"
    shutil.copytree(shelf[0], folder)
    v2 = builtin.read_manifest(folder)
    doc = json.loads((folder / "manifest.json").read_text())
    assert doc["version"] == builtin.MANIFEST_VERSION == 2 and "bundles" in doc  # what write_manifest writes
    old = _as_version_1(doc)
    assert "fingerprint" in old["models"][0] and "parts" not in old["models"][0]
    (folder / "manifest.json").write_text(json.dumps(old))
    v1 = builtin.read_manifest(folder)
    assert v1 == v2
    monkeypatch.setenv(builtin.BUILTIN_ENV, str(folder))
    assert builtin.resolve_network("tiny-b") == str(folder / "tiny-b.safetensors")
    assert builtin.default_bundle().name == "tiny-a"
    code, out, err = run_cli(capsys, ["models", "--check", "--json"])
    assert code == 0, err
    assert [b["name"] for b in json.loads(out)["bundles"]] == ["tiny-a", "tiny-b"]
    code, _, err = run_cli(capsys, ["encode", shelf[1] / "mat.binary", "-m", "tiny-b", "-o", tmp_path / "o"])
    assert code == 0, err
    assert read_embedding(tmp_path / "o" / "mat.emb").decoder == v1.bundles[1].part("network").digest


def test_models_command(installed, capsys):
    code, out, err = run_cli(capsys, ["models", "--check"])
    assert code == 0, err
    for m in builtin.installed_bundles():
        assert m.name in out and m.part("network").digest[:12] in out
    assert "tiny-a *" in out and "N=400" in out and "0.300" in out and "checked: 2 model(s), 2 part(s)" in out
    assert f"tiny-b network: {installed[0] / 'tiny-b.safetensors'}" in out
    row = next(line for line in out.splitlines() if line.startswith("tiny-b "))
    assert "network" in row  # the parts column
    code, out, err = run_cli(capsys, ["models", "--json"])
    assert code == 0, err
    doc = json.loads(out)
    assert doc["default"] == "tiny-a" and [m["name"] for m in doc["bundles"]] == ["tiny-a", "tiny-b"]
    assert doc["folder"] == str(installed[0])
    assert doc["bundles"][1]["validation"] == {"40": 0.3, "400": 0.2} and doc["bundles"][0]["installed"]
    network = doc["bundles"][0]["parts"]["network"]
    assert network["file"] == "tiny-a.safetensors" and network["installed"]
    assert network["digest"] == builtin.installed_bundles()[0].part("network").digest


def test_models_command_fits_80_columns(shelf, tmp_path):
    # The shipped manifest's shape (longer names, steps, minutes, five N) in an 80-column
    # terminal: every figure readable, none cut to an ellipsis.
    folder = tmp_path / "builtin"
    shutil.copytree(shelf[0], folder)
    doc = json.loads((folder / "manifest.json").read_text())
    ns = (40, 100, 400, 1000, 4000)
    for i, d in enumerate(doc["bundles"]):
        d.update(name=f"merl-rgl-l40-{i}", materials=151, steps=30000 + i, train_seconds=840.3,
                 validation={str(n): 0.1234 + n / 1e5 for n in ns})
    builtin.write_manifest(folder, doc["bundles"], default="merl-rgl-l40-0")
    r = run_brdfkit(["models"], env={**quiet_env(), builtin.BUILTIN_ENV: str(folder), "COLUMNS": "80"})
    assert r.returncode == 0, r.stderr
    assert "\u2026" not in r.stdout and "..." not in r.stdout
    # The folder and the path lines run on (a terminal wraps them); the tables must fit.
    tables = r.stdout.split("\n\n")[:2]
    assert all(len(line) <= 80 for t in tables for line in t.splitlines()[1:]), r.stdout
    for i, d in enumerate(doc["bundles"]):
        assert f"merl-rgl-l40-{i}" in tables[0] and f"{30000 + i:,}" in tables[0] and "14 min" in tables[0]
        assert f"(digest {d['parts']['network']['digest'][:12]}; materials: stiff)" in r.stdout
    assert all(f"N={n}" in tables[1] and f"{0.1234 + n / 1e5:.3f}" in tables[1] for n in ns)


def test_models_command_with_none_installed(capsys):
    code, out, err = run_cli(capsys, ["models"])
    assert code == 0, err
    assert out.count("\n") == 1 and "no built-in models installed" in out
    code, out, _ = run_cli(capsys, ["models", "--json"])
    assert code == 0 and json.loads(out)["bundles"] == []


def test_models_command_speaks_in_renders(shelf, tmp_path):
    """The manifest's ``renders`` (tools/pack_builtin.py from a bench.json) are what
    ``brdfkit models`` shows first: PSNR / Delta E per N and for encode, and how and on
    which materials they were measured; a model without them shows dashes."""
    folder = tmp_path / "builtin"
    shutil.copytree(shelf[0], folder)
    doc = json.loads((folder / "manifest.json").read_text())
    doc["bundles"][0]["renders"] = {"psnr": {"40": 44.21, "400": 48.5, "encode": 41.97},
                                   "delta_e": {"40": 0.71, "400": 0.4, "encode": 0.861},
                                   "scenes": ["reference", "backlight"], "resolution": 64,
                                   "materials": "20 materials of test20 (held out)"}
    builtin.write_manifest(folder, doc["bundles"], default="tiny-a")
    r = run_brdfkit(["models"], env={**quiet_env(), builtin.BUILTIN_ENV: str(folder), "COLUMNS": "120"})
    assert r.returncode == 0, r.stderr
    assert "Validation: renders, PSNR dB / Delta E 2000" in r.stdout
    row = next(line for line in r.stdout.splitlines() if "tiny-a" in line and "44.2/0.71" in line)
    assert "48.5/0.40" in row and "42.0/0.86" in row
    assert "tiny-a: 20 materials of test20 (held out); scenes reference, backlight; 64 px" in r.stdout
    block = r.stdout.split("Validation: renders")[1].split("\n\n")[0]
    assert "tiny-a" in block and "tiny-b" not in block  # no figures, so no row in the renders' table
    # The manifest's field is checked: a render figure that is not a number is refused.
    doc["bundles"][0]["renders"]["psnr"]["40"] = "high"
    (folder / "manifest.json").write_text(json.dumps(doc))
    r = run_brdfkit(["models"], env={**quiet_env(), builtin.BUILTIN_ENV: str(folder)})
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "renders" in r.stderr, r.stderr
