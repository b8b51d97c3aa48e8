"""The routes that left the product on 2026-12-01 (``docs/notes/generalisation.md``, "What
left the product"): ``brdfkit sparse --method residual`` and its ``-O prior=FILE``,
``brdfkit fit --method correction`` and its ``-O latent``, the residual files of networks
of sparse fits. Each is refused in one line with exit code 2, and nothing is written."""

from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import one_error_line, run_cli


def _old_residual(folder, components: int = 4, latent: int = 0) -> str:
    """A residual file as ``brdfkit fit --method correction`` wrote it: one network of the
    basis's ``K`` components that takes the sample count (and, with ``latent``, a set
    encoder's latent), beside its basis. Written with the file format's own writer, since
    ``save_residual`` now refuses to write what ``load_residual`` refuses to read."""
    from brdfkit.io.digest import file_digest
    from brdfkit.io.tensorfile import write_safetensors
    from brdfkit.residual.network import hyponet_shapes
    from brdfkit.testing.examples import tiny_basis_file

    basis = tiny_basis_file(folder / "basis.safetensors", components)
    width, hidden, inputs = 8, 16, 2 * components + 1 + latent
    total = sum(int(np.prod(s)) for s in hyponet_shapes(width))
    shapes = {"body.0.weight": (hidden, inputs), "body.0.bias": (hidden,), "body.2.weight": (hidden, hidden),
              "body.2.bias": (hidden,), "head.weight": (total, hidden), "head.bias": (total,),
              **{f"base.{j}": s for j, s in enumerate(hyponet_shapes(width))}}
    cfg = {"k_min": components, "k_max": components, "width": width, "hidden": hidden, "count": True}
    if latent:
        cfg["latent"] = latent
    header = {"format": "brdfkit-residual", "version": "1", "storage": "float32", "configs": json.dumps([cfg]),
              "basis_digest": file_digest(basis), "basis_file": "basis.safetensors", "offered": "[]",
              "meta": json.dumps({"purpose": "sparse"})}
    path = folder / "correction.safetensors"
    write_safetensors(path, {f"net0.{k}": np.zeros(s, np.float32) for k, s in shapes.items()}, header)
    return path


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    """A table, a sample set of it and an old residual file of sparse fits."""
    from brdfkit.acquisition.sampling import draw_samples
    from brdfkit.io.merl import write_merl
    from brdfkit.io.samples import write_samples
    from brdfkit.testing.examples import lambertian_table

    d = tmp_path_factory.mktemp("left")
    write_merl(d / "t.binary", lambertian_table())
    write_samples(d / "s.csv", draw_samples(lambertian_table(), 40, seed=0))
    return d, _old_residual(d)


def test_sparse_method_residual_is_an_unknown_choice(inputs, capsys, tmp_path):
    d, old = inputs
    code, _, err = run_cli(capsys, ["sparse", d / "s.csv", "--method", "residual", "-m", old, "-o",
                                    tmp_path / "o.binary"])
    assert code == 2 and "Invalid value for '--method'" in err and "'residual' is not one of" in err, err
    assert not (tmp_path / "o.binary").exists()


def test_fit_method_correction_is_an_unknown_choice(inputs, capsys, tmp_path):
    d, _ = inputs
    code, _, err = run_cli(capsys, ["fit", "--method", "correction", d, "-O", "latent=16", "-o",
                                    tmp_path / "c.safetensors"])
    assert code == 2 and "Invalid value for '--method'" in err and "'correction' is not one of" in err, err
    assert not list(tmp_path.iterdir())


def test_the_library_refuses_them_in_one_line(inputs):
    import brdfkit
    from brdfkit.errors import InputError

    d, old = inputs
    with pytest.raises(InputError, match="unknown method 'residual'; known: hypernet, ipca, nbrdf, prior"):
        brdfkit.sparse(d / "s.csv", old, method="residual")
    with pytest.raises(InputError, match="unknown --method 'correction' for fit; known: hypernet, basis, prior, "
                                         "residual"):
        brdfkit.fit([d], d / "c.safetensors", method="correction")


@pytest.mark.parametrize("extra", [[], ["--size", "12"], ["--size", "90"], ["--kind", "residual"]])
def test_encode_with_a_residual_of_sparse_fits_is_refused_in_one_line(inputs, capsys, tmp_path, extra):
    """It used to stop on an IndexError (no size to encode at), and ``--size 90`` listed an
    empty set of sizes."""
    d, old = inputs
    code, _, err = run_cli(capsys, ["encode", d / "t.binary", "-m", old, *extra, "-o", tmp_path / "e.emb"])
    line = one_error_line(err)
    assert code == 2 and "holds a network of sparse fits (count: brdfkit fit --method correction)" in line, line
    assert "internal error" not in line and "hold  numbers" not in line
    assert not (tmp_path / "e.emb").exists()


def test_decode_and_load_refuse_it_too(inputs, capsys, tmp_path):
    """An ``.emb`` of ``sparse --method residual --emb`` (its ``samples`` option) names such a
    file: its decode is refused by the same line, and a set encoder's file (``-O latent``)
    alike."""
    from brdfkit.errors import FormatError
    from brdfkit.io.digest import file_digest
    from brdfkit.io.embedding import Embedding, write_embedding
    from brdfkit.residual.residual_file import load_residual, read_offer

    d, old = inputs
    emb = Embedding(np.zeros(12, np.float32), "residual", file_digest(old), "s.csv", 40,
                    options={"correction": 1.0, "samples": 40})
    write_embedding(tmp_path / "s.emb", emb)
    code, _, err = run_cli(capsys, ["decode", tmp_path / "s.emb", "-m", old, "-o", tmp_path / "o.binary"])
    assert code == 2 and "holds a network of sparse fits" in one_error_line(err)
    assert not (tmp_path / "o.binary").exists()
    latent = _old_residual(tmp_path, latent=4)
    for read in (load_residual, read_offer):
        with pytest.raises(FormatError, match=r"sparse fits \(count, latent: brdfkit fit --method correction\)"):
            read(latent)


def test_sparse_options_of_the_method_that_left_are_refused(inputs, capsys, tmp_path):
    """``-O prior=FILE`` and ``-O correction=...`` were method residual's; ``--emb`` is the
    hypernetwork's alone."""
    from brdfkit.testing.examples import tiny_basis_file

    d, _ = inputs
    basis = tiny_basis_file(tmp_path / "b.safetensors")
    for argv, words in ((["-m", basis, "-O", "prior=x.safetensors"], "method 'ipca' takes the option(s) lam, got prior"),
                        (["-m", basis, "-O", "correction=on"], "method 'ipca' takes the option(s) lam, got correction"),
                        (["-m", basis, "--emb", tmp_path / "o.emb"], "--method hypernet does (its latent)")):
        code, _, err = run_cli(capsys, ["sparse", d / "s.csv", *argv, "-o", tmp_path / "o.binary"])
        assert code == 2 and words in one_error_line(err), err
    assert not (tmp_path / "o.binary").exists() and not (tmp_path / "o.emb").exists()
