"""What the test modules share: the one-torch-thread and no-``$BRDFKIT_MODEL`` fixtures,
the tiny model configurations, the good and bad files of the bad-input tests,
``installed`` (a module's ``shelf`` of built-in models in use), the ``brdfkit`` runners
(a subprocess, or in-process with ``run_cli``, or ``run_cli_uncaptured`` in a module
fixture), the checks of one-line errors
(``one_error_line``, ``format_error``), the leftover-file check, and the order in which
the suite's two workers take the files (:data:`HEAVY_FIRST`).

Fixtures apply by name (the two autouse ones to every test); the constants and functions are imported
by name (``from conftest import run_brdfkit, TINY``; pytest puts ``tests/`` on
``sys.path``). Helpers of one group of tests stay in ``helpers_<group>.py``.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

# NumPy's OpenBLAS: one thread in the test processes and the commands they start, set before
# NumPy loads (it reads the variable once). The suite's two workers share 2 cores; with a
# thread pool each, a float32 product of a few rows by a million cells (the Gram matrix of
# ``fit_basis``) spins for tens of seconds instead of taking milliseconds.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

# glibc's malloc: freed memory kept for the next allocation in the suite's worker processes
# and the commands they start (set here, before pytest-xdist starts its workers; glibc
# reads the variables when a process starts). A MERL table (35 MB in float64) is above
# the largest size glibc serves from its heap (32 MiB), so each one was mapped and
# unmapped again and its pages faulted in zeroed: the suite's processes spent 147 s of
# their 822 s of CPU in the kernel. Kept, test_routes_sizes.py's merl80 half takes 30 s
# instead of 41 (sys 4.5 s instead of 13.3; 2026-12-02). Values do not depend on it.
os.environ.setdefault("MALLOC_MMAP_MAX_", "0")
os.environ.setdefault("MALLOC_TRIM_THRESHOLD_", str(4 << 30))

# Hypothesis draws the same examples on every run (the property tests and the fuzzer):
# a result depends on the code, not on the draw; BRDFKIT_FUZZ_RANDOM=1 explores.
try:
    from hypothesis import settings as _hypothesis_settings

    _hypothesis_settings.register_profile("brdfkit", derandomize=not os.environ.get("BRDFKIT_FUZZ_RANDOM"))
    _hypothesis_settings.load_profile("brdfkit")
except ImportError:  # the tests that need it skip without it
    pass

# A hypernetwork small enough that a dense encode or decode takes a fraction of a second
# (a ``HyperConfig``; the model tests save it untrained).
TINY_CONFIG = dict(latent_dim=7, encoder_hidden=(16, 16), hypo_hidden=8, hypo_layers=2,
                   decoder_hidden=16, decoder_layers=1)

# A model small enough to train in seconds on one core (``fit`` options, architecture and
# schedule); every fit in the tests uses it, with latent dimension ``TINY_LATENT``.
TINY = dict(query_size=512, context_min=50, context_max=400, hypo_hidden=32, decoder_hidden=64,
            encoder_hidden=(64, 64), lr=2e-3, warmup_steps=20, lr_schedule="constant")
TINY_LATENT = 8


def tiny_cli_options(latent: bool = True) -> list[str]:
    """``TINY`` as ``brdfkit fit -O KEY=VALUE`` arguments (and ``--latent-dim``)."""
    out = []
    for k, v in TINY.items():
        v = list(v) if isinstance(v, tuple) else v
        out += ["-O", f"{k}={v}".replace(" ", "")]
    return out + (["--latent-dim", str(TINY_LATENT)] if latent else [])


@pytest.fixture(autouse=True, scope="module")
def one_torch_thread():
    """One torch thread per test module: the test machine's 2 cores are shared, and
    oversubscribed OpenMP threads make small matrix products several times slower."""
    import torch

    old = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(old)


@pytest.fixture(scope="session")
def no_builtin_models(tmp_path_factory):
    """An empty built-in models folder."""
    return tmp_path_factory.mktemp("no-builtin-models")


@pytest.fixture(autouse=True)
def no_model_env(monkeypatch, no_builtin_models):
    """No test sees the developer's ``$BRDFKIT_MODEL`` (commands take ``-m`` from it), nor
    the package's built-in models (a default model would answer every "no model given"
    test): ``$BRDFKIT_BUILTIN_MODELS`` names an empty folder. A test that wants either
    sets it."""
    monkeypatch.delenv("BRDFKIT_MODEL", raising=False)
    monkeypatch.setenv("BRDFKIT_BUILTIN_MODELS", str(no_builtin_models))


# --- the order the two workers take the files in -------------------------------------------

HEAVY_FIRST = ("test_batch_bytes.py", "test_view_browser.py", "test_routes_encode.py", "test_routes_sizes.py",
               "test_routes_*.py", "test_demo_real.py",
               "test_reproducible.py", "test_residual.py", "test_baselines.py", "test_shipped_models.py",
               "test_training.py", "test_torch_free.py", "test_prior.py", "test_demo.py", "test_bench.py")
"""The test files (``fnmatch`` patterns) that take longest in the suite's 2-worker run,
longest first (``--durations``): the workers take them first, then the others in their
order. pytest-xdist hands a worker a whole file at a time (``--dist loadfile``); a long file
taken last leaves the other worker idle until it ends, which is most of what a suite of
unequal files loses on 2 cores (``--no-loadscope-reorder`` keeps this order; xdist's own
puts the files with most tests first). A file that takes more than about 15 s goes here."""


def pytest_collection_modifyitems(config, items):
    """The :data:`HEAVY_FIRST` files first (a stable sort: each file's tests stay together
    and in their order, the other files in theirs)."""
    import fnmatch

    def rank(item) -> int:
        name = item.path.name
        return next((i for i, p in enumerate(HEAVY_FIRST) if fnmatch.fnmatch(name, p)), len(HEAVY_FIRST))

    items.sort(key=rank)


# --- the files of the bad-input tests (test_bad_input_*.py, helpers_bad_input.py) -----------

@pytest.fixture(scope="session")
def good(tmp_path_factory):
    """The good files of the bad-input tests: a folder with a tiny model, another model,
    a MERL table, a sample CSV, two embeddings of the model and one of the other."""
    from brdfkit import api
    from brdfkit.io.embedding import write_embedding
    from brdfkit.acquisition.sampling import draw_samples

    from helpers_model import make_model, material_table, write_inputs

    d = tmp_path_factory.mktemp("good")
    make_model(d / "model.safetensors", seed=0)
    make_model(d / "other.safetensors", seed=1)
    write_inputs(d, "samples.csv")
    m = api.load_model(d / "model.safetensors", "cpu")
    write_embedding(d / "a.emb", api.encode(d / "samples.csv", m))
    write_embedding(d / "b.emb", api.encode(draw_samples(material_table(0), 200, seed=0), m, source="w"))
    o = api.load_model(d / "other.safetensors", "cpu")
    write_embedding(d / "other.emb", api.encode(d / "samples.csv", o))
    return d


@pytest.fixture(scope="session")
def bad_merl(good, tmp_path_factory):
    """name -> path of a malformed MERL table (``helpers_bad_input.MERL_MESSAGES``)."""
    from helpers_bad_input import merl_variants

    return merl_variants(tmp_path_factory.mktemp("bad-merl"), (good / "mat.binary").read_bytes())


@pytest.fixture(scope="session")
def bad_models(good, tmp_path_factory):
    """name -> (path of a bad model file, the message after "PATH: ")."""
    from helpers_bad_input import bad_model_files

    return bad_model_files(tmp_path_factory.mktemp("bad-models"), (good / "model.safetensors").read_bytes())


@pytest.fixture(scope="session")
def bad_embs(good, tmp_path_factory):
    """name -> (path of a bad embedding file, its message)."""
    import json

    from helpers_bad_input import bad_embedding_files

    return bad_embedding_files(tmp_path_factory.mktemp("bad-embs"), json.loads((good / "a.emb").read_text()),
                               json.loads((good / "other.emb").read_text()))


@pytest.fixture
def installed(shelf, monkeypatch):
    """The test module's ``shelf`` fixture, ``(folder, inputs)``, with its folder of
    built-in models as ``$BRDFKIT_BUILTIN_MODELS``."""
    from brdfkit.models import builtin

    monkeypatch.setenv(builtin.BUILTIN_ENV, str(shelf[0]))
    return shelf


# --- brdfkit as a user runs it -------------------------------------------------------------

def brdfkit_command() -> list[str]:
    """The installed console script, or the same entry point through ``python -c``."""
    script = Path(sys.executable).with_name("brdfkit")
    if script.exists():
        return [str(script)]
    return [sys.executable, "-c", "import sys; from brdfkit.cli import main; main(sys.argv[1:])"]


def quiet_env() -> dict:
    """Environment for subprocesses: one thread each (the test machine has 2 shared
    cores; oversubscribed OpenMP threads slow tiny models down tenfold)."""
    env = dict(os.environ)
    env["OMP_NUM_THREADS"] = "1"
    env["MKL_NUM_THREADS"] = "1"
    return env


def run_brdfkit(args, cwd=None, timeout=120, env=None) -> subprocess.CompletedProcess:
    """Run ``brdfkit ARGS`` in a subprocess, as a user would; text output captured."""
    return subprocess.run(brdfkit_command() + [str(a) for a in args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=timeout)


def run_cli(capsys, args) -> tuple[int, str, str]:
    """Run ``brdfkit ARGS`` in-process (the console script's entry point, without a
    process's start-up): ``(exit code, stdout, stderr)`` of the command alone."""
    from brdfkit.cli import main

    capsys.readouterr()
    with pytest.raises(SystemExit) as e:
        main([str(a) for a in args])
    out = capsys.readouterr()
    return e.value.code, out.out, out.err


def run_here(capsys, args):
    """``run_cli`` as the fields of a finished process (``returncode``, ``stdout``,
    ``stderr``), for tests written against ``run_brdfkit`` whose process is not what they
    check."""
    import types

    code, out, err = run_cli(capsys, args)
    return types.SimpleNamespace(returncode=code, stdout=out, stderr=err)


def run_cli_uncaptured(args) -> tuple[int, str]:
    """Run ``brdfkit ARGS`` in-process where no ``capsys`` is at hand (a module fixture
    building its inputs with the commands): ``(exit code, stderr)``."""
    import contextlib
    import io

    from brdfkit.cli import main

    err = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        try:
            main([str(a) for a in args])
        except SystemExit as e:
            return e.code, err.getvalue()
    return 0, err.getvalue()


def no_bench_plots(monkeypatch) -> list:
    """``brdfkit bench`` (``run_bench``, ``merge_results``) in this process from now on
    without its matplotlib figures (about 3 s a run; tests/test_bench.py's end-to-end test
    checks them): the folders they would have gone to, in turn."""
    import brdfkit.bench.runner

    folders = []
    monkeypatch.setattr(brdfkit.bench.runner, "write_plots", lambda folder, result: folders.append(folder) or [])
    return folders


def one_error_line(err: str) -> str:
    """The one line of ``err``, a ``brdfkit: error: ...`` (bad input is one line, never
    a traceback)."""
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("brdfkit: error: ") and "Traceback" not in err, err
    return lines[0]


def format_error(read, path, match: str | None = None, content: bytes | None = None) -> str:
    """The message of the :class:`brdfkit.errors.FormatError` that ``read(path)`` raises
    (matching ``match``), checked to name ``path`` on one line; ``content``: the bytes
    written to ``path`` first."""
    from brdfkit.errors import FormatError

    if content is not None:
        path.write_bytes(content)
    with pytest.raises(FormatError, match=match) as e:
        read(path)
    message = str(e.value)
    assert str(path) in message and "\n" not in message, message
    return message


def popen_brdfkit(args, **kw) -> subprocess.Popen:
    """Start ``brdfkit ARGS`` as a user would (own process, one thread, text output
    captured)."""
    return subprocess.Popen(brdfkit_command() + [str(a) for a in args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=quiet_env(), **kw)


def tmp_leftovers(folder) -> list[str]:
    """Temporary files of :mod:`brdfkit.atomic` left in ``folder``."""
    return sorted(n for n in os.listdir(folder) if n.startswith(".brdfkit-tmp-"))
