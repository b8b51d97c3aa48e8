"""The part registry (``brdfkit.models.parts.PARTS``): the one place a model's parts are
defined (file, digest rule, loader, class), which the manifest, the embedding kinds, the
reconstruction methods and ``brdfkit fit``'s recipes refer to; files and loaded objects
told apart by their header format and their class; the digest a part loads with is its
rule's; a file of a part a job does not take refused in one line."""

from __future__ import annotations

import numpy as np
import pytest

from brdfkit.errors import InputError
from brdfkit.models.parts import HEADER_DIGEST_KEY, PARTS, file_part, get_part, part_of, part_of_format

from conftest import run_cli


def test_every_registry_refers_to_the_parts():
    from brdfkit.embeddings import KINDS
    from brdfkit.methods import METHODS
    from brdfkit.training import FITTERS

    assert list(PARTS) == ["network", "basis", "prior", "residual"]
    assert all(p.name == n for n, p in PARTS.items())
    assert {k: v.part for k, v in KINDS.items()} == {"residual": "residual", "basis": "basis", "hypernet": "network"}
    assert {k: v.part for k, v in METHODS.items()} == {"hypernet": "network", "ipca": "basis", "nbrdf": None,
                                                       "prior": "prior"}
    assert {k: v.part for k, v in FITTERS.items()} == {"hypernet": "network", "basis": "basis", "prior": "prior",
                                                       "residual": "residual"}
    with pytest.raises(InputError, match="unknown model part 'weights'; parts: network, basis, prior, residual"):
        get_part("weights")


def test_the_formats_and_classes_are_the_part_packages_own():
    """The registry names each part's header format and class; the packages that write and
    load the files hold the same."""
    from brdfkit.basis.basis_file import BASIS_FORMAT, is_basis_format
    from brdfkit.hypernet.network_file import MODEL_FORMAT
    from brdfkit.prior.prior_file import PRIOR_FORMAT
    from brdfkit.residual.residual_file import RESIDUAL_FORMAT

    assert PARTS["network"].formats[0] == MODEL_FORMAT
    assert PARTS["basis"].formats[0] == BASIS_FORMAT
    assert all(is_basis_format(f) for f in PARTS["basis"].formats) and not is_basis_format(PRIOR_FORMAT)
    assert PARTS["prior"].formats == (PRIOR_FORMAT,) and PARTS["residual"].formats == (RESIDUAL_FORMAT,)
    assert [p.digest for p in PARTS.values()] == ["header", "file", "header", "file"]
    for part in PARTS.values():  # the class it names lives where it says (is_loaded looks there)
        assert part.type().__module__ == part.cls.split(":")[0]
    assert part_of_format(None) is None and part_of_format("brdfkit-ipca") is PARTS["basis"]


def _prior_file(path, basis):
    """A learnt-prior file of ``basis`` with random weights, written without torch."""
    from brdfkit.prior.model import PriorConfig, PriorModel, PriorWeights, _layer_shapes
    from brdfkit.prior.prior_file import save_prior

    cfg = PriorConfig(n_components=basis.n_components, latent_dim=4, width=8)
    rng = np.random.default_rng(0)
    weights = PriorWeights(cfg, {k: rng.normal(size=s).astype(np.float32) for k, s in _layer_shapes(cfg).items()})
    save_prior(path, PriorModel(basis, weights, cfg, {"materials": ["a", "b"]}))
    return path


def _residual_header(path):
    """A file whose header says it is a basis residual (what telling parts apart reads)."""
    from brdfkit.io.tensorfile import write_safetensors

    write_safetensors(path, {"x": np.zeros(1, np.float32)}, {"format": PARTS["residual"].formats[0],
                                                             "version": "1"})
    return path


def test_files_by_their_header_and_objects_by_their_class(tmp_path):
    from brdfkit.basis import load_basis
    from brdfkit.hypernet.network_file import load_network
    from brdfkit.prior.prior_file import load_prior
    from brdfkit.testing.examples import tiny_basis_file, tiny_model

    basis_path = tiny_basis_file(tmp_path / "b.safetensors")
    net_path = tiny_model(tmp_path / "n.safetensors")
    prior_path = _prior_file(tmp_path / "p.safetensors", load_basis(basis_path))
    residual_path = _residual_header(tmp_path / "r.safetensors")
    (tmp_path / "t.csv").write_text("not a model\n")
    found = {p: file_part(p).name for p in (basis_path, net_path, prior_path, residual_path, tmp_path / "t.csv")}
    # a file that is no part's is the network's to refuse (its loader says what it is)
    assert list(found.values()) == ["basis", "network", "prior", "residual", "network"]
    loaded = {"basis": load_basis(basis_path), "prior": load_prior(prior_path),
              "network": load_network(net_path, device="cpu")}
    for name, obj in loaded.items():
        assert part_of(obj) is PARTS[name]
        obj2, digest = PARTS[name].load(tmp_path / f"{name[0]}.safetensors", "cpu")
        assert type(obj2) is type(obj) and digest == PARTS[name].recorded_digest(tmp_path / f"{name[0]}.safetensors")
    # a header digest, under its one key, is the one the file's loader checks its content against
    from brdfkit.io.tensorfile import open_safetensors

    for name, path in (("network", net_path), ("prior", prior_path)):
        with open_safetensors(str(path)) as f:
            assert f.metadata()[HEADER_DIGEST_KEY] == loaded[name].digest == PARTS[name].load(path, "cpu")[1]
    assert PARTS["prior"].materials(loaded["prior"]) == {"a", "b"}
    assert part_of(object()) is None and part_of(loaded["basis"].components) is None


def test_sparse_refuses_a_file_of_another_part_than_its_method_takes(tmp_path, capsys):
    """A basis residual given to `sparse -m` goes to the method that takes residuals, whose
    loader refuses a file that lies in one line; a file of another part than --method
    takes is refused in one line."""
    from brdfkit.acquisition.sampling import draw_samples
    from brdfkit.io.samples import write_samples
    from brdfkit.testing.examples import lambertian_table, tiny_basis_file

    write_samples(tmp_path / "s.csv", draw_samples(lambertian_table(), 40, seed=0))
    residual = _residual_header(tmp_path / "r.safetensors")
    basis = tiny_basis_file(tmp_path / "b.safetensors")
    for args, message in (
            ([residual], "r.safetensors"),
            ([basis, "--method", "hypernet"], "b.safetensors: a PCA basis file, not the hypernetwork --method "
                                              "hypernet takes"),
            ([residual, "--method", "prior"], "r.safetensors: a basis residual file, not the learnt prior --method "
                                              "prior takes")):
        code, _, err = run_cli(capsys, ["sparse", tmp_path / "s.csv", "-m", *args, "-o", tmp_path / "o.binary"])
        lines = [line for line in err.splitlines() if line.strip()]
        assert code == 2 and len(lines) == 1 and message in lines[0], err
    assert not (tmp_path / "o.binary").exists()


def test_the_library_picks_a_loaded_models_method_by_its_class(tmp_path):
    import brdfkit
    from brdfkit.acquisition.sampling import draw_samples
    from brdfkit.basis import load_basis
    from brdfkit.testing.examples import lambertian_table, tiny_basis_file

    basis = load_basis(tiny_basis_file(tmp_path / "b.safetensors"))
    samples = draw_samples(lambertian_table(), 40, seed=0)
    table, emb = brdfkit.sparse(samples, basis)
    np.testing.assert_array_equal(table, brdfkit.sparse(samples, basis, method="ipca")[0])
    prior = brdfkit.methods.get_method("prior").load(_prior_file(tmp_path / "p.safetensors", basis))
    np.testing.assert_array_equal(brdfkit.sparse(samples, prior)[0], prior.reconstruct(samples))
    with pytest.raises(InputError, match="expected a name, a path or a loaded model, not a dict"):
        brdfkit.sparse(samples, {"basis": basis})
