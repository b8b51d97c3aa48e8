"""Mitsuba 3 imported with the ``llvm_ad_rgb`` variant, and the libLLVM it needs found.

Mitsuba's LLVM backend needs a ``libLLVM`` that Dr.Jit accepts: LLVM 19 is seen to work,
Debian 12's 14 is refused and 15 aborts the process (``docs/render.md``).
:func:`ensure_libllvm` looks for LLVM 19 only (``BRDFKIT_LIBLLVM_SEARCH``, glob patterns
separated by ``os.pathsep``, replaces the search), sets ``DRJIT_LIBLLVM_PATH`` when unset,
refuses one naming LLVM 15 or older, and otherwise asks for ``apt-get install -y
libllvm19``. :func:`load_mitsuba` imports Mitsuba once per process and registers the
``brdfkit`` BSDF (:mod:`brdfkit.render.mitsuba3.bsdf`).
"""

from __future__ import annotations

import glob
import os
import threading

from brdfkit.errors import BrdfkitError

__all__ = ["VARIANT", "LIBLLVM_CANDIDATES", "LIBLLVM_PATTERNS", "ensure_libllvm", "libllvm_version", "load_mitsuba"]

VARIANT = "llvm_ad_rgb"
LIBLLVM_CANDIDATES = tuple(f"/usr/lib/{d}/{n}" for d in ("x86_64-linux-gnu", "llvm-19/lib", "aarch64-linux-gnu")
                           for n in ("libLLVM.so.19.1", "libLLVM-19.so"))
LIBLLVM_PATTERNS = ("/usr/lib/*/libLLVM.so.19*", "/usr/lib/*/libLLVM-19.so*",
                    "/usr/lib/llvm-19/lib/libLLVM*.so*")
# Seen on Debian 12: 14 is refused by Dr.Jit, 15 aborts the process (exit 134).
BROKEN_LLVM_BELOW = 16
_INSTALL_HINT = ("Mitsuba's LLVM backend needs libLLVM 19 (the version seen to work; "
                 "Debian 12's LLVM 14 and 15 crash): install it with "
                 "`apt-get install -y libllvm19`, or set DRJIT_LIBLLVM_PATH to a libLLVM 19 .so")

_lock = threading.Lock()
_state: dict = {}  # the imported modules, once per process


def ensure_libllvm() -> str:
    """Make sure Dr.Jit will find a usable ``libLLVM`` before Mitsuba is imported.

    Returns
    -------
    str
        The library path in ``DRJIT_LIBLLVM_PATH`` (set here to the first of
        :data:`LIBLLVM_CANDIDATES` that exists, when unset).

    Raises
    ------
    BrdfkitError
        No usable library: the message says to ``apt-get install -y libllvm19``.
    """
    path = os.environ.get("DRJIT_LIBLLVM_PATH")
    if path:
        if not os.path.isfile(path):
            raise BrdfkitError(f"DRJIT_LIBLLVM_PATH={path}: no such file. {_INSTALL_HINT}")
        version = libllvm_version(path)
        if version is not None and version < BROKEN_LLVM_BELOW:
            raise BrdfkitError(f"DRJIT_LIBLLVM_PATH={path}: LLVM {version} crashes Mitsuba's "
                               f"LLVM backend. {_INSTALL_HINT}")
        return path
    search = os.environ.get("BRDFKIT_LIBLLVM_SEARCH")
    if search is not None:
        candidates, patterns = (), tuple(p for p in search.split(os.pathsep) if p)
    else:
        candidates, patterns = LIBLLVM_CANDIDATES, LIBLLVM_PATTERNS
    found = [c for c in candidates if os.path.isfile(c)]
    found += sorted(f for p in patterns for f in glob.glob(p) if os.path.isfile(f))
    if not found:
        raise BrdfkitError(f"no usable libLLVM found. {_INSTALL_HINT}")
    os.environ["DRJIT_LIBLLVM_PATH"] = found[0]
    return found[0]


def libllvm_version(path: str) -> int | None:
    """The LLVM major version in a library's file name (``libLLVM-15.so.1``,
    ``libLLVM.so.19.1``, ``/usr/lib/llvm-14/lib/libLLVM.so``), or ``None``."""
    import re

    name = os.path.basename(path)
    m = re.match(r"libLLVM-(\d+)", name) or re.match(r"libLLVM\.so\.(\d+)", name)
    if m is None:
        m = re.search(r"llvm-(\d+)", path)
    return int(m.group(1)) if m else None


def load_mitsuba():
    """Import Mitsuba with the ``llvm_ad_rgb`` variant and register the ``brdfkit`` BSDF.

    Returns
    -------
    tuple
        ``(mitsuba, drjit)`` modules.
    """
    with _lock:
        if "mi" in _state:
            return _state["mi"], _state["dr"]
        ensure_libllvm()
        try:
            import drjit as dr
            import mitsuba as mi

            mi.set_variant(VARIANT)
        except ImportError as e:
            if "LLVM" in str(e):  # Dr.Jit refused the library (LLVM 14), Mitsuba is there
                raise BrdfkitError(f"Mitsuba's LLVM backend refused {os.environ.get('DRJIT_LIBLLVM_PATH')}. "
                                   f"{_INSTALL_HINT}") from None
            raise BrdfkitError(f"cannot import Mitsuba 3 ({e}); install it with `pip install mitsuba`") from None
        except Exception as e:  # variant not compiled, LLVM refused
            raise BrdfkitError(f"Mitsuba variant {VARIANT} unavailable ({e}). {_INSTALL_HINT}") from None
        from brdfkit.render.mitsuba3.bsdf import bsdf_class

        mi.register_bsdf("brdfkit", lambda props: bsdf_class(mi, dr)(props))
        _state["mi"], _state["dr"] = mi, dr
        return mi, dr
