"""Data-parallel training through a real ``torchrun --nproc_per_node 2`` (gloo, CPU)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from brdfkit.io.merl import read_merl
from brdfkit.hypernet.network_file import load_network
from brdfkit.hypernet.mapping import median_reference

from conftest import brdfkit_command, quiet_env, tiny_cli_options, tmp_leftovers
from helpers_training import tiny_library

pytest.importorskip("torch.distributed")


def torchrun() -> list[str]:
    script = Path(sys.executable).with_name("torchrun")
    return [str(script)] if script.exists() else [sys.executable, "-m", "torch.distributed.run"]


@pytest.mark.slow
def test_two_process_fit_gives_one_model_with_identical_ranks(tmp_path_factory, tmp_path):
    lib = tiny_library(tmp_path_factory)
    out = tmp_path / "m.safetensors"
    # A wall budget far below the step count: the stop must be agreed by both ranks
    # (rank 0's clock, shared each step), or one rank would hang in the next all-reduce.
    cmd = torchrun() + ["--nproc_per_node", "2", "--no-python", *brdfkit_command(), "fit", str(lib),
                        "-o", str(out), "--steps", "100000", "--minutes", "0.04", "--device", "cpu",
                        *tiny_cli_options()]
    env = quiet_env()
    env.pop("WORLD_SIZE", None)
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=240, env=env, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    # One model (and its checkpoint) and nothing else: rank 1 writes no files.
    assert sorted(os.listdir(tmp_path)) == ["m.safetensors", "m.safetensors.ckpt"]
    assert tmp_leftovers(tmp_path) == []
    assert proc.stderr.count("wrote ") == 1
    model = load_network(out, "cpu")
    meta = model.meta
    assert meta["world_size"] == 2
    assert 0 < meta["steps"] < 100000 and meta["skipped_steps"] == 0
    # Each rank reported the digest of its own final weights: both equal the file's.
    assert meta["rank_digests"] == [model.digest, model.digest]
    # The reference is the median of ALL training materials, not of rank 0's share.
    stack = np.stack([read_merl(lib / f"synth-00{i}.binary").astype(np.float32).reshape(-1)
                      for i in range(3)])
    np.testing.assert_array_equal(model.rho_ref, median_reference(stack))
