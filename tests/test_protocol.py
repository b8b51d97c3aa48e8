"""The benchmarks' one sampling protocol (``brdfkit.acquisition.protocol``, issue 22 item 4):
``brdfkit bench`` and ``benchmarks/eval_sparse.py`` reconstruct the same samples for the
same material, N and draw, uniform or planned; ``brdfkit bench --sampling planned``."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from brdfkit.bench import BenchConfig, run_bench, sample_seed
from brdfkit.errors import InputError
from brdfkit.io.merl import read_merl
from brdfkit.acquisition.planning import plan_directions
from brdfkit.acquisition.protocol import SamplingProtocol, draw_seed
from brdfkit.acquisition.sampling import draw_samples, measure_samples

from conftest import no_bench_plots, quiet_env
from helpers_training import tiny_library

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
EVAL_SPARSE = os.path.join(REPO, "benchmarks", "eval_sparse.py")


@pytest.fixture(scope="module")
def lib(tmp_path_factory):
    """The three synthetic tables of the training tests, a 4-component basis fitted to them,
    a test list of two."""
    from brdfkit.basis import fit_basis, save_basis

    root = tmp_path_factory.mktemp("protocol")
    lib = tiny_library(tmp_path_factory)
    names = sorted(p.stem for p in lib.glob("*.binary"))
    save_basis(root / "basis.safetensors", fit_basis(sorted(lib.glob("*.binary")), n_components=4))
    (root / "test.txt").write_text(f"{names[0]}\n{names[2]}\n")
    return {"root": root, "lib": lib, "names": names, "basis": root / "basis.safetensors", "test": root / "test.txt"}


@pytest.mark.slow
def test_uniform_is_the_bench_draw(lib):
    name = lib["names"][0]
    table = read_merl(lib["lib"] / f"{name}.binary")
    samples, info = SamplingProtocol("uniform").samples(table, name, 30, 2)
    assert draw_seed(2, 30, name) == sample_seed(2, 30, name)  # the bench's name for it
    want = draw_samples(table, 30, seed=draw_seed(2, 30, name))
    np.testing.assert_array_equal(samples.rgb, want.rgb)
    assert info == {"sampling": "uniform", "sample_seed": draw_seed(2, 30, name),
                    "samples_digest": want.digest()}
    other, _ = SamplingProtocol("uniform").samples(table, lib["names"][1], 30, 2)
    assert other.digest() != samples.digest()  # another material, another draw


@pytest.mark.slow
def test_planned_is_the_table_at_the_plan(lib):
    protocol = SamplingProtocol("planned", lib["basis"], "nielsen")
    tables = [read_merl(lib["lib"] / f"{n}.binary") for n in lib["names"][:2]]
    (a, info), (b, _) = [protocol.samples(t, n, 12, 1) for t, n in zip(tables, lib["names"])]
    plan = plan_directions(lib["basis"], 12, design="nielsen", seed=1)
    np.testing.assert_array_equal(a.theta_h, plan.directions.theta_h)  # the same directions for every material
    np.testing.assert_array_equal(b.theta_h, plan.directions.theta_h)
    np.testing.assert_array_equal(a.rgb, measure_samples(tables[0], plan.directions).rgb)
    assert info == {"sampling": "planned", "design": "nielsen", "plan_seed": 1,
                    "condition_number": plan.condition_number, "samples_digest": a.digest()}
    again, _ = protocol.samples(tables[0], lib["names"][0], 12, 2)
    assert again.digest() != a.digest()  # another draw, another plan


@pytest.mark.parametrize("args, message", [
    (("sobol",), "unknown sampling 'sobol'; known: uniform, planned"),
    (("planned",), "planned sampling needs the PCA basis to plan for"),
    (("planned", "{basis}", "sobol"), "unknown design 'sobol'; known: nielsen, render, uniform"),
    (("uniform", "{basis}"), "uniform sampling takes no basis and no design"),
])
def test_protocol_refuses(lib, args, message):
    with pytest.raises(InputError) as e:
        SamplingProtocol(*[a.format(basis=lib["basis"]) for a in args])
    assert str(e.value) == message


@pytest.mark.slow
def test_bench_and_eval_sparse_reconstruct_the_same_samples(lib, tmp_path, monkeypatch):
    """Both scripts, as their users run them, on the same materials, N and draws: the
    same samples (digests) and so the same IPCA reconstruction (log RMSE)."""
    no_bench_plots(monkeypatch)  # the records are compared, not the figures
    cfg = BenchConfig(output=str(tmp_path / "bench"), data=str(lib["lib"]), test_list=str(lib["test"]),
                      ipca=str(lib["basis"]), methods=("ipca",), n=(9, 20), seeds=1, first_seed=1,
                      sampling=("uniform", "planned"), plan_design="nielsen", resolution=8, threads=1)
    bench = [r for r in run_bench(cfg, progress=False)["records"] if r["kind"] == "sparse"]
    proc = subprocess.run([sys.executable, EVAL_SPARSE, "--ipca", str(lib["basis"]), "--data", str(lib["lib"]),
                           "--list", str(lib["test"]), "--n", "9", "20", "--seeds", "1",
                           "--sampling", "uniform", "planned", "--plan-design", "nielsen",
                           "--json", str(tmp_path / "eval.json")],
                          capture_output=True, text=True, timeout=300, env=quiet_env(), cwd=REPO)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "ipca (planned)" in proc.stdout
    evals = json.loads((tmp_path / "eval.json").read_text())["records"]
    key = lambda r: (r["material"], r["n"], r["seed"], r["sampling"])  # noqa: E731
    assert len(bench) == len(evals) == 2 * 2 * 2  # materials, N, samplings; one draw, not the first
    assert {r["seed"] for r in bench} == {1}
    assert {key(r) for r in bench} == {key(r) for r in evals}
    by_key = {key(r): r for r in evals}
    for r in bench:
        e = by_key[key(r)]
        assert "error" not in r, r
        assert r["samples_digest"] == e["samples_digest"]
        assert r["log_rmse"] == pytest.approx(e["log_rmse"], rel=1e-12)
        if r["sampling"] == "planned":
            assert r["design"] == e["design"] == "nielsen"
            assert r["plan_seed"] == e["plan_seed"] == r["seed"]
            assert r["condition_number"] == e["condition_number"]
        else:
            assert r["sample_seed"] == e["sample_seed"] == draw_seed(r["seed"], r["n"], r["material"])


@pytest.mark.slow
def test_bench_cli_planned_and_uniform_rows(lib, tmp_path, capsys, monkeypatch):
    """``brdfkit bench --sampling uniform,planned``: a row of each sampling and N, the
    plan's command in bench.md; merged with a uniform run of the same seeds, two samplings,
    not duplicates. In this process (the command line's entry point; what is checked is
    the rows, not a process) without the figures (tests/test_bench.py's end-to-end test
    draws them)."""
    from conftest import run_cli

    no_bench_plots(monkeypatch)  # the records are counted and merged, not the figures
    out = tmp_path / "out"
    args = ["bench", "--data", lib["lib"], "--test-list", lib["test"], "--methods", "ipca",
            "--plan-model", lib["basis"], "--plan-design", "nielsen", "--ipca", lib["basis"], "--n", "9,20", "--seeds",
            "1", "--sampling", "uniform,planned", "--resolution", "8", "--threads", "1", "-o", out]
    args = [str(a) for a in args]
    code, _, err = run_cli(capsys, args)
    assert code == 0, err[-3000:]
    result = json.loads((out / "bench.json").read_text())
    assert result["config"]["sampling"] == ["uniform", "planned"]
    rows = {(r["method"], r["sampling"], r["n"]) for r in result["summary"]["sparse"]}
    assert rows == {("ipca", s, n) for s in ("uniform", "planned") for n in (9, 20)}
    md = (out / "bench.md").read_text()
    assert "| ipca | 9 |" in md and "| ipca (planned) | 9 |" in md
    assert f"`brdfkit plan -n N -m {lib['basis'].name} --design nielsen --seed DRAW`" in md

    # Merging: a planned run and a uniform run of the same seeds are two samplings, not
    # duplicates.
    other = tmp_path / "other"
    args = args[:-1] + [str(other)]
    args[args.index("uniform,planned")] = "uniform"
    args[args.index("--n") + 1] = "9"
    for argv in (args + ["--first-seed", "1"], ["bench", "--merge", str(out), "--merge", str(other),
                                                "-o", str(tmp_path / "merged")]):
        code, _, err = run_cli(capsys, argv)
        assert code == 0, err[-3000:]
    merged = json.loads((tmp_path / "merged" / "bench.json").read_text())
    assert merged["config"]["sampling"] == ["uniform", "planned"]
    assert len(merged["records"]) == 2 * (4 + 1)


@pytest.mark.parametrize("args, message", [
    (["--sampling", "planned"], "--sampling planned needs the PCA basis to plan for: --plan-model NAME|FILE"),
    (["--sampling", "uniform,sobol", "--ipca", "{basis}"], "--sampling: unknown sampling 'sobol'; known: uniform, "
                                                            "planned"),
    (["--sampling", "uniform,uniform", "--ipca", "{basis}"], "--sampling: a sampling is named twice"),
    (["--sampling", "planned", "--ipca", "{basis}", "--plan-design", "sobol"], "--plan-design: unknown design"),
])
def test_bench_sampling_options_refused(lib, tmp_path, capsys, args, message):
    from conftest import one_error_line, run_cli

    code, _, err = run_cli(capsys, ["bench", "--data", lib["lib"], "--methods", "nbrdf",
                                 *[a.format(basis=lib["basis"]) for a in args], "-o", tmp_path / "out"])
    assert code == 2
    assert one_error_line(err).startswith("brdfkit: error: " + message), err
