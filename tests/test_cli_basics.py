"""The command line and atomic outputs: fast help, no heavy imports, synth, sample,
interrupted writes."""

from __future__ import annotations

import hashlib
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from brdfkit.atomic import atomic_open, atomic_path, refuse_overwrite_of_inputs
from brdfkit.errors import InputError
from brdfkit.io.merl import is_merl_file, read_merl, write_merl
from brdfkit.io.samples import read_samples
from brdfkit.acquisition.sampling import draw_samples
from brdfkit.materials.synthetic import STIFF, library, table

from conftest import brdfkit_command, run_brdfkit, tmp_leftovers
from helpers_foundation import measured_mask, random_table

HEAVY = ("torch", "mitsuba", "drjit", "colour")


def _python(code: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)


@pytest.fixture(scope="module")
def merl_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("cli") / "material.binary"
    write_merl(path, random_table(seed=21))
    return path


def test_help_lists_commands_quickly():
    run_brdfkit(["--help"])  # warm the file cache
    start = time.perf_counter()
    res = run_brdfkit(["--help"])
    wall = time.perf_counter() - start
    assert res.returncode == 0 and res.stderr == ""
    assert wall < 2.0, f"brdfkit --help took {wall:.2f} s"
    from brdfkit.cli import COMMANDS, cli
    listed = [line.split()[0] for line in res.stdout.split("Commands:")[1].splitlines() if line.strip()]
    assert "sample" in listed and "synth" in listed
    assert listed == cli.list_commands(None) and set(listed) <= set(COMMANDS)


def test_help_says_what_the_demo_runs():
    # `brdfkit demo` runs real materials through the built-in models; only --train is synthetic.
    res = run_brdfkit(["--help"], env={**os.environ, "COLUMNS": "80"})  # one row a command
    rows = {line.split()[0]: " ".join(line.split()[1:])
            for line in res.stdout.split("Commands:")[1].splitlines() if line.strip()}
    assert "real materials" in rows["demo"] and "--train: synthetic" in rows["demo"], rows["demo"]
    assert "synthetic data" not in rows["demo"]


def test_help_imports_no_heavy_module():
    res = _python("import sys\nimport brdfkit.cli\n"
                  "try:\n    brdfkit.cli.main(['--help'])\nexcept SystemExit:\n    pass\n"
                  f"print(sorted(m for m in {HEAVY!r} if m in sys.modules))")
    assert res.returncode == 0, res.stderr
    assert res.stdout.strip().splitlines()[-1] == "[]"


def test_import_brdfkit_imports_no_heavy_module():
    res = _python("import sys, brdfkit\n"
                  "from brdfkit import read_merl, write_merl, read_samples, draw_samples, to_mapped\n"
                  "brdfkit.geometry, brdfkit.synthetic, brdfkit.mapping\n"
                  f"print(sorted(m for m in {HEAVY!r} if m in sys.modules))")
    assert res.returncode == 0, res.stderr
    assert res.stdout.strip() == "[]"


def test_importtime_shows_no_torch():
    res = subprocess.run([sys.executable, "-X", "importtime", "-c", "import brdfkit.cli"],
                         capture_output=True, text=True, timeout=60)
    imported = {line.split("|")[-1].strip().split(".")[0] for line in res.stderr.splitlines() if "|" in line}
    assert "click" in imported and not imported & set(HEAVY)


def test_version():
    res = run_brdfkit(["--version"])
    assert res.returncode == 0 and "0.1.0" in res.stdout


def test_unknown_command():
    res = run_brdfkit(["frobnicate"])
    assert res.returncode == 2 and "Traceback" not in res.stderr


# --- synth -----------------------------------------------------------------------------

@pytest.mark.slow
def test_synth_writes_valid_files(tmp_path):
    out = tmp_path / "lib"
    res = run_brdfkit(["synth", out, "-n", "5"])
    assert res.returncode == 0, res.stderr
    names = sorted(os.listdir(out))
    expected = sorted(m.name + ".binary" for m in library(5))
    assert names == expected
    for name in names:
        path = out / name
        assert is_merl_file(path) and oct(path.stat().st_mode & 0o777) == oct(0o666 & ~_umask())
        t = read_merl(path)
        np.testing.assert_array_equal(np.isnan(t).any(-1), ~measured_mask())
        assert np.nanmin(t) >= 0
    # the file is the documented material, not just any valid table
    white = table(STIFF[2])
    np.testing.assert_allclose(read_merl(out / "stiff-white.binary"), white, rtol=1e-15, equal_nan=True)


def _umask():
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def test_synth_refuses_a_file_as_folder(tmp_path):
    f = tmp_path / "file"
    f.write_text("x")
    res = run_brdfkit(["synth", f, "-n", "1"])
    assert res.returncode == 2 and str(f) in res.stderr and "Traceback" not in res.stderr


# --- sample ----------------------------------------------------------------------------

@pytest.mark.slow
def test_sample_happy_path(merl_file, tmp_path):
    out = tmp_path / "s.csv"
    res = run_brdfkit(["sample", merl_file, "-n", "200", "--seed", "9", "-o", out])
    assert res.returncode == 0, res.stderr
    assert res.stdout == ""  # messages go to stderr
    got = read_samples(out)
    want = draw_samples(read_merl(merl_file), 200, seed=9)
    np.testing.assert_array_equal(got.rgb, want.rgb)
    np.testing.assert_array_equal(got.theta_h, want.theta_h)
    assert not tmp_leftovers(tmp_path)
    res = run_brdfkit(["sample", merl_file, "-n", "200", "--seed", "9", "--distribution", "cells",
                       "-o", tmp_path / "c.csv"])
    assert res.returncode == 0 and len(read_samples(tmp_path / "c.csv")) == 200


def test_sample_refuses_output_equal_to_input(merl_file, tmp_path):
    digest = hashlib.sha256(merl_file.read_bytes()).hexdigest()
    link = tmp_path / "link.binary"
    link.symlink_to(merl_file)
    for output in (merl_file, link):
        res = run_brdfkit(["sample", merl_file, "-n", "3", "-o", output])
        assert res.returncode == 2
        lines = res.stderr.strip().splitlines()
        assert len(lines) == 1 and "output path is also an input" in lines[0]
    assert hashlib.sha256(merl_file.read_bytes()).hexdigest() == digest


@pytest.mark.parametrize("args, pattern", [
    (["-n", "3", "-o", "/nonexistent-folder/x.csv"], "output folder"),
    (["-n", "0", "-o", "x.csv"], "Invalid value"),
    (["-n", "3"], "Missing option"),
])
def test_sample_bad_options(merl_file, tmp_path, args, pattern):
    res = run_brdfkit(["sample", merl_file] + args, cwd=tmp_path)
    assert res.returncode == 2 and pattern in res.stderr and "Traceback" not in res.stderr
    assert not (tmp_path / "x.csv").exists()


# --- atomic outputs --------------------------------------------------------------------

def test_atomic_path_error_leaves_nothing(tmp_path):
    target = tmp_path / "out.bin"
    with pytest.raises(RuntimeError):
        with atomic_path(target) as tmp:
            with open(tmp, "wb") as f:
                f.write(b"half")
            raise RuntimeError("crash while writing")
    assert not target.exists() and not tmp_leftovers(tmp_path)


def test_atomic_keyboard_interrupt_keeps_old_content(tmp_path):
    target = tmp_path / "out.txt"
    target.write_text("old")
    with pytest.raises(KeyboardInterrupt):
        with atomic_open(target) as f:
            f.write("new, half written")
            raise KeyboardInterrupt
    assert target.read_text() == "old" and not tmp_leftovers(tmp_path)


def test_atomic_success_and_permissions(tmp_path):
    target = tmp_path / "out.txt"
    with atomic_open(target) as f:
        f.write("done")
    assert target.read_text() == "done" and not tmp_leftovers(tmp_path)
    assert target.stat().st_mode & 0o777 == 0o666 & ~_umask()


def test_an_output_its_reader_refuses_is_not_written(tmp_path):
    """``verify``: the writer's own format reader reads the finished temporary file before
    it takes its name; a refusal leaves the old content and no temporary file."""
    from brdfkit.atomic import UnreadableOutput
    from brdfkit.io.merl import read_merl

    target = tmp_path / "t.binary"
    target.write_bytes(b"old")
    with pytest.raises(UnreadableOutput) as e:
        with atomic_open(target, "wb", verify=read_merl) as f:
            f.write(b"\x00" * 16)  # not a MERL table
    line = str(e.value)
    assert "\n" not in line and line.startswith(f"{target}: not written") and ".brdfkit-tmp-" not in line
    assert target.read_bytes() == b"old" and not tmp_leftovers(tmp_path)
    seen = []
    with atomic_open(tmp_path / "ok.txt", verify=lambda p: seen.append(open(p).read())) as f:
        f.write("complete")
    assert seen == ["complete"]


def test_atomic_refusals(tmp_path):
    with pytest.raises(InputError, match="does not exist"):
        with atomic_path(tmp_path / "no" / "x"):
            pass
    with pytest.raises(InputError, match="is a directory"):
        with atomic_path(tmp_path):
            pass
    with pytest.raises(ValueError):
        with atomic_open(tmp_path / "x", "a"):
            pass
    src = tmp_path / "in.csv"
    src.write_text("x")
    with pytest.raises(InputError, match="also an input"):
        refuse_overwrite_of_inputs(str(tmp_path / "." / "in.csv"), [src])
    refuse_overwrite_of_inputs(None, [src])
    refuse_overwrite_of_inputs(tmp_path / "other.csv", [src, None])


@pytest.mark.slow
def test_ctrl_c_during_write_leaves_no_temp_file(tmp_path):
    # A real SIGINT to a real `brdfkit synth`, sent as soon as its first temporary output
    # file appears (while the 35 MB table is being written).
    out = tmp_path / "lib"
    out.mkdir()
    proc = subprocess.Popen(brdfkit_command() + ["synth", str(out), "-n", "3", "--no-stiff"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 60
    seen_tmp = False
    while proc.poll() is None and time.monotonic() < deadline:
        if tmp_leftovers(out):
            seen_tmp = True
            proc.send_signal(signal.SIGINT)
            break
        time.sleep(0.0005)
    else:
        proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert not tmp_leftovers(out)
    if proc.returncode == 0:
        pytest.skip("synth finished before the interrupt arrived")
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "brdfkit: error: interrupted" in err
    assert [ln for ln in err.splitlines() if ln.strip()][-1] == "brdfkit: error: interrupted"
    # whatever was completed is whole; nothing half-written under the final name
    for name in os.listdir(out):
        assert is_merl_file(out / name)
    assert seen_tmp, "no temporary file seen: the interrupt did not land during a write"


def test_library_imports_nothing_from_the_cli():
    # Data flows one way: the command line imports the library, never the reverse.
    import re

    root = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "brdfkit")
    pattern = re.compile(r"^\s*(from\s+(brdfkit\.cli|\.+cli)\b|import\s+brdfkit\.cli\b)", re.M)
    offenders = []
    for folder, _, files in os.walk(root):
        if os.path.relpath(folder, root).split(os.sep)[0] == "cli":
            continue
        offenders += [os.path.join(folder, f) for f in files
                      if f.endswith(".py") and pattern.search(open(os.path.join(folder, f)).read())]
    assert offenders == []
