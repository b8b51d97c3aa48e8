"""How many threads the command line lets torch use on a shared machine.

torch runs its CPU operators on one OpenMP thread per core. When other processes already
keep the cores busy, those threads wait for each other at every operator: on the 2-core
project machine at load average 11, ``brdfkit sparse`` took 57 s wall with torch's two
threads and 9.7 s with one (a dense decode: 11.3 s against 0.64 s;
``docs/performance.md``). :func:`set_default_threads` therefore sizes the OpenMP pool to
the cores that are idle by the 1-minute load average, before torch is imported, unless
the user chose (``OMP_NUM_THREADS``). The library itself never changes thread settings.
"""

from __future__ import annotations

import os

__all__ = ["threads_for_load", "set_default_threads"]

# Any of these set by the user means the thread count is theirs to choose.
USER_VARIABLES = ("OMP_NUM_THREADS", "MKL_NUM_THREADS")


def threads_for_load(cpus: int, load: float) -> int:
    """Threads worth running when ``load`` runnable tasks (the load average) already
    compete for ``cpus`` cores: the idle cores, at least one, at most ``cpus``."""
    return max(1, min(cpus, int(cpus - load + 0.5)))


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
    try:
        load = os.getloadavg()[0]
    except (AttributeError, OSError):
        return None
    cpus = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    n = threads_for_load(cpus, load)
    if n < cpus:
        environ["OMP_NUM_THREADS"] = str(n)
    return n
