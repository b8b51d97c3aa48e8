"""The learnt prior as part of a built-in model: ``brdfkit sparse``'s method ``auto``
(``brdfkit.methods.choice``), ``-m NAME`` for every method, ``brdfkit models``,
``brdfkit bench`` with built-in names, ``brdfkit.load_model(NAME)``.

The built-in folder is a temporary one (``$BRDFKIT_BUILTIN_MODELS``): ``tiny-p`` (the
default: an untrained tiny hypernetwork and an untrained learnt prior over a 3-component
PCA basis of two synthetic tables, the basis in a shared file beside it) and ``tiny-h``
(a hypernetwork only), packed and listed with the real functions. Untrained models: the
tests check which file runs, not how well.
"""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from brdfkit import api
from brdfkit.io.embedding import read_embedding
from brdfkit.io.merl import read_merl
from brdfkit.methods import get_method
from brdfkit.models import builtin
from brdfkit.io.samples import read_samples, write_samples
from brdfkit.acquisition.sampling import draw_samples

from conftest import one_error_line, run_cli
from helpers_model import material_table, pack_tiny_builtins, write_inputs

BASIS = "tiny.basis.safetensors"
PRIOR = "tiny-p.prior.safetensors"


def _pack_prior(path, tables) -> str:
    """An untrained learnt prior over a 3-component basis of ``tables``, the basis in
    :data:`BASIS` beside it; returns its digest."""
    import torch

    from brdfkit.basis import fit_basis
    from brdfkit.prior.prior_file import save_prior
    from brdfkit.prior.model import PriorConfig, PriorModel, prior_net

    basis = fit_basis(tables, n_components=3, names=["stiff-white", "ggx"])
    cfg = PriorConfig(n_components=3, latent_dim=4, width=8)
    torch.manual_seed(0)
    return save_prior(path, PriorModel(basis, prior_net(cfg), cfg, {"materials": ["stiff-white", "ggx"]}),
                      basis_file=BASIS)


@pytest.fixture(scope="module")
def shelf(tmp_path_factory):
    """``(folder, inputs)``: the built-in folder and a folder with ``mat.binary`` and a
    200-sample set ``s.csv`` of it."""
    src = tmp_path_factory.mktemp("trained")
    folder = tmp_path_factory.mktemp("builtin")
    entries = pack_tiny_builtins(src, folder, (("tiny-p", 0), ("tiny-h", 1)), validation={40: 0.3})
    fp = _pack_prior(folder / PRIOR, [material_table(0), material_table(1)])
    from brdfkit.prior.prior_file import basis_entry

    entries[0]["parts"].update(prior={"file": PRIOR, "digest": fp}, **basis_entry(folder / PRIOR))
    builtin.write_manifest(folder, entries, default="tiny-p")
    return folder, write_inputs(tmp_path_factory.mktemp("inputs"))


def _check_table(out, method: str, model, samples) -> None:
    """``out`` holds what ``method`` reconstructs from ``samples`` with ``model`` (through
    the MERL file's scales and back)."""
    want = get_method(method).reconstruct(read_samples(samples), str(model), device="cpu")
    np.testing.assert_allclose(read_merl(out), want, rtol=1e-12, equal_nan=True)


# --- brdfkit sparse ---------------------------------------------------------------------------

@pytest.mark.slow
@pytest.mark.parametrize("argv, library", [
    ([], {}),                                                # the default: the default built-in's learnt prior
    (["--method", "ipca"], {"method": "ipca"}),              # no -m: the default built-in's basis
    (["-m", "tiny-h"], {"model": "tiny-h"}),                 # a built-in without a prior: its hypernetwork
    (["-m", "tiny-h", "--no-refine"], {"model": "tiny-h", "refine": False}),
])
def test_library_and_command_line_sparse_write_the_same_bytes(installed, capsys, tmp_path, argv, library):
    """``brdfkit.sparse(samples)`` and ``brdfkit sparse`` run the same method with the same
    model and defaults, and so write the same table to the byte."""
    from brdfkit.io.merl import write_merl

    _, inputs = installed
    code, _, err = run_cli(capsys, ["sparse", inputs / "s.csv", *argv, "-o", tmp_path / "cli.binary"])
    assert code == 0, err
    table, _ = api.sparse(read_samples(inputs / "s.csv"), **library)
    write_merl(tmp_path / "lib.binary", table)
    assert (tmp_path / "cli.binary").read_bytes() == (tmp_path / "lib.binary").read_bytes()


@pytest.mark.slow
def test_library_and_command_line_encode_and_decode_write_the_same_bytes(installed, capsys, tmp_path):
    from brdfkit.io.embedding import write_embedding
    from brdfkit.io.merl import write_merl

    _, inputs = installed
    for argv, kw in (([], {}), (["--size", "6", "--steps", "3"], {"size": 6, "steps": 3})):
        code, _, err = run_cli(capsys, ["encode", inputs / "mat.binary", *argv, "-o", tmp_path / "cli"])
        assert code == 0, err
        emb = api.encode(inputs / "mat.binary", **kw)
        assert emb.kind == "basis"  # the default built-in ships a basis
        write_embedding(tmp_path / "lib.emb", emb)
        assert (tmp_path / "cli" / "mat.emb").read_bytes() == (tmp_path / "lib.emb").read_bytes()
        code, _, err = run_cli(capsys, ["decode", tmp_path / "cli" / "mat.emb", "-o", tmp_path / "cli.binary"])
        assert code == 0, err
        write_merl(tmp_path / "lib.binary", api.decode(tmp_path / "lib.emb"))
        assert (tmp_path / "cli.binary").read_bytes() == (tmp_path / "lib.binary").read_bytes()
        (tmp_path / "cli.binary").unlink()


def test_sparse_default_is_the_default_builtins_prior(installed, capsys, tmp_path):
    folder, inputs = installed
    code, out, err = run_cli(capsys, ["sparse", inputs / "s.csv", "-o", tmp_path / "a.binary"])
    assert code == 0, err
    assert out == "" and "(method prior, model tiny-p, the default built-in)" in err
    _check_table(tmp_path / "a.binary", "prior", folder / PRIOR, inputs / "s.csv")
    # --method prior without -m takes the same file.
    code, _, err = run_cli(capsys, ["sparse", inputs / "s.csv", "--method", "prior", "-o", tmp_path / "b.binary"])
    assert code == 0 and "(method prior, model tiny-p, the default built-in)" in err
    assert (tmp_path / "b.binary").read_bytes() == (tmp_path / "a.binary").read_bytes()


@pytest.mark.slow
def test_sparse_default_without_a_prior_is_the_hypernetwork(installed, capsys, monkeypatch, tmp_path):
    """A default built-in without a learnt prior: its hypernetwork, as before."""
    folder, inputs = installed
    alt = tmp_path / "builtin"
    shutil.copytree(folder, alt)
    entries = [m.to_json() for m in builtin.read_manifest(alt).bundles]
    for e in entries:
        for key in ("default", "installed"):
            e.pop(key)
        for part in e["parts"].values():
            part.pop("path")
    builtin.write_manifest(alt, entries, default="tiny-h")
    monkeypatch.setenv(builtin.BUILTIN_ENV, str(alt))
    code, _, err = run_cli(capsys, ["sparse", inputs / "s.csv", "-o", tmp_path / "h.binary",
                                    "--emb", tmp_path / "h.emb"])
    assert code == 0, err
    assert "(method hypernet, model tiny-h, the default built-in)" in err
    assert read_embedding(tmp_path / "h.emb").decoder == builtin.installed_bundles()[1].part("network").digest


@pytest.mark.slow
def test_sparse_builtin_name_for_every_method(installed, capsys, tmp_path):
    folder, inputs = installed
    s = inputs / "s.csv"
    fps = {m.name: m.part("network").digest for m in builtin.installed_bundles()}
    cases = [([], "tiny-p", "prior", folder / PRIOR),
             ([], "tiny-h", "hypernet", folder / "tiny-h.safetensors"),
             (["--method", "prior"], "tiny-p", "prior", folder / PRIOR),
             (["--method", "ipca"], "tiny-p", "ipca", folder / BASIS),
             (["--method", "hypernet"], "tiny-p", "hypernet", folder / "tiny-p.safetensors")]
    for i, (extra, name, method, model) in enumerate(cases):
        out = tmp_path / f"{i}.binary"
        code, _, err = run_cli(capsys, ["sparse", s, "-m", name, *extra, "-o", out])
        assert code == 0, (extra, name, err)
        assert f"(method {method}, model {name})" in err, err
        _check_table(out, method, model, s)
    code, _, err = run_cli(capsys, ["sparse", s, "-m", "tiny-p", "--method", "hypernet", "-o", tmp_path / "e.binary",
                                    "--emb", tmp_path / "e.emb"])
    assert code == 0, err
    assert read_embedding(tmp_path / "e.emb").decoder == fps["tiny-p"]  # the hypernetwork's


@pytest.mark.slow
def test_sparse_file_by_its_format(installed, capsys, tmp_path):
    folder, inputs = installed
    s = inputs / "s.csv"
    for i, (file, method) in enumerate(((PRIOR, "prior"), (BASIS, "ipca"), ("tiny-h.safetensors", "hypernet"))):
        out = tmp_path / f"{i}.binary"
        code, _, err = run_cli(capsys, ["sparse", s, "-m", folder / file, "-o", out])
        assert code == 0, err
        assert f"(method {method}, model {folder / file})" in err
        _check_table(out, method, folder / file, s)
    # Not a model file at all: the hypernetwork loader names what it is.
    code, _, err = run_cli(capsys, ["sparse", s, "-m", inputs / "mat.binary", "-o", tmp_path / "x.binary"])
    assert code == 2 and "mat.binary" in one_error_line(err)
    assert not (tmp_path / "x.binary").exists()


def test_sparse_usage_errors(installed, capsys, tmp_path):
    folder, inputs = installed
    s, out = inputs / "s.csv", tmp_path / "x.binary"
    for argv, words in (([], ("learnt prior", "makes no embedding", "--method hypernet does")),
                        (["--method", "prior", "-m", "tiny-p"], ("learnt prior", "--method hypernet does")),
                        (["--method", "ipca", "-m", "tiny-p"], ("method 'ipca' makes no embedding",))):
        code, _, err = run_cli(capsys, ["sparse", s, *argv, "-o", out, "--emb", tmp_path / "x.emb"])
        line = one_error_line(err)
        assert code == 2 and all(w in line for w in words), line
    for argv, words in ((["-m", "tiny-h", "--method", "prior"], ("'tiny-h' ships no learnt prior", "with one: tiny-p")),
                        (["-m", "tiny-h", "--method", "ipca"], ("'tiny-h' ships no PCA basis", "with one: tiny-p")),
                        (["-m", "nope"], ("unknown model 'nope'", "tiny-p, tiny-h"))):
        code, _, err = run_cli(capsys, ["sparse", s, *argv, "-o", out])
        line = one_error_line(err)
        assert code == 2 and all(w in line for w in words), line
    assert not out.exists() and not (tmp_path / "x.emb").exists()


def test_sparse_with_nothing_installed(capsys, tmp_path):
    write_samples(tmp_path / "s.csv", draw_samples(material_table(1), 50, seed=0))
    for argv in ([], ["--method", "prior"], ["--method", "hypernet"]):
        code, _, err = run_cli(capsys, ["sparse", tmp_path / "s.csv", *argv, "-o", tmp_path / "x.binary"])
        assert code == 2 and "no model given" in one_error_line(err)


def test_damaged_basis_refused(shelf, monkeypatch, capsys, tmp_path):
    folder = tmp_path / "builtin"
    shutil.copytree(shelf[0], folder)
    monkeypatch.setenv(builtin.BUILTIN_ENV, str(folder))
    data = bytearray((folder / BASIS).read_bytes())
    data[-3] ^= 0x40
    (folder / BASIS).write_bytes(bytes(data))
    for argv in (["sparse", shelf[1] / "s.csv", "-o", tmp_path / "x.binary"], ["models", "--check"]):
        code, _, err = run_cli(capsys, argv)
        assert code == 2 and "not the one it was saved with" in one_error_line(err)


def test_version_1_manifest_with_a_prior_still_reads(shelf, monkeypatch, capsys, tmp_path):
    """A version 1 manifest named a built-in's learnt prior and its basis beside the
    hypernetwork (``prior`` / ``prior_fingerprint``, ``basis`` / ``basis_fingerprint``): it
    reads as the same bundles, and ``sparse`` takes the same prior by default."""
    folder = tmp_path / "builtin"
    shutil.copytree(shelf[0], folder)
    doc = json.loads((folder / "manifest.json").read_text())
    models = []
    for e in doc["bundles"]:
        e = dict(e)
        parts = e.pop("parts")
        old = {"file": parts["network"]["file"], "fingerprint": parts["network"]["digest"]}
        for key in ("prior", "basis"):
            if key in parts:
                old.update({key: parts[key]["file"], f"{key}_fingerprint": parts[key]["digest"]})
        models.append({**e, **old})
    v2 = builtin.read_manifest(folder)
    old = {"format": doc["format"], "version": 1, "default": doc["default"], "models": models}
    (folder / "manifest.json").write_text(json.dumps(old))
    assert builtin.read_manifest(folder) == v2
    monkeypatch.setenv(builtin.BUILTIN_ENV, str(folder))
    assert builtin.resolve_prior("tiny-p") == str(folder / PRIOR)
    assert builtin.resolve_basis("tiny-p") == str(folder / BASIS)
    code, _, err = run_cli(capsys, ["sparse", shelf[1] / "s.csv", "-o", tmp_path / "a.binary"])
    assert code == 0 and "(method prior, model tiny-p, the default built-in)" in err, err
    _check_table(tmp_path / "a.binary", "prior", folder / PRIOR, shelf[1] / "s.csv")


# --- brdfkit models, brdfkit.load_model ---------------------------------------------------------

def test_models_command_shows_the_prior(installed, capsys):
    folder, _ = installed
    code, out, err = run_cli(capsys, ["models", "--check"])
    assert code == 0, err
    rows = {}  # the first table's rows (the validation table's come after)
    for line in out.splitlines():
        if line.startswith("tiny-") and "/" not in line:
            rows.setdefault(line.split()[0], line.split())
    assert rows["tiny-p"][1] == "*" and set(rows["tiny-p"][2:5]) == {"network", "prior", "basis"}
    assert rows["tiny-p"][5] == "7"
    assert rows["tiny-h"][1:3] == ["network", "7"]
    assert f"tiny-p prior: {folder / PRIOR}" in out and f"tiny-p basis: {folder / BASIS}" in out
    assert f"tiny-p network: {folder / 'tiny-p.safetensors'}" in out
    assert "checked: 2 model(s), 4 part(s): each loads and matches the manifest" in out
    code, out, err = run_cli(capsys, ["models", "--json"])
    assert code == 0, err
    models = {m["name"]: m for m in json.loads(out)["bundles"]}
    prior = models["tiny-p"]["parts"]["prior"]
    assert prior["file"] == PRIOR and prior["installed"] and len(prior["digest"]) == 64
    assert models["tiny-p"]["parts"]["basis"]["file"] == BASIS
    assert set(models["tiny-h"]["parts"]) == {"network"}


def test_load_model_takes_a_builtin_name(installed):
    folder, _ = installed
    m = api.load_model("tiny-h", device="cpu")
    assert m.digest == builtin.installed_bundles()[1].part("network").digest
    import brdfkit

    assert brdfkit.load_model("tiny-p", device="cpu").digest == builtin.installed_bundles()[0].part("network").digest


# --- brdfkit bench ------------------------------------------------------------------------------

@pytest.mark.slow
def test_bench_default_methods_lead_with_a_builtins_prior(installed, capsys, tmp_path):
    """With no --methods, a built-in -m that has a learnt prior adds the method 'prior'
    (its prior, as `sparse --method auto` picks it) before hypernet, ipca, nbrdf."""
    from brdfkit.bench import DEFAULT_METHODS, BenchConfig

    folder, inputs = installed
    r = BenchConfig(output="o", data=str(inputs), model="tiny-p", ipca="tiny-p").resolved()
    assert r.methods == ("prior", *DEFAULT_METHODS) and r.models == {"prior": str(folder / PRIOR)}
    for cfg in (BenchConfig(output="o", model="tiny-h"), BenchConfig(output="o", model=str(folder / "tiny-p.safetensors")),
                BenchConfig(output="o")):
        assert cfg.resolved().methods == DEFAULT_METHODS and cfg.resolved().models == {}
    assert BenchConfig(output="o", model="tiny-p", methods=("ipca",)).resolved().methods == ("ipca",)
    # The built-in's basis is the default ipca's when --ipca is not given; a given one stays.
    assert BenchConfig(output="o", model="tiny-p").resolved().ipca == str(folder / BASIS)
    assert BenchConfig(output="o", model="tiny-p", ipca="x.safetensors").resolved().ipca == "x.safetensors"
    assert BenchConfig(output="o", model="tiny-h").resolved().ipca is None
    given = BenchConfig(output="o", model="tiny-h", models={"prior": "tiny-p"}).resolved()
    assert given.methods == ("prior", *DEFAULT_METHODS) and given.models == {"prior": str(folder / PRIOR)}

    out = tmp_path / "out"
    code, _, err = run_cli(capsys, ["bench", "--data", inputs, "-m", "tiny-p", "--ipca", "tiny-p", "--n", "40",
                                    "--seeds", "1", "--nbrdf-steps", "2", "--resolution", "8", "--threads", "1",
                                    "-q", "-o", out])
    assert code == 0, err
    result = json.loads((out / "bench.json").read_text())
    assert result["config"]["methods"] == ["prior", "hypernet", "ipca", "nbrdf"]
    # The record names the built-in as given, and holds the digests of the parts that ran.
    assert result["config"]["models"] == {"prior": "tiny-p"} and result["config"]["ipca"] == "tiny-p"
    tiny_p = {b.name: b for b in builtin.read_manifest(folder).bundles}["tiny-p"]
    assert result["parts"] == {"tiny-p": {p: tiny_p.part(p).digest for p in ("basis", "network", "prior")}}
    assert sorted(r["method"] for r in result["records"]) == ["hypernet", "ipca", "nbrdf", "prior"]
    assert all("error" not in r for r in result["records"]), result["records"]


@pytest.mark.slow
def test_bench_takes_builtin_names(installed, capsys, tmp_path):
    from brdfkit.bench import BenchConfig
    from brdfkit.errors import InputError

    folder, inputs = installed
    cfg = BenchConfig(output=str(tmp_path / "o"), data=str(inputs), model="tiny-h", ipca="tiny-p",
                      models={"prior": "tiny-p"}, compression_models=("tiny-h",), compression_data=str(inputs))
    r = cfg.resolved()
    assert (r.model, r.ipca, r.models, r.compression_models) == (
        str(folder / "tiny-h.safetensors"), str(folder / BASIS), {"prior": str(folder / PRIOR)},
        (str(folder / "tiny-h.safetensors") + ":hypernet-7",))  # what `encode -m tiny-h` makes: its latent
    assert BenchConfig(output="o", model="x/m.safetensors").resolved().model == "x/m.safetensors"
    with pytest.raises(InputError, match="'tiny-h' ships no learnt prior"):
        BenchConfig(output="o", models={"prior": "tiny-h"}).resolved()
    with pytest.raises(InputError, match="method 'prior' needs --model-file prior=FILE"):
        BenchConfig(output="o", data=str(inputs), methods=("prior",)).validate()

    out = tmp_path / "out"
    code, _, err = run_cli(capsys, ["bench", "--data", inputs, "--methods", "hypernet,ipca,prior", "-m", "tiny-h",
                                    "--ipca", "tiny-p", "--model-file", "prior=tiny-p", "--n", "40", "--seeds", "1",
                                    "--resolution", "8", "--threads", "1", "-q", "-o", out])
    assert code == 0, err
    result = json.loads((out / "bench.json").read_text())
    assert result["complete"] and result["config"]["models"] == {"prior": "tiny-p"}
    assert result["config"]["model"] == "tiny-h" and str(folder) not in json.dumps(result["config"])
    bundles = {b.name: b for b in builtin.read_manifest(folder).bundles}
    assert result["parts"] == {"tiny-h": {"network": bundles["tiny-h"].part("network").digest},
                               "tiny-p": {p: bundles["tiny-p"].part(p).digest for p in ("basis", "prior")}}
    # Its compression entries too: the name given, the kind and size that ran.
    assert cfg.recorded(r)[0]["compression_models"] == ("tiny-h:hypernet-7",)
    recs = result["records"]
    assert sorted(r["method"] for r in recs) == ["hypernet", "ipca", "prior"]
    assert all("error" not in r for r in recs), recs

    code, _, err = run_cli(capsys, ["bench", "--data", inputs, "--methods", "prior", "--model-file", "prior=nope",
                                    "-o", tmp_path / "bad"])
    assert code == 2 and "unknown model 'nope'" in one_error_line(err)
