"""The sparse reconstruction through the basis plus a correction (``brdfkit fit --method
correction``, ``brdfkit sparse --method residual``): training (seeded, resumable to the
bit), the held-out choice, the table and the embedding it writes, and refusals."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import run_cli, run_cli_uncaptured
from helpers_training import synthetic_library

pytestmark = pytest.mark.slow  # a basis, a learnt prior and a correction trained: a minute

TINY = ["-O", "folds=2", "-O", "width=8", "-O", "hidden=16", "-O", "batch=2", "-O", "cells=128",
        "-O", "context_min=8", "-O", "context_max=64", "-O", "checkpoint_every=2"]


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """Four synthetic tables, a basis of 3 components with the grazing share, a tiny learnt
    prior and a correction of 4 steps."""
    lib = synthetic_library(tmp_path_factory, 4, seed=1)
    out = tmp_path_factory.mktemp("correction")
    basis, prior, corr = out / "basis.safetensors", out / "prior.safetensors", out / "corr.safetensors"
    for args in (["fit", "--method", "basis", lib, "--components", "3", "-O", "w_floor=0.005", "-O", "eps_share=0.03",
                  "-o", basis],
                 ["fit", "--method", "prior", lib, "-O", f"basis={basis}", "-O", "folds=2", "--steps", "3",
                  "--latent-dim", "4", "-O", "width=8", "-O", "query_size=64", "--batch-materials", "2", "-q",
                  "-o", prior],
                 ["fit", "--method", "correction", lib, "-O", f"prior={prior}", "-O", f"basis={basis}", "--steps", "4",
                  *TINY, "-o", corr]):
        code, err = run_cli_uncaptured(args)
        assert code == 0, err
    return lib, basis, prior, corr


def _residual(trained):
    from brdfkit.basis import load_basis
    from brdfkit.io.digest import file_digest
    from brdfkit.residual import load_residual

    _, basis, _, corr = trained
    return load_residual(corr, basis=(load_basis(basis), file_digest(basis)))


class _StopAfterTwoSteps:
    """Stands in for the Ctrl-C handler: a stop is asked for after the loop's second step
    (its checkpoint written), as a cut training is."""

    def __init__(self):
        self.reads = 0

    @property
    def requested(self):
        self.reads += 1  # two reads a step: the loop's, the checkpoint's
        return self.reads > 4

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False


def test_the_correction_is_one_count_network_naming_its_prior_and_resumes_to_the_bit(trained, tmp_path,
                                                                                    monkeypatch):
    from brdfkit.prior.correction import fit_correction
    from brdfkit.prior.prior_file import load_prior
    from brdfkit.residual.residual_file import serves_sparse

    lib, basis, prior, corr = trained
    res = _residual(trained)
    (cfg, _), = res.nets
    assert cfg.count and cfg.k_min == cfg.k_max == 3 and serves_sparse(corr)
    assert res.meta["prior_digest"] == load_prior(prior).digest and res.meta["purpose"] == "sparse"
    assert res.sizes() == ()  # encode offers nothing of a network of sparse fits
    opts = dict(folds=2, width=8, hidden=16, batch=2, cells=128, context_min=8, context_max=64, checkpoint_every=2,
                steps=4)
    cut = tmp_path / "cut.safetensors"
    monkeypatch.setattr("brdfkit.distributed.StopSignals", _StopAfterTwoSteps)
    fit_correction([lib], cut, prior=prior, basis=basis, progress=False, **opts)
    assert not cut.exists() and (tmp_path / "cut.safetensors.ckpt").exists()
    monkeypatch.undo()
    fit_correction([lib], cut, prior=prior, basis=basis, progress=False, resume=True, **opts)
    assert cut.read_bytes() == corr.read_bytes()


def test_sparse_through_the_correction_writes_the_table_its_embedding_decodes(trained, tmp_path, capsys):
    from brdfkit.acquisition.sampling import draw_samples
    from brdfkit.io.embedding import read_embedding
    from brdfkit.io.merl import read_merl
    from brdfkit.io.samples import write_samples

    lib, basis, prior, corr = trained
    table = read_merl(next(lib.glob("*.binary")))
    write_samples(tmp_path / "s.csv", draw_samples(table, 60, seed=0))
    outs = {}
    for mode in ("on", "off", "auto"):
        out, emb = tmp_path / f"{mode}.binary", tmp_path / f"{mode}.emb"
        code, _, err = run_cli(capsys, ["sparse", tmp_path / "s.csv", "-m", corr, "-O", f"prior={prior}", "-O",
                                        f"correction={mode}", "-o", out, "--emb", emb])
        assert code == 0, err
        assert "method residual" in err
        e = read_embedding(emb)
        assert e.kind == "residual" and e.size == 9 and e.options["samples"] == 60
        assert e.options["correction"] == (1.0 if mode == "on" else 0.0 if mode == "off" else e.options["correction"])
        code, _, err = run_cli(capsys, ["decode", emb, "-m", corr, "-o", tmp_path / f"{mode}-back.binary"])
        assert code == 0, err
        assert (tmp_path / f"{mode}-back.binary").read_bytes() == out.read_bytes()
        outs[mode] = out.read_bytes()
    assert outs["auto"] in (outs["on"], outs["off"]) and outs["on"] != outs["off"]
    # --method prior is the same coefficients decoded by the basis alone
    code, _, err = run_cli(capsys, ["sparse", tmp_path / "s.csv", "-m", prior, "--method", "prior", "-o",
                                    tmp_path / "prior.binary"])
    assert code == 0, err
    assert (tmp_path / "prior.binary").read_bytes() == outs["off"]


def test_the_held_out_choice_is_the_lower_error_and_depends_on_the_samples_alone(trained):
    from brdfkit.acquisition.sampling import draw_samples
    from brdfkit.io.merl import read_merl
    from brdfkit.prior.corrected import CorrectedPrior
    from brdfkit.prior.prior_file import load_prior

    lib, _, prior, _ = trained
    model = CorrectedPrior(load_prior(prior), _residual(trained))
    table = read_merl(sorted(lib.glob("*.binary"))[1])
    samples = draw_samples(table, 40, seed=2)
    a, b = model.fit(samples), model.fit(samples)
    assert a.heldout == b.heldout and a.corrected == (a.heldout[1] < a.heldout[0])
    np.testing.assert_array_equal(a.coefficients, b.coefficients)
    one = model.fit(samples.subset(np.arange(1)))  # nothing to hold out: the basis alone
    assert one.heldout is None and not one.corrected


def test_refusals_in_one_line(trained, tmp_path, capsys):
    from brdfkit.acquisition.sampling import draw_samples
    from brdfkit.io.merl import read_merl
    from brdfkit.io.samples import write_samples

    lib, basis, prior, corr = trained
    write_samples(tmp_path / "s.csv", draw_samples(read_merl(next(lib.glob("*.binary"))), 20, seed=0))
    for args, words in (
            (["sparse", tmp_path / "s.csv", "-m", corr, "-o", tmp_path / "o.binary"], "give it with -O prior=FILE"),
            (["sparse", tmp_path / "s.csv", "-m", corr, "-O", f"prior={prior}", "-O", "correction=maybe", "-o",
              tmp_path / "o.binary"], "correction='maybe'"),
            (["sparse", tmp_path / "s.csv", "-m", prior, "--emb", tmp_path / "o.emb", "-o", tmp_path / "o.binary"],
             "--emb: the learnt prior (method prior) makes no embedding"),
            (["fit", "--method", "correction", lib, "-O", f"basis={basis}", "-o", tmp_path / "c.safetensors"],
             "needs -O prior=PRIOR"),
            (["fit", "--method", "correction", lib, "-O", f"prior={prior}", "-O", f"basis={basis}", "-O", "loss=l1",
              "-o", tmp_path / "c.safetensors"], "-O loss=l1")):
        code, _, err = run_cli(capsys, args)
        lines = [line for line in err.splitlines() if line.strip()]
        assert code == 2 and len(lines) == 1 and words in lines[0], err
    assert not (tmp_path / "o.binary").exists() and not (tmp_path / "c.safetensors").exists()
