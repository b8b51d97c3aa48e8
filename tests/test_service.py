"""What a model serves (``brdfkit.methods.service``): one answer, from the headers alone, that
``brdfkit models``, ``encode``, ``decode`` and ``sparse`` all ask, so that a route it lists
runs and a route it does not is refused in one line saying what it serves.

The built-in folder is a temporary one (``$BRDFKIT_BUILTIN_MODELS``): ``tiny-p`` (the
default: a hypernetwork, a learnt prior, its basis of 3 components and a residual of that
basis with networks of 1 and 3 components, two members at 3, offered at 3 and 9 numbers),
``tiny-h`` (a hypernetwork alone) and ``tiny-b`` (a basis alone).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from brdfkit.models import builtin

from conftest import one_error_line, run_cli
from helpers_model import material_table, pack_tiny_builtins, write_inputs

BASIS = "tiny.basis.safetensors"
PRIOR = "tiny-p.prior.safetensors"
RESIDUAL = "tiny-p.residual.safetensors"


def _residual(folder, nets) -> str:
    """An untrained residual of the basis :data:`BASIS` in ``folder``: a network for each
    ``(k, member)`` of ``nets``, offered at 3 and 9 numbers; returns its digest."""
    from brdfkit.io.digest import file_digest
    from brdfkit.residual.network import ResidualConfig, hyponet_shapes
    from brdfkit.residual.residual_file import save_residual

    rng = np.random.default_rng(0)
    out = []
    for k, member in nets:
        cfg = ResidualConfig(k, k, width=4, hidden=5, member=member)
        total = sum(int(np.prod(s)) for s in hyponet_shapes(cfg.width))
        shapes = {"body.0.weight": (5, cfg.inputs), "body.0.bias": (5,), "body.2.weight": (5, 5), "body.2.bias": (5,),
                  "head.weight": (total, 5), "head.bias": (total,),
                  **{f"base.{j}": s for j, s in enumerate(hyponet_shapes(cfg.width))}}
        out.append((cfg, {n: 0.01 * rng.normal(size=s).astype(np.float32) for n, s in shapes.items()}))
    save_residual(folder / RESIDUAL, out, basis_digest=file_digest(folder / BASIS), basis_file=BASIS, offered=(3, 9))
    return file_digest(folder / RESIDUAL)


@pytest.fixture(scope="module")
def shelf(tmp_path_factory):
    """``(folder, inputs)``: the built-in folder and a folder with ``mat.binary`` and a
    200-sample set ``s.csv`` of it."""
    import torch

    from brdfkit.basis import fit_basis, save_basis
    from brdfkit.io.digest import file_digest
    from brdfkit.prior.model import PriorConfig, PriorModel, prior_net
    from brdfkit.prior.prior_file import basis_entry, save_prior

    src = tmp_path_factory.mktemp("trained")
    folder = tmp_path_factory.mktemp("builtin")
    entries = pack_tiny_builtins(src, folder, (("tiny-p", 0), ("tiny-h", 1)), validation={})
    basis = fit_basis([material_table(0), material_table(1)], n_components=3, names=["stiff-white", "ggx"])
    cfg = PriorConfig(n_components=3, latent_dim=4, width=8)
    torch.manual_seed(0)
    fp = save_prior(folder / PRIOR, PriorModel(basis, prior_net(cfg), cfg, {"materials": ["stiff-white", "ggx"]}),
                    basis_file=BASIS)
    entries[0]["parts"].update(prior={"file": PRIOR, "digest": fp}, **basis_entry(folder / PRIOR))
    entries[0]["parts"]["residual"] = {"file": RESIDUAL, "digest": _residual(folder, [(1, 0), (3, 0), (3, 1)])}
    save_basis(folder / "tiny-b.safetensors", basis)
    entries.append({"name": "tiny-b", "parts": {"basis": {"file": "tiny-b.safetensors",
                                                          "digest": file_digest(folder / "tiny-b.safetensors")}}})
    builtin.write_manifest(folder, entries, default="tiny-p")
    return folder, write_inputs(tmp_path_factory.mktemp("inputs"))


WANT = {"tiny-p": ({"residual": (3, 9), "basis": (3, 6, 9), "hypernet": (7,)}, {"residual": 9, "basis": 9, "hypernet": 7},
                   {"residual": 2, "basis": 1, "hypernet": 1}, ("prior", "hypernet", "ipca")),
        "tiny-h": ({"hypernet": (7,)}, {"hypernet": 7}, {"hypernet": 1}, ("hypernet",)),
        "tiny-b": ({"basis": (3, 6, 9)}, {"basis": 9}, {"basis": 1}, ("ipca",))}


def test_each_builtin_says_what_it_serves(installed):
    from brdfkit.methods.service import installed_services, serves

    folder, _ = installed
    services = installed_services()
    assert [s.bundle for s in services] == ["tiny-p", "tiny-h", "tiny-b"]
    for s in services:
        kinds, sizes, members, methods = WANT[s.bundle]
        assert (s.kinds, s.default_sizes, s.members, s.methods) == (kinds, sizes, members, methods), s
        assert s.default_kind == next(iter(kinds)) and s.default_method == methods[0] and s.label == s.bundle
    p = services[0]
    assert p.files == {"network": str(folder / "tiny-p.safetensors"), "basis": str(folder / BASIS),
                       "prior": str(folder / PRIOR), "residual": str(folder / RESIDUAL)}  # PARTS' order
    assert serves("tiny-h") == services[1] and serves(None).label == "tiny-p, the default built-in"
    assert p.summary() == ("residual embeddings of 3, 9 numbers; basis embeddings of 3, 6, 9 numbers; hypernet "
                           "embeddings of 7 numbers; sparse --method prior, hypernet, ipca")


def test_what_it_serves_is_read_from_the_headers_and_is_what_the_loaded_files_offer(installed, monkeypatch):
    """No weights are loaded to say what a model serves; what the headers say is what the
    loaded files give (:attr:`EmbeddingKind.sizes`, ``default_size``, the members)."""
    from brdfkit.embeddings.kind import EmbeddingKind
    from brdfkit.embeddings.registry import KINDS
    from brdfkit.methods.service import installed_services

    def refuse(*a, **k):
        raise AssertionError("a part was loaded to say what it serves")

    with monkeypatch.context() as m:
        m.setattr(EmbeddingKind, "load", refuse)
        services = installed_services()
    for s in services:
        for kind, sizes in s.kinds.items():
            obj, _ = KINDS[kind].load(s.files[KINDS[kind].part], "cpu")
            assert tuple(KINDS[kind].sizes(obj)) == sizes and KINDS[kind].default_size(obj) == s.default_sizes[kind]
            if kind == "residual":
                assert max(len(obj.members(sz // 3)) for sz in sizes) == s.members[kind]


def test_every_route_it_lists_runs_and_the_others_are_refused(installed):
    """``kind_for`` and ``choose_decoder`` take every kind and size listed, ``choose`` every
    method listed and loads its file; what is not listed is refused in one line that says
    what the model serves."""
    from brdfkit.embeddings import choose_decoder
    from brdfkit.embeddings.registry import KINDS
    from brdfkit.errors import InputError
    from brdfkit.methods import METHODS
    from brdfkit.methods.choice import choose
    from brdfkit.methods.service import installed_services

    for s in installed_services():
        for kind, sizes in s.kinds.items():
            for size in sizes:
                dec = choose_decoder(kind, s.bundle, "cpu", size)
                assert s.kind_for(kind, size) == kind and dec.kind == kind and size in dec.sizes
                assert s.kind_for(None, size) == next(k for k in s.kinds if size in s.kinds[k])
            for size in set(range(1, 13)) - set(sizes):
                with pytest.raises(InputError, match=f"--size {size}: .*; it serves {s.summary()}"):
                    s.kind_for(kind, size)
        for kind in set(KINDS) - set(s.kinds):
            with pytest.raises(InputError, match=f"it serves {s.summary()}"):
                s.kind_for(kind)
        for method in s.methods:
            choice = choose(method, s.bundle)
            assert (choice.method, choice.label) == (method, s.bundle)
            assert METHODS[method].load(choice.path, "cpu") is not None
        assert choose("auto", s.bundle).method == s.default_method
        for method in set(METHODS) - set(s.methods):
            with pytest.raises(InputError, match=f"it serves {s.summary()}|takes no model file"):
                choose(method, s.bundle)


def test_a_builtin_with_a_basis_alone_reconstructs_by_ipca(installed, capsys, tmp_path):
    """``--method auto`` runs what the model serves: ``ipca`` for a basis alone (it used to
    ask for the hypernetwork ``tiny-b`` does not ship)."""
    _, inputs = installed
    code, _, err = run_cli(capsys, ["sparse", inputs / "s.csv", "-m", "tiny-b", "-o", tmp_path / "o.binary"])
    assert code == 0 and "(method ipca, model tiny-b)" in err, err


@pytest.mark.parametrize("argv, words", [
    (["encode", "{mat}", "-m", "tiny-p", "--size", "12"],
     "--size 12: tiny-p makes no embedding of 12 numbers; it serves residual embeddings of 3, 9 numbers; basis "
     "embeddings of 3, 6, 9 numbers; hypernet embeddings of 7 numbers; sparse --method prior, hypernet, ipca"),
    (["encode", "{mat}", "-m", "tiny-h", "--size", "9"], "--size 9: hypernet embeddings of tiny-h hold 7 numbers"),
    (["encode", "{mat}", "-m", "tiny-p", "--kind", "residual", "--size", "6"],
     "--size 6: residual embeddings of tiny-p hold 3, 9 numbers; it serves"),
    (["encode", "{mat}", "-m", "tiny-h", "--kind", "basis"],
     "built-in model 'tiny-h' ships no PCA basis (built-ins with one: tiny-p, tiny-b; `brdfkit models` lists them); "
     "it serves hypernet embeddings of 7 numbers; sparse --method hypernet"),
    (["sparse", "{s}", "-m", "tiny-b", "--method", "prior"],
     "built-in model 'tiny-b' ships no learnt prior (built-ins with one: tiny-p; `brdfkit models` lists them); "
     "it serves basis embeddings of 3, 6, 9 numbers; sparse --method ipca"),
    (["sparse", "{s}", "-m", "tiny-b", "--method", "nbrdf"], "method 'nbrdf' takes no model file, got tiny-b"),
    (["sparse", "{s}", "-m", "{residual}"], "a basis residual file, which no sparse-reconstruction method takes")])
def test_a_route_it_does_not_serve_is_one_line_saying_what_it_serves(installed, capsys, tmp_path, argv, words):
    folder, inputs = installed
    args = [a.format(mat=inputs / "mat.binary", s=inputs / "s.csv", residual=folder / RESIDUAL) for a in argv]
    code, _, err = run_cli(capsys, [*args, "-o", tmp_path / "out"])
    assert code == 2 and words in one_error_line(err), err
    assert not (tmp_path / "out").exists()


def test_decode_with_a_model_without_the_embeddings_part_says_what_it_serves(installed, capsys, tmp_path):
    from brdfkit.io.embedding import Embedding, write_embedding

    folder, _ = installed
    write_embedding(tmp_path / "r.emb", Embedding(np.zeros(9, np.float32), "residual", "0" * 64, "x"))
    code, _, err = run_cli(capsys, ["decode", tmp_path / "r.emb", "-m", "tiny-h", "-o", tmp_path / "o.binary"])
    line = one_error_line(err)
    assert code == 2 and "'tiny-h' ships no basis residual" in line and "it serves hypernet embeddings" in line


def test_files_serve_their_part(installed, tmp_path):
    from brdfkit.methods.service import serves

    folder, inputs = installed
    for path, kinds, methods in ((folder / BASIS, {"basis": (3, 6, 9)}, ("ipca",)),
                                 (folder / PRIOR, {}, ("prior",)),
                                 (folder / RESIDUAL, {"residual": (3, 9)}, ()),
                                 (folder / "tiny-h.safetensors", {"hypernet": (7,)}, ("hypernet",))):
        s = serves(path)
        assert (s.bundle, s.label, s.kinds, s.methods) == (None, str(path), kinds, methods)
        assert list(s.files.values()) == [str(path)]
    junk = tmp_path / "junk.safetensors"
    junk.write_bytes(b"not safetensors")
    s = serves(junk)  # its header names no part: the loader of the job's part says what it is
    assert (s.files, s.kinds, s.methods) == ({}, {}, ())
    assert (s.kind_for(), s.method_for(), s.path("prior")) == ("hypernet", "hypernet", str(junk))


def test_models_lists_what_each_builtin_serves(installed, capsys):
    code, out, err = run_cli(capsys, ["models"])
    assert code == 0, err
    assert "tiny-p encode: residual 3, 9* (2 members); basis 3, 6, 9*; hypernet 7*" in out
    assert "tiny-p sparse: prior, hypernet, ipca" in out and "tiny-b sparse: ipca" in out
    code, out, err = run_cli(capsys, ["models", "--json"])
    served = {b["name"]: b["serves"] for b in json.loads(out)["bundles"]}
    assert served["tiny-b"] == {"kinds": {"basis": [3, 6, 9]}, "default_kind": "basis", "default_sizes": {"basis": 9},
                                "members": {"basis": 1}, "methods": ["ipca"], "default_method": "ipca"}
