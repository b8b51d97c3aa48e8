"""What a new user meets (issue 13, "Found"): each test failed before its fix.

A green test run without libLLVM 19, LLVM advice that names what works, the library's
thread pool, cheap output checks before heavy work, output modes that follow the umask,
messages in the CLI's own words, no progress noise in pipes, and a demo that writes its
image.
"""

from __future__ import annotations

import os
import stat
import subprocess
import sys
import types
from pathlib import Path

import numpy as np
import pytest

from conftest import brdfkit_command, quiet_env, run_cli, run_cli_uncaptured, run_here

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def library(tmp_path_factory):
    """Two small synthetic MERL tables (``brdfkit synth``)."""
    folder = tmp_path_factory.mktemp("lib")
    code, err = run_cli_uncaptured(["synth", folder, "-n", "2", "--no-stiff"])
    assert code == 0, err
    return folder


# --- 5. cheap checks before work ----------------------------------------------------------

@pytest.mark.parametrize("argv", [
    ["render", "{missing}.binary", "-o", "/nonexistent/x.exr"],
    ["render", "{missing}.binary", "-o", "{tmp}/x.exr", "--png", "/nonexistent/x.png"],
    ["sparse", "{missing}.csv", "-m", "{missing}.safetensors", "-o", "/nonexistent/x.binary"],
    ["sparse", "{missing}.csv", "-m", "{missing}.safetensors", "-o", "{tmp}/x.binary",
     "--emb", "/nonexistent/x.emb"],
    ["decode", "{missing}.emb", "-m", "{missing}.safetensors", "-o", "/nonexistent/x.binary"],
    ["interpolate", "{missing}.emb", "{missing}2.emb", "--t", "0.5", "-o", "/nonexistent/x.emb"],
    ["sample", "{missing}.binary", "-n", "40", "-o", "/nonexistent/x.csv"],
    ["fit", "{missing}", "-o", "/nonexistent/model.safetensors"],
])
def test_a_bad_output_path_fails_before_any_input_is_read(tmp_path, argv, capsys):
    """The output is checked first: with a missing input too, the error names the
    output folder, so nothing (table, model, render) was read or computed before (in this
    process: the command's checks, not a process, are what is tested)."""
    args = [a.format(missing=tmp_path / "missing", tmp=tmp_path) for a in argv]
    r = run_here(capsys, args)
    assert r.returncode == 2, r.stderr
    assert "/nonexistent" in r.stderr and "does not exist" in r.stderr, r.stderr
    assert r.stderr.count("\n") == 1 and "Traceback" not in r.stderr


def test_an_output_that_is_a_folder_fails_first(tmp_path, capsys):
    r = run_here(capsys, ["sparse", tmp_path / "missing.csv", "-m", tmp_path / "m.safetensors",
                          "-o", tmp_path])
    assert r.returncode == 2 and "is a directory" in r.stderr, r.stderr


# --- 6. model files follow the umask ------------------------------------------------------

@pytest.fixture
def umask_022():
    old = os.umask(0o022)
    yield
    os.umask(old)


def _mode(path) -> int:
    return stat.S_IMODE(os.stat(path).st_mode)


def test_atomic_output_replaced_by_its_writer_keeps_the_umask_mode(tmp_path, umask_022):
    """A writer that replaces the temporary file with a private one (as safetensors does)."""
    from brdfkit.atomic import atomic_path

    with atomic_path(tmp_path / "out.bin") as tmp:
        os.unlink(tmp)
        os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600))
    assert _mode(tmp_path / "out.bin") == 0o644


def test_reference_tables_are_0644_under_umask_022(tmp_path, umask_022):
    from brdfkit.hypernet.mapping import save_reference

    save_reference(tmp_path / "ref.safetensors", np.ones((90, 90, 180, 3)))
    assert _mode(tmp_path / "ref.safetensors") == 0o644


@pytest.mark.slow
def test_fit_writes_its_model_file_0644_under_umask_022(tmp_path, library, umask_022, capsys):
    """``brdfkit fit --method basis`` (seconds; the hypernet's network file goes through the
    same writer, ``safetensors`` into :func:`brdfkit.atomic.atomic_path`), in this process
    under its umask."""
    r = run_here(capsys, ["fit", library, "--method", "basis", "--components", "2",
                          "-o", tmp_path / "basis.safetensors", "--quiet"])
    assert r.returncode == 0, r.stderr
    assert _mode(tmp_path / "basis.safetensors") == 0o644


# --- 1, 2. no libLLVM 19: Mitsuba tests skip; the advice names what works ----------------

@pytest.mark.slow
@pytest.mark.parametrize("env", [{"DRJIT_LIBLLVM_PATH": "/nonexistent/libLLVM.so.19.1"},
                                 {"BRDFKIT_LIBLLVM_SEARCH": ""}], ids=["bad-path", "none-found"])
def test_mitsuba_tests_skip_with_the_reason_without_libllvm(env):
    """The README's test command on a machine without libLLVM 19: every Mitsuba test
    skips (saying why), none fails. ``BRDFKIT_LIBLLVM_SEARCH=""`` searches nowhere."""
    environ = {k: v for k, v in os.environ.items() if k != "DRJIT_LIBLLVM_PATH"}
    environ.update(env, OMP_NUM_THREADS="1")
    r = subprocess.run([sys.executable, "-m", "pytest", "-q", "-rs", "-p", "no:cacheprovider", "-n", "0",
                        "tests/test_stability.py::test_mitsuba_render_of_the_mirror",
                        "tests/test_mitsuba_plugin.py"],
                       cwd=REPO, env=environ, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stdout[-3000:]
    assert "failed" not in r.stdout and " skipped" in r.stdout, r.stdout[-3000:]
    assert "apt-get install -y libllvm19" in r.stdout, r.stdout[-3000:]


def test_llvm_advice_names_19_and_refuses_14_and_15(tmp_path, monkeypatch):
    from brdfkit.errors import BrdfkitError
    from brdfkit.render.mitsuba3 import loader as mp

    for name in ("libLLVM-15.so.1", "libLLVM-14.so"):
        lib = tmp_path / name
        lib.write_bytes(b"")
        monkeypatch.setenv("DRJIT_LIBLLVM_PATH", str(lib))
        with pytest.raises(BrdfkitError) as e:
            mp.ensure_libllvm()
        assert "libllvm19" in str(e.value) and "15 or later" not in str(e.value)
    assert mp.libllvm_version("/usr/lib/llvm-14/lib/libLLVM.so") == 14
    assert mp.libllvm_version("/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1") == 19
    assert mp.libllvm_version("/usr/lib/x86_64-linux-gnu/libLLVM-15.so.1") == 15


def test_llvm_auto_detection_picks_only_19(monkeypatch):
    from brdfkit.errors import BrdfkitError
    from brdfkit.render.mitsuba3 import loader as mp

    assert all("19" in p for p in mp.LIBLLVM_CANDIDATES + mp.LIBLLVM_PATTERNS)
    monkeypatch.delenv("DRJIT_LIBLLVM_PATH", raising=False)
    monkeypatch.delenv("BRDFKIT_LIBLLVM_SEARCH", raising=False)
    try:
        path = mp.ensure_libllvm()
    except BrdfkitError as e:
        pytest.skip(f"no libLLVM 19 here: {e}")
    assert mp.libllvm_version(path) == 19


# --- 7. the CLI's own words, clean temporary folders, quiet pipes, the demo's image -------

def test_interpolate_outside_0_1_names_the_cli_flag(tmp_path, capsys):
    r = run_here(capsys, ["interpolate", tmp_path / "a.emb", tmp_path / "b.emb", "--t", "1.5",
                          "-o", tmp_path / "c.emb"])
    assert r.returncode == 2
    assert "--allow-extrapolation" in r.stderr and "allow_extrapolation=" not in r.stderr, r.stderr


@pytest.mark.slow
def test_fuzz_seeds_leave_nothing_in_the_temporary_folder(tmp_path):
    """The fuzz tests' valid seed files (a model, a reference table, ...) are built in the
    temporary folder and removed once read."""
    pytest.importorskip("hypothesis")
    code = ("from brdfkit.testing import fuzzing\n"
            "for p in fuzzing.PARSERS.values(): p.seed()\n")
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    env = {**os.environ, "TMPDIR": str(tmp), "OMP_NUM_THREADS": "1"}
    r = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    assert os.listdir(tmp) == []


@pytest.mark.slow
def test_piped_metrics_output_starts_with_the_table(library):
    """stdout and stderr into one pipe: no blank lines where progress bars were."""
    a, b = sorted(library.glob("*.binary"))
    r = subprocess.run(brdfkit_command() + ["metrics", "--ref", str(b), str(a), "--resolution", "16"],
                       env=quiet_env(), stdout=subprocess.PIPE,
                       stderr=subprocess.STDOUT, text=True, timeout=300)
    assert r.returncode == 0, r.stdout
    assert r.stdout.splitlines()[0].strip(), repr(r.stdout[:200])
    assert "\x1b[" not in r.stdout


# --- 4. where data comes from -------------------------------------------------------------

def _csv_blocks(text: str) -> list[str]:
    import re

    return re.findall(r"```csv\n(.*?)```", text, re.S)


@pytest.mark.parametrize("doc", ["README.md", "docs/data.md"])
def test_your_data_example_csv_is_a_valid_sample_set(doc, tmp_path):
    from brdfkit.io.samples import read_samples

    blocks = _csv_blocks((REPO / doc).read_text())
    assert blocks, f"{doc}: no sample CSV example"
    for i, block in enumerate(blocks):
        path = tmp_path / f"{i}.csv"
        path.write_text(block)
        s = read_samples(path)
        assert len(s) >= 4


def test_help_and_docs_do_not_send_users_to_a_folder_beside_the_checkout(capsys):
    """``../shared`` exists only beside the development checkout: help texts and docs
    speak of the reference proxies and ``merl-test.txt`` (``docs/data.md`` gives the
    command that makes the proxies; ``docs/notes/results.md`` records the runs as made)."""
    for cmd in ("fit", "bench"):
        code, out, _ = run_cli(capsys, [cmd, "--help"])
        r = types.SimpleNamespace(returncode=code, stdout=out)
        assert r.returncode == 0 and "../shared" not in r.stdout, (cmd, r.stdout)
    allowed = {"data.md", "results.md"}
    for doc in [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]:
        if doc.name in allowed:
            continue
        text = doc.read_text()
        assert "../shared" not in text.replace("python ../shared/tools/nbrdf_to_merl.py", ""), doc
    assert "## Your data" in (REPO / "README.md").read_text()


# --- 3. the library's thread pool ---------------------------------------------------------

@pytest.mark.slow
def test_library_offers_the_clis_thread_choice_and_the_example_uses_it():
    """``brdfkit.set_torch_threads()``: the idle cores, as the command line chooses;
    available without importing torch until called."""
    code = ("import sys, brdfkit\n"
            "f = brdfkit.set_torch_threads\n"
            "assert 'torch' not in sys.modules\n"
            "import torch\n"
            "n = f()\n"
            "assert n == torch.get_num_threads() and 1 <= n <= (__import__('os').cpu_count() or 1), n\n"
            "assert f(1) == 1 == torch.get_num_threads()\n")
    env = {k: v for k, v in os.environ.items() if k not in ("OMP_NUM_THREADS", "MKL_NUM_THREADS")}
    r = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    example = (REPO / "examples" / "python_api.py").read_text()
    assert "brdfkit.set_torch_threads()" in example
    assert example.index("brdfkit.set_torch_threads()") < example.index("brdfkit.load_model(")


def test_demo_render_writes_its_images(tmp_path):
    """The demo's rendered reconstruction and material are written (PNG and EXR), not
    only scored."""
    pytest.importorskip("torch")
    from PIL import Image

    from brdfkit.demos.synthetic_training import render_psnr
    from brdfkit.render.image import read_exr
    from brdfkit.materials.synthetic import STIFF, table

    white = table(STIFF[2])
    save = (str(tmp_path / "white-half"), str(tmp_path / "white"))
    value = render_psnr(resolution=12)(white * 0.5, white, save=save)
    assert 0 < value < 30
    for prefix in save:
        assert read_exr(prefix + ".exr").shape == (12, 12, 3)
        with Image.open(prefix + ".png") as im:
            assert im.format == "PNG" and im.size == (12, 12)
    assert read_exr(save[0] + ".exr").sum() < read_exr(save[1] + ".exr").sum()
