"""Where and on how many threads torch runs: the one device rule and the thread counts;
and where a process's seconds go (its stages, ``$BRDFKIT_PROFILE``).

Device
------
``None`` or ``"auto"`` picks CUDA when a GPU is present, else the CPU; ``"cpu"``,
``"cuda"`` and ``"cuda:N"`` (or a ``torch.device``) name one. A CUDA device asked for on a
machine without one is refused with a one-line :class:`~brdfkit.errors.InputError`
rather than failing later inside torch (:func:`resolve_device`).

Threads
-------
torch runs its CPU operators on one OpenMP thread per core. When other processes already
keep the cores busy, those threads wait for each other at every operator: on the 2-core
project machine at load average 11, ``brdfkit sparse`` took 57 s wall with torch's two
threads and 9.7 s with one (a dense decode: 11.3 s against 0.64 s;
``docs/notes/performance.md``). :func:`set_default_threads` therefore sizes the OpenMP pool to
the cores that are idle by the 1-minute load average, before torch is imported, unless
the user chose (``OMP_NUM_THREADS``).

The library itself never changes the thread settings it was given: a library function
that needs another thread count for its own work (NBRDF's tiny network runs fastest on
one thread) sets it with :func:`torch_threads` for the duration of the call and restores
it. :func:`set_torch_threads` (``--threads`` of ``brdfkit render`` and ``metrics``, the
benchmark's worker processes) is for the command line and for processes brdfkit starts.

Stages
------
``BRDFKIT_PROFILE=stages.json brdfkit encode ...`` writes, when the process ends, every
second of it from the process's start in a named stage (:func:`stage`,
:class:`StageProfile`): the command's own (``load model``, ``encode/project``, ...) and
each first import (``.../import``). ``benchmarks/encode_decode.py`` adds the fork before
the interpreter and its teardown after, so that the stages sum to the wall time seen from
outside. Without the variable a stage costs an attribute lookup.

torch is imported on first use only.
"""

from __future__ import annotations

import contextlib
import os

from brdfkit.errors import InputError

__all__ = ["resolve_device", "threads_for_load", "idle_cores", "running_others", "set_default_threads",
           "set_torch_threads", "torch_threads", "cpu_threads", "set_cpu_threads", "thread_map", "beside",
           "blas_threads",
           "PROFILE_ENV", "StageProfile", "stage", "start_profile"]

def resolve_device(device=None, *, local_rank: int | None = None):
    """The ``torch.device`` for a device option.

    Parameters
    ----------
    device
        ``None`` / ``"auto"`` (CUDA when available, else CPU), ``"cpu"``, ``"cuda"``,
        ``"cuda:N"``, or a ``torch.device``.
    local_rank
        Under ``torchrun``: this process's local rank, so that a bare ``"cuda"`` (or
        ``"auto"`` on a GPU machine) gives each process its own GPU,
        ``cuda:(local_rank mod GPUs)``.

    Returns
    -------
    torch.device

    Raises
    ------
    InputError
        CUDA asked for without a CUDA device, or a device that is not CPU or CUDA.
    """
    import torch

    name = "auto" if device is None else str(device)
    if name == "auto":
        name = "cuda" if torch.cuda.is_available() else "cpu"
    if name.startswith("cuda"):
        if not torch.cuda.is_available():
            raise InputError(f"device {name!r}: no CUDA device is available (use --device cpu or auto)")
        if name == "cuda" and local_rank is not None:
            name = f"cuda:{local_rank % torch.cuda.device_count()}"
        try:
            return torch.device(name)
        except RuntimeError:
            raise InputError(f"device {name!r}: not a CUDA device name (cuda or cuda:N)") from None
    if name != "cpu":
        raise InputError(f"device {name!r}: use auto, cpu or cuda")
    return torch.device("cpu")


# Any of these set by the user means the thread count is theirs to choose.
USER_VARIABLES = ("OMP_NUM_THREADS", "MKL_NUM_THREADS")


def threads_for_load(cpus: int, load: float) -> int:
    """Threads worth running when ``load`` runnable tasks (the load average) already
    compete for ``cpus`` cores: the idle cores, at least one, at most ``cpus``."""
    return max(1, min(cpus, int(cpus - load + 0.5)))


def _cpus() -> int:
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


def running_others() -> int | None:
    """Tasks runnable right now besides this process (the 4th field of ``/proc/loadavg``,
    ``running/total``, minus one), or ``None`` where there is no such file."""
    try:
        with open("/proc/loadavg") as f:
            running = int(f.read().split()[3].split("/")[0])
    except (OSError, ValueError, IndexError):
        return None
    return max(0, running - 1)


def idle_cores() -> int | None:
    """:func:`threads_for_load` of this machine now; ``None`` without a load average.

    The load is the smaller of the 1-minute load average and the tasks runnable now
    besides this one: the average still counts commands that have finished (a user's
    previous command holds it near 1 for a minute on an idle machine, which made
    ``brdfkit render`` run on one of two idle cores), while a job that keeps a core busy
    shows in both."""
    try:
        load = os.getloadavg()[0]
    except (AttributeError, OSError):
        return None
    now = running_others()
    if now is not None:
        load = min(load, now)
    return threads_for_load(_cpus(), load)


def set_default_threads(environ=None) -> int | None:
    """Set ``OMP_NUM_THREADS`` to :func:`threads_for_load` when that is below the core
    count and the user set no thread variable; call before importing torch.

    Returns
    -------
    int or None
        The thread count chosen, or ``None`` when the user's setting (or a platform
        without a load average) leaves torch's default.
    """
    environ = os.environ if environ is None else environ
    if any(k in environ for k in USER_VARIABLES):
        return None
    n = idle_cores()
    if n is None:
        return None
    if n < _cpus():
        environ["OMP_NUM_THREADS"] = str(n)
    return n


def set_torch_threads(threads: int | None = None) -> int:
    """Set torch's thread count to ``threads``, by default to the idle cores (at least 1,
    at most torch's current count); returns the count set. For the command line
    (``--threads``), processes brdfkit starts, and programs using the library, once at
    their start (``brdfkit.set_torch_threads()``, as ``examples/python_api.py`` does);
    never called by library functions: the thread pool is the program's to choose.

    Measured: on the shared 2-core machine, 2 threads rendered 256 px in 42 s at load 1.8
    and 621 s at load 6.7, 1 thread in 17.5 s and 27.6 s (OpenMP threads wait for busy
    cores at every operation; docs/render.md)."""
    import torch

    if threads is None:
        threads = max(1, min(torch.get_num_threads(), idle_cores() or 1))
    torch.set_num_threads(int(threads))
    return int(threads)


@contextlib.contextmanager
def torch_threads(threads: int | None):
    """Run the block with torch on ``threads`` CPU threads, restoring the count after
    (``None``: leave it as it is)."""
    if threads is None:
        yield
        return
    import torch

    old = torch.get_num_threads()
    torch.set_num_threads(int(threads))
    try:
        yield
    finally:
        torch.set_num_threads(old)


_CPU_THREADS: list = []


def set_cpu_threads(threads: int | None = None) -> int:
    """Set the threads of brdfkit's own NumPy work (the renderer's blocks of pixels,
    :func:`thread_map`) to ``threads``, by default to the idle cores; returns the count.
    For the command line (``--threads``) and programs using the library; imports no
    torch."""
    n = int(threads) if threads is not None else max(1, idle_cores() or _cpus())
    _CPU_THREADS[:] = [max(1, n)]
    return _CPU_THREADS[0]


def cpu_threads() -> int:
    """The threads of brdfkit's own NumPy work: :func:`set_cpu_threads`'s count, else
    ``OMP_NUM_THREADS`` when set (the command line sets it by the machine's load before
    anything runs), else the cores."""
    if _CPU_THREADS:
        return _CPU_THREADS[0]
    try:
        return max(1, int(os.environ["OMP_NUM_THREADS"]))
    except (KeyError, ValueError):
        return _cpus()


def beside(fn, *args, **kwargs):
    """``fn(*args, **kwargs)`` on a thread of its own while the caller goes on, when
    :func:`cpu_threads` allows more than one, else now: a ``Future`` whose ``result()``
    gives its value (or raises its error). For a fixed piece of work independent of what
    the caller does meanwhile: its result is the same either way."""
    import threading
    from concurrent.futures import Future

    fut: Future = Future()

    def run():
        try:
            fut.set_result(fn(*args, **kwargs))
        except BaseException as e:  # raised by result(), in the caller
            fut.set_exception(e)

    if cpu_threads() <= 1:
        run()
    else:
        threading.Thread(target=run, daemon=True, name="brdfkit-beside").start()
    return fut


def thread_map(fn, items, threads: int | None = None):
    """``map(fn, items)`` on :func:`cpu_threads` threads (``threads`` if given), results in
    the order of ``items``: for work that releases the GIL (NumPy on large arrays) and
    whose results do not depend on which thread made them. While more than one thread
    runs, NumPy's BLAS runs on one thread (:func:`blas_threads`): the pieces, not the
    products, share the cores."""
    n = cpu_threads() if threads is None else int(threads)
    items = list(items)
    if n <= 1 or len(items) <= 1:
        yield from map(fn, items)
        return
    from concurrent.futures import ThreadPoolExecutor

    with blas_threads(1), ThreadPoolExecutor(max_workers=min(n, len(items))) as pool:
        yield from pool.map(fn, items)


@contextlib.contextmanager
def blas_threads(threads: int | None):
    """Run the block with NumPy's BLAS on ``threads`` threads, restoring the count after
    (``None``: as it is). What a result that must not depend on the machine's cores runs
    under (an encode's arithmetic: a product split over threads may sum in another order).

    The BLAS is found by :mod:`threadpoolctl`, which knows OpenBLAS, MKL, BLIS and the
    others whatever the NumPy build (every BLAS loaded in the process is set)."""
    if threads is None:
        yield
        return
    with _blas().limit(limits=int(threads)):
        yield


_BLAS: list = []  # [(modules imported then, controller)]


def _blas():
    """threadpoolctl's controller of the BLAS libraries loaded (NumPy's, and any another
    module brought, torch's): found again only after new modules were imported."""
    import sys

    if not _BLAS or _BLAS[0][0] != len(sys.modules):
        import numpy  # noqa: F401  (loads NumPy's BLAS, so that threadpoolctl sees it)
        from threadpoolctl import ThreadpoolController

        _BLAS[:] = [(len(sys.modules), ThreadpoolController().select(user_api="blas"))]
    return _BLAS[0][1]


# --- the stages of a process (BRDFKIT_PROFILE) -----------------------------------------------

PROFILE_ENV = "BRDFKIT_PROFILE"
"""Environment variable: a JSON file that a ``brdfkit`` process writes its stages into
when it ends (:func:`stage`, :func:`start_profile`); unset, the stages cost nothing."""

_PROFILE: list = []  # the running StageProfile, when there is one


class StageProfile:
    """The seconds of a process in named stages, every second in exactly one.

    The process's time is cut at each entry to and exit from a :func:`stage` of the main
    thread, and each piece is charged to the stages open then, joined by ``/`` (the
    innermost a stage's own time; ``main`` outside any). With ``imports`` set, a module
    imported for the first time is a stage of its own, ``import``, under the stage that
    imported it. Wall seconds are ``time.time`` (comparable with another process's
    clock), CPU seconds ``time.process_time`` (every thread of the process: a stage that
    works on two cores shows up to twice its wall time)."""

    def __init__(self, imports: bool = True):
        import threading
        import time

        self._clock, self._cpu, self._main = time.time, time.process_time, threading.main_thread()
        self.started = _process_start()
        self.stack: list = []
        self.totals: dict = {}  # path -> [wall s, cpu s, entries]
        self._t, self._c = self._clock(), self._cpu()
        self.totals["start: interpreter and brdfkit.runtime"] = [
            self._t - self.started if self.started is not None else 0.0, self._c, 1]
        if imports:
            _watch_imports(self)

    def _cut(self) -> None:
        t, c = self._clock(), self._cpu()
        entry = self.totals.setdefault("/".join(self.stack) or "main", [0.0, 0.0, 0])
        entry[0] += t - self._t
        entry[1] += c - self._c
        self._t, self._c = t, c

    def enter(self, name: str) -> bool:
        """Open stage ``name`` (``False``, and nothing done, off the main thread or inside
        a stage of the same name)."""
        import threading

        if threading.current_thread() is not self._main or (self.stack and self.stack[-1] == name):
            return False
        self._cut()
        self.stack.append(name)
        self.totals.setdefault("/".join(self.stack), [0.0, 0.0, 0])[2] += 1
        return True

    def leave(self) -> None:
        """Close the innermost stage."""
        self._cut()
        self.stack.pop()

    def record(self) -> dict:
        """``{"started", "ended", "wall_s", "cpu_s", "stages": [{"stage", "wall_s",
        "cpu_s", "entries"}]}``, the stages in the order first entered; ``started`` the
        process's start (epoch seconds, ``/proc``'s 10 ms ticks; ``None`` elsewhere)."""
        self._cut()
        stages = [{"stage": k, "wall_s": round(v[0], 4), "cpu_s": round(v[1], 4), "entries": v[2]}
                  for k, v in self.totals.items()]
        return {"started": self.started, "ended": self._t, "wall_s": round(sum(v[0] for v in self.totals.values()), 4),
                "cpu_s": round(self._c, 4), "stages": stages}


class _Stage:
    """:func:`stage`'s context manager."""

    __slots__ = ("name", "open")

    def __init__(self, name):
        self.name, self.open = name, False

    def __enter__(self):
        self.open = bool(_PROFILE) and _PROFILE[0].enter(self.name)
        return self

    def __exit__(self, *exc):
        if self.open:
            _PROFILE[0].leave()
        return False


def stage(name: str) -> contextlib.AbstractContextManager:
    """``with stage("project"): ...``: the block's seconds are stage ``name`` of the
    process's profile (:class:`StageProfile`) when one runs (``$BRDFKIT_PROFILE``), else
    nothing at all. Stages nest; one entered off the main thread is part of the stage
    that started the thread."""
    return _Stage(name)


def start_profile(environ=None) -> StageProfile | None:
    """Start the process's profile when ``$BRDFKIT_PROFILE`` names a file (the command
    line calls this first), and write it there, as JSON, when the interpreter exits;
    ``None`` when the variable is unset."""
    import atexit

    environ = os.environ if environ is None else environ
    path = environ.get(PROFILE_ENV)
    if not path or _PROFILE:
        return _PROFILE[0] if _PROFILE else None
    _PROFILE.append(StageProfile())
    atexit.register(_write_profile, path, list(__import__("sys").argv))
    return _PROFILE[0]


def _write_profile(path: str, argv: list) -> None:
    import json

    from brdfkit.atomic import atomic_open

    prof = _PROFILE[0]
    while prof.stack:
        prof.leave()
    with atomic_open(path, "w") as f:
        json.dump({"format": "brdfkit-stages", "argv": argv, **prof.record()}, f, indent=1)


def _process_start() -> float | None:
    """This process's start in epoch seconds (Linux ``/proc``, 10 ms ticks), or ``None``."""
    try:
        with open("/proc/self/stat") as f:
            ticks = int(f.read().rsplit(")", 1)[1].split()[19])
        with open("/proc/stat") as f:
            boot = next(int(line.split()[1]) for line in f if line.startswith("btime"))
        return boot + ticks / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError, StopIteration, AttributeError):
        return None


def _watch_imports(prof: StageProfile) -> None:
    """Charge first imports to a stage ``import`` (profiling only: ``builtins.__import__``
    and ``importlib.import_module`` wrapped)."""
    import builtins
    import importlib
    import sys

    plain, by_name = builtins.__import__, importlib.import_module

    def new(name, fromlist=()):
        if name not in sys.modules:
            return True
        mod = sys.modules[name]
        return any(isinstance(n, str) and n != "*" and not hasattr(mod, n) for n in fromlist or ())

    def imported(name, globals=None, locals=None, fromlist=(), level=0):
        if level or not new(name, fromlist):
            return plain(name, globals, locals, fromlist, level)
        with stage("import"):
            return plain(name, globals, locals, fromlist, level)

    def import_module(name, package=None):
        if name in sys.modules:
            return by_name(name, package)
        with stage("import"):
            return by_name(name, package)

    builtins.__import__, importlib.import_module = imported, import_module
