"""Training: the model learns, bad steps are skipped, checkpoints resume, inputs are checked.

All fits use the tiny model of ``conftest.TINY`` on 3 synthetic materials, one
thread; the subprocess tests run the real ``brdfkit fit`` command and real signals.
"""

from __future__ import annotations

import os
import signal
import time
import warnings

import numpy as np
import pytest
import torch

from brdfkit.hypernet import network as hypernet
from brdfkit.hypernet.training.checkpoint import load_checkpoint
from brdfkit.errors import FormatError, InputError
from brdfkit.io.merl import read_merl
from brdfkit.hypernet.network_file import load_network, weights_digest
from brdfkit.hypernet.training.loop import TrainingError, fit
from brdfkit.hypernet.mapping import median_reference
from brdfkit.io.folders import collect_materials, read_exclude_list

from conftest import TINY, TINY_LATENT, popen_brdfkit, run_cli, tiny_cli_options, tmp_leftovers
from helpers_training import mapped_mse_and_log_rmse, tiny_library


@pytest.fixture(scope="module")
def lib(tmp_path_factory):
    return tiny_library(tmp_path_factory)


def tiny_fit(lib, out, **kw):
    kw = {**TINY, "latent_dim": TINY_LATENT, "progress": False, **kw}
    return fit(lib, out, **kw)


def untrained(cfg, seed=0):
    torch.manual_seed(seed)
    return hypernet.HyperBRDF(cfg).eval()


# --- the model learns ---------------------------------------------------------------------

@pytest.mark.slow
def test_trained_model_reconstructs_far_better_than_untrained(lib, tmp_path):
    out = tmp_path / "m.safetensors"
    tiny_fit(lib, out, steps=200)
    model = load_network(out, "cpu")
    assert model.meta["steps"] == 200 and model.meta["skipped_steps"] == 0
    assert model.meta["materials"] == ["synth-000", "synth-001", "synth-002"]
    init = untrained(model.cfg)
    for name in model.meta["materials"]:
        table = read_merl(lib / f"{name}.binary")
        mse_t, log_t = mapped_mse_and_log_rmse(model.net, model.rho_ref, table)
        mse_u, log_u = mapped_mse_and_log_rmse(init, model.rho_ref, table)
        # Measured: 45-90x (mapped MSE) and 4.2-7x (log RMSE) better after 200 steps.
        assert mse_t * 10 < mse_u, (name, mse_t, mse_u)
        assert log_t * 3 < log_u, (name, log_t, log_u)


@pytest.mark.slow
def test_reference_is_median_of_training_materials(lib, tmp_path):
    out = tmp_path / "m.safetensors"
    tiny_fit(lib, out, steps=2, exclude=["synth-002"])
    model = load_network(out, "cpu")
    assert model.meta["materials"] == ["synth-000", "synth-001"]
    assert model.meta["excluded"] == ["synth-002"]
    tables = [read_merl(lib / f"synth-00{i}.binary") for i in (0, 1)]
    from brdfkit.hypernet.mapping import median_reference
    np.testing.assert_array_equal(model.rho_ref, median_reference(tables))


@pytest.mark.slow
def test_fast_median_equals_nanmedian(lib):
    tables = [read_merl(lib / f"synth-00{i}.binary") for i in range(3)]
    holey = tables[0].copy()
    holey[40:45, 10:20, :, :] = np.nan  # unmeasured in one table only: the nanmedian path
    rng = np.random.default_rng(0)
    holes = np.isnan(holey.reshape(-1))
    unmeasured = np.isnan(tables[0].reshape(-1))  # below the horizon: NaN in every table
    # The columns compared: 50,000 at random, every hole of one table only, and 20,000 of
    # the all-NaN columns (not all million of them: np.nanmedian's seconds)
    some = lambda where, k: rng.choice(np.flatnonzero(where), k, replace=False)  # noqa: E731
    for group in (tables, tables + [holey]):  # odd and even counts
        stack = np.stack([t.astype(np.float32).reshape(-1) for t in group])
        fast = median_reference(stack).reshape(-1)
        assert (holes & ~unmeasured).sum() > 10_000
        cols = np.union1d(np.union1d(rng.integers(0, stack.shape[1], 50_000), np.flatnonzero(holes & ~unmeasured)),
                          some(unmeasured, 20_000))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN columns below the horizon
            want = np.nanmedian(stack[:, cols], axis=0)
        np.testing.assert_array_equal(fast[cols], want)


# --- non-finite steps ----------------------------------------------------------------------

def _nan_loss_on(monkeypatch, calls):
    real = hypernet.hyper_loss
    count = {"n": 0}

    def loss(*a, **k):
        count["n"] += 1
        total, mse = real(*a, **k)
        if count["n"] in calls:
            return total * float("nan"), mse
        return total, mse

    monkeypatch.setattr(hypernet, "hyper_loss", loss)
    return count


def test_nan_step_is_skipped_without_update(lib, tmp_path, monkeypatch):
    _nan_loss_on(monkeypatch, calls={1, 2, 3})
    out = tmp_path / "m.safetensors"
    tiny_fit(lib, out, steps=3)
    model = load_network(out, "cpu")
    assert model.meta["skipped_steps"] == 3
    # Nothing was trained on: the weights are exactly the seed's initial weights.
    assert model.digest == weights_digest(untrained(model.cfg))


def test_training_goes_on_after_a_nan_step(lib, tmp_path, monkeypatch):
    _nan_loss_on(monkeypatch, calls={2})
    out = tmp_path / "m.safetensors"
    tiny_fit(lib, out, steps=6)
    model = load_network(out, "cpu")
    assert model.meta["skipped_steps"] == 1 and model.meta["steps"] == 6
    assert model.digest != weights_digest(untrained(model.cfg))
    assert all(torch.isfinite(p).all() for p in model.net.parameters())


@pytest.mark.slow
def test_persistent_nan_stops_with_clear_error(lib, tmp_path, monkeypatch):
    _nan_loss_on(monkeypatch, calls=set(range(1, 100)))
    out = tmp_path / "m.safetensors"
    with pytest.raises(TrainingError, match="NaN or infinite for 4 consecutive steps"):
        tiny_fit(lib, out, steps=50, max_bad_steps=4)
    assert not out.exists()


# --- checkpoints and resume ----------------------------------------------------------------

@pytest.mark.slow
def test_resume_continues_exactly(lib, tmp_path):
    """5 steps + resume to 10 gives bit-identical weights to 10 steps in one go: the
    checkpoint holds the optimiser state and the sampler re-seeds from the step."""
    whole, split = tmp_path / "whole.safetensors", tmp_path / "split.safetensors"
    # TINY has a constant rate: a cosine schedule follows the total of each run (5, then 10).
    tiny_fit(lib, whole, steps=10)
    tiny_fit(lib, split, steps=5)
    assert load_checkpoint(str(split) + ".ckpt")["step"] == 5
    tiny_fit(lib, split, steps=10, resume=True)
    a, b = load_network(whole, "cpu"), load_network(split, "cpu")
    assert a.digest == b.digest
    assert b.meta["resumed_from_steps"] == [5] and b.meta["steps"] == 10


@pytest.mark.slow
def test_resume_refuses_other_data_or_options(lib, tmp_path):
    out = tmp_path / "m.safetensors"
    tiny_fit(lib, out, steps=2)
    with pytest.raises(InputError, match="other materials"):
        tiny_fit(lib, out, steps=4, resume=True, exclude=["synth-001"])
    with pytest.raises(InputError, match="other training options"):
        tiny_fit(lib, out, steps=4, resume=True, query_size=256)
    with pytest.raises(InputError, match="another model configuration"):
        tiny_fit(lib, out, steps=4, resume=True, hypo_hidden=16)
    with pytest.raises(InputError, match="seed"):
        tiny_fit(lib, out, steps=4, resume=True, seed=3)
    with pytest.raises(InputError, match="no checkpoint"):
        tiny_fit(lib, tmp_path / "other.safetensors", steps=4, resume=True)
    bogus = tmp_path / "bogus.safetensors"
    (tmp_path / "bogus.safetensors.ckpt").write_bytes(b"not a checkpoint at all")
    with pytest.raises(FormatError, match="checkpoint"):
        tiny_fit(lib, bogus, steps=4, resume=True)


def _wait_for(path, proc, timeout=60.0):
    t0 = time.monotonic()
    while not os.path.exists(path):
        if proc.poll() is not None:
            raise AssertionError(f"fit ended early ({proc.returncode}): {proc.stderr.read()}")
        if time.monotonic() - t0 > timeout:
            proc.kill()
            raise AssertionError("no checkpoint appeared")
        time.sleep(0.1)


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGKILL], ids=["sigint", "sigkill"])
def test_interrupted_fit_resumes_from_checkpoint(lib, tmp_path, sig, capsys):
    out = tmp_path / "m.safetensors"
    ckpt = str(out) + ".ckpt"
    args = ["fit", lib, "-o", out, "--steps", "1000000", "--minutes", "2",
            "--checkpoint-minutes", "0.005", *tiny_cli_options()]
    proc = popen_brdfkit(args)
    _wait_for(ckpt, proc)
    time.sleep(0.5)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=60)
    if sig == signal.SIGINT:
        assert proc.returncode == 130, err
        assert "checkpoint" in err and "saved" in err and "Traceback" not in err
        assert tmp_leftovers(tmp_path) == []
    else:
        assert proc.returncode == -signal.SIGKILL
    assert not out.exists()  # the model is written only at the end
    done = int(load_checkpoint(ckpt)["step"])
    assert done > 0
    # the resumption in this process: the interrupted run is the one that needs a process of its own
    code, _, err = run_cli(capsys, args[:4] + ["--steps", str(done + 15)] + args[6:] + ["--resume"])
    assert code == 0, err
    assert f"at step {done}" in err
    meta = load_network(out, "cpu").meta
    assert meta["steps"] == done + 15 and meta["resumed_from_steps"] == [done]


@pytest.mark.slow
def test_minutes_budget_stops_training(lib, tmp_path):
    out = tmp_path / "m.safetensors"
    t0 = time.monotonic()
    tiny_fit(lib, out, steps=10_000_000, minutes=0.01)
    assert time.monotonic() - t0 < 60  # 10 million steps would take hours
    meta = load_network(out, "cpu").meta
    assert 0 < meta["steps"] < 10_000_000
    # --minutes chose the step count once (issue 28): --steps replays the run, bit for bit.
    assert meta["budget"]["steps"] == meta["steps"] and meta["budget"]["probe_steps"] > 0
    again = tmp_path / "again.safetensors"
    tiny_fit(lib, again, steps=meta["steps"])
    assert load_network(again, "cpu").digest == load_network(out, "cpu").digest
    assert load_network(again, "cpu").meta["budget"] is None


# --- inputs --------------------------------------------------------------------------------

def test_collect_materials_sorted_and_excluded(lib, tmp_path):
    paths, names, excluded, unknown = collect_materials(
        [lib / "synth-002.binary", lib], exclude=["synth-001.binary", "nosuch"])
    assert names == ["synth-000", "synth-002"]
    assert [os.path.basename(p) for p in paths] == ["synth-000.binary", "synth-002.binary"]
    assert excluded == ["synth-001"] and unknown == ["nosuch"]
    lst = tmp_path / "test.txt"
    lst.write_text("# held out\nsynth-000  # a comment\n\n  synth-002\n")
    assert read_exclude_list(lst) == ["synth-000", "synth-002"]


def test_bad_inputs_are_clear_errors(lib, tmp_path):
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(InputError, match="no .binary files"):
        collect_materials(empty)
    with pytest.raises(InputError, match="no such file"):
        collect_materials(tmp_path / "missing")
    with pytest.raises(InputError, match="nothing to train on"):
        collect_materials(lib, exclude=["synth-000", "synth-001", "synth-002"])
    other = tmp_path / "other"
    other.mkdir()
    os.symlink(lib / "synth-000.binary", other / "synth-001.binary")
    with pytest.raises(InputError, match="unique"):
        collect_materials([lib, other])
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "broken.binary").write_bytes(b"\x5a\x00\x00\x00" * 10)
    os.symlink(lib / "synth-000.binary", bad / "synth-000.binary")
    with pytest.raises(FormatError, match="broken.binary"):
        tiny_fit(bad, tmp_path / "m.safetensors", steps=2)
    with pytest.raises(InputError, match="also an input"):
        tiny_fit(lib / "synth-000.binary", lib / "synth-000.binary", steps=2)
    with pytest.raises(InputError, match="unknown training option"):
        tiny_fit(lib, tmp_path / "m.safetensors", steps=2, query_sise=3)
    with pytest.raises(InputError, match="steps"):
        tiny_fit(lib, tmp_path / "m.safetensors", steps=0)
    with pytest.raises(InputError, match="does not exist"):
        tiny_fit(lib, tmp_path / "nodir" / "m.safetensors", steps=2)
    with pytest.raises(InputError, match="device"):
        tiny_fit(lib, tmp_path / "m.safetensors", steps=2, device="tpu")


def test_options_and_the_schedule():
    # brdfkit.hypernet.training.options holds them; brdfkit.hypernet.training.loop still offers TrainOptions.
    from brdfkit.hypernet.training import loop as training
    from brdfkit.hypernet.training.options import TrainOptions, lr_factor, parse_options

    assert training.TrainOptions is TrainOptions
    cos = TrainOptions(warmup_steps=10, lr_schedule="cosine", lr_final=0.1)
    assert lr_factor(0, 0.0, cos) == pytest.approx(0.1)  # warm-up: step 1 of 10
    assert lr_factor(9, 0.0, cos) == pytest.approx(1.0)
    assert lr_factor(50, 0.5, cos) == pytest.approx(0.55)  # half way down the cosine
    assert lr_factor(50, 1.0, cos) == lr_factor(50, 3.0, cos) == pytest.approx(0.1)
    const = TrainOptions(warmup_steps=4, lr_schedule="constant")
    assert [lr_factor(s, 0.9, const) for s in (0, 3, 99)] == [0.25, 1.0, 1.0]
    assert lr_factor(0, 0.0, TrainOptions(warmup_steps=0, lr_schedule="constant")) == 1.0
    opts, cfg = parse_options(7, {"lr": 1, "hypo_hidden": 16, "encoder_hidden": [8, 8]})
    assert opts.lr == 1.0 and isinstance(opts.lr, float) and cfg.latent_dim == 7
    assert cfg.hypo_hidden == 16 and cfg.encoder_hidden == (8, 8)
    for bad, match in (({"lr_schedule": "step"}, "lr_schedule"), ({"query_sise": 3}, "unknown training option"),
                       ({"lr": "fast"}, "not a float"), ({"context_min": 9, "context_max": 8}, "context_max")):
        with pytest.raises(InputError, match=match):
            parse_options(7, bad)


def test_cli_reports_bad_input_in_one_line(lib, tmp_path, capsys):
    code, _, err = run_cli(capsys, ["fit", tmp_path / "nothing", "-o", tmp_path / "m.safetensors"])
    assert code == 2
    assert err.strip().splitlines() == [f"brdfkit: error: {tmp_path / 'nothing'}: no such file or folder"]
    code, _, err = run_cli(capsys, ["fit", lib, "-o", tmp_path / "m.safetensors", "-O", "lr"])
    assert code == 2 and "KEY=VALUE" in err
