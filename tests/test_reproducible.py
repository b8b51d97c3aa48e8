"""Same input, same bytes (issue 28 item 5): ``brdfkit encode`` and ``brdfkit sparse
--method hypernet`` give identical output files on an idle machine and beside a busy
process (where the command line picks fewer torch threads); budgets are steps, and a
wall-clock cap is only applied when asked for, and said."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from brdfkit.acquisition.sampling import draw_samples
from brdfkit.io.merl import write_merl
from brdfkit.io.samples import write_samples

from conftest import run_brdfkit, run_cli
from helpers_model import make_model, material_table


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    d = tmp_path_factory.mktemp("repro")
    make_model(d / "model.safetensors", seed=1)
    write_merl(d / "mat.binary", material_table(1))
    write_samples(d / "s.csv", draw_samples(material_table(1), 300, seed=2))
    return d


def _busy(n: int):
    """``n`` processes that keep a core busy each."""
    return [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(n)]


def _run_twice(commands, outputs):
    """The bytes of ``outputs`` after the ``brdfkit`` ``commands`` on two torch threads,
    then beside a busy process with the thread count the command line picks for the load
    (one: ``threads_for_load(2, 1)``, as beside two; a second busy process only slowed
    the commands, sharing 2 cores with the suite's other worker)."""
    env = {k: v for k, v in os.environ.items() if k not in ("OMP_NUM_THREADS", "MKL_NUM_THREADS")}
    got = []
    for busy, extra in ((0, {"OMP_NUM_THREADS": "2"}), (1, {})):
        procs = _busy(busy)
        try:
            for args in commands:
                r = run_brdfkit(args, env={**env, **extra}, timeout=300)
                assert r.returncode == 0, r.stderr
        finally:
            for p in procs:
                p.kill()
                p.wait()
        got.append([open(o, "rb").read() for o in outputs])
        for o in outputs:
            os.remove(o)
    return got


@pytest.mark.slow
def test_encode_and_sparse_give_the_same_bytes_idle_and_beside_busy_processes(inputs, tmp_path):
    emb, out, s_emb = tmp_path / "mat.emb", tmp_path / "s.binary", tmp_path / "s.emb"
    model = inputs / "model.safetensors"
    # Short budgets (2 refinement steps, 5 sample-refinement steps a stage): a thread
    # count's other sums show in the first step's bytes; more steps only cost seconds
    # (each command runs twice, once beside a busy process).
    idle, busy = _run_twice([["encode", inputs / "mat.binary", "-m", model, "-o", tmp_path, "--steps", "2"],
                             ["sparse", inputs / "s.csv", "--method", "hypernet", "-m", model, "--refine-target",
                              "latent", "-O", "steps=5", "-o", out, "--emb", s_emb]], [emb, out, s_emb])
    assert idle == busy
    rec = json.loads(idle[0])["refinement"]
    assert rec["stopped"] in ("steps", "converged") and 0 <= rec["best_step"] <= rec["steps"] <= 2


def test_max_seconds_cuts_and_says_so(inputs, tmp_path, capsys):
    code, out, err = run_cli(capsys, ["encode", inputs / "mat.binary", "-m", inputs / "model.safetensors",
                                      "-o", tmp_path, "--steps", "100000", "--max-seconds", "0.01"])
    assert code == 0, err
    assert "--max-seconds cut" in out + err
    assert json.loads((tmp_path / "mat.emb").read_text())["refinement"]["stopped"] == "max_seconds"
