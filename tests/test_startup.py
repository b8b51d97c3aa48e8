"""Start-up (issue 14 item 4): the commands that do not need torch never import it.

Each command runs as a user runs it, in a fresh process, through ``brdfkit.cli.main``; the
process then prints which of the heavy modules it imported. ``plot`` of tables is checked
in ``tests/test_plot.py``, ``import brdfkit`` and ``brdfkit --help`` in
``tests/test_cli_basics.py``. A process run with ``$BRDFKIT_PROFILE`` writes where its
seconds went, every one of them in a named stage.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

HEAVY = ("torch", "mitsuba", "drjit", "colour", "matplotlib", "safetensors")

# Runs ``main(argv)`` for each argv of a JSON list in one process (a command's --help
# exits, so SystemExit is caught) and prints the heavy modules imported after each.
RUNNER = """
import json, sys
from brdfkit.cli import main
out = []
for argv in json.loads(sys.argv[1]):
    try:
        main(argv)
    except SystemExit as e:
        code = e.code or 0
    else:
        code = 0
    out.append([code, sorted(m for m in HEAVY if m in sys.modules)])
print("RESULT " + json.dumps(out))
"""


def _run(*argvs, cwd=None):
    """Run the argvs in one fresh process: ``[(exit code, heavy modules so far), ...]``."""
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    code = f"HEAVY = {HEAVY!r}\n" + RUNNER
    r = subprocess.run([sys.executable, "-c", code, json.dumps([list(map(str, a)) for a in argvs])],
                       cwd=cwd, env=env, capture_output=True, text=True, timeout=300)
    lines = [line for line in r.stdout.splitlines() if line.startswith("RESULT ")]
    assert r.returncode == 0 and lines, r.stderr[-2000:]
    return [tuple(x) for x in json.loads(lines[-1][len("RESULT "):])]


def test_every_commands_help_imports_nothing_heavy():
    from brdfkit.cli import COMMANDS

    results = _run(*[[name, "--help"] for name in COMMANDS], ["material", "--list"])
    for name, (code, heavy) in zip([f"{n} --help" for n in COMMANDS] + ["material --list"], results):
        assert code == 0, name
        assert heavy == [], f"brdfkit {name} imported {heavy}"


@pytest.mark.slow
def test_synth_and_sample_of_a_table_import_no_torch(tmp_path):
    lib = tmp_path / "lib"
    (synth, _), (sample, heavy) = _run(["synth", lib, "-n", "1", "--no-stiff"],
                                       ["sample", lib / "synth-000.binary", "-n", "50", "-o", tmp_path / "s.csv"])
    assert synth == 0 and sample == 0
    assert (tmp_path / "s.csv").is_file()
    assert heavy == []


def test_interpolate_without_binary_imports_no_torch(good, tmp_path):
    out = tmp_path / "mix.emb"
    [(code, heavy)] = _run(["interpolate", good / "a.emb", good / "b.emb", "-t", "0.25", "-o", out])
    assert code == 0 and out.is_file()
    assert heavy == []


@pytest.mark.slow
def test_metrics_of_two_images_imports_no_torch(tmp_path):
    """Two EXRs need no render, so no torch nor Mitsuba (Delta E is colour-science's)."""
    from brdfkit.render.image import write_exr

    rng = np.random.default_rng(0)
    write_exr(tmp_path / "a.exr", rng.uniform(0, 1, (16, 16, 3)).astype(np.float32))
    write_exr(tmp_path / "b.exr", rng.uniform(0, 1, (16, 16, 3)).astype(np.float32))
    [(code, heavy)] = _run(["metrics", "--ref", tmp_path / "b.exr", tmp_path / "a.exr", "--json"])
    assert code == 0
    assert "torch" not in heavy and "mitsuba" not in heavy


@pytest.mark.slow
def test_compare_sheet_of_images_imports_no_torch(tmp_path):
    from brdfkit.render.image import write_exr

    rng = np.random.default_rng(1)
    for name in ("ref", "a", "b"):
        write_exr(tmp_path / f"{name}.exr", rng.uniform(0, 1, (16, 16, 3)).astype(np.float32))
    [(code, heavy)] = _run(["compare", tmp_path / "ref.exr", tmp_path / "a.exr", tmp_path / "b.exr",
                            "-o", tmp_path / "sheet.png", "--json"])
    assert code == 0 and (tmp_path / "sheet.png").is_file()
    assert "torch" not in heavy and "mitsuba" not in heavy


@pytest.mark.slow
def test_commands_that_run_the_network_do_import_torch(good, tmp_path):
    """The probe itself: a command that needs torch is seen importing it."""
    [(code, heavy)] = _run(["encode", good / "samples.csv", "-m", good / "model.safetensors",
                            "-o", tmp_path / "s.emb"])
    assert code == 0 and "torch" in heavy


@pytest.mark.slow
def test_a_profiled_encode_accounts_for_every_second_in_named_stages(tmp_path):
    """``$BRDFKIT_PROFILE``: a whole ``brdfkit encode`` process writes its stages, which tile
    its time from the process's start to its end (nothing twice, nothing left out), the
    command's own stages and first imports among them."""
    from brdfkit.io.merl import write_merl
    from brdfkit.testing.examples import lambertian_table, tiny_basis_file

    from conftest import brdfkit_command, quiet_env

    write_merl(tmp_path / "t.binary", lambertian_table())
    basis = tiny_basis_file(tmp_path / "basis.safetensors")
    env = {**quiet_env(), "BRDFKIT_PROFILE": str(tmp_path / "stages.json")}
    r = subprocess.run([*brdfkit_command(), "encode", "t.binary", "-m", str(basis), "--size", "6", "--steps", "1"],
                       cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    rec = json.loads((tmp_path / "stages.json").read_text())
    names = [s["stage"] for s in rec["stages"]]
    for want in ("load model", "read table (waiting for the reader)", "encode", "encode/project", "encode/refine",
                 "write embedding", "import"):
        assert want in names, names
    assert names[0].startswith("start") and len(set(names)) == len(names)
    assert abs(sum(s["wall_s"] for s in rec["stages"]) - rec["wall_s"]) < 1e-3
    if rec["started"] is not None:  # the process's start (10 ms ticks) to its end, all of it in the stages
        assert abs(rec["ended"] - rec["started"] - rec["wall_s"]) < 0.02
    assert all(s["wall_s"] >= 0 and s["cpu_s"] >= 0 for s in rec["stages"])


def test_stages_nest_and_tile_the_time():
    """Each piece of time is charged once, to the stages open then; a stage entered off the
    main thread is part of the one that started the thread; without ``$BRDFKIT_PROFILE``
    no profile runs and a stage does nothing."""
    import threading
    import time

    from brdfkit import runtime

    prof = runtime.StageProfile(imports=False)
    runtime._PROFILE.append(prof)
    try:
        with runtime.stage("a"):
            time.sleep(0.02)
            with runtime.stage("b"):
                time.sleep(0.03)
                t = threading.Thread(target=lambda: runtime.stage("c").__enter__())
                t.start()
                t.join()
        time.sleep(0.01)
    finally:
        runtime._PROFILE.clear()
    rec = prof.record()
    got = {s["stage"]: s["wall_s"] for s in rec["stages"]}
    assert set(got) == {rec["stages"][0]["stage"], "a", "a/b", "main"}
    assert got["a"] >= 0.02 and got["a/b"] >= 0.03 and got["main"] >= 0.01
    assert abs(sum(got.values()) - rec["wall_s"]) < 1e-3
    assert runtime.start_profile({}) is None and not runtime._PROFILE
    with runtime.stage("nothing") as st:
        assert not st.open
