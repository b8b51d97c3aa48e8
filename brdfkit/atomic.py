"""Atomic output files: write to a temporary file beside the target, then rename.

A crash, ``SIGKILL`` or Ctrl-C while writing never leaves a half-written output: the
target either keeps its old content or gets the complete new one (``os.replace`` is
atomic on POSIX within one file system). Outputs equal to an input are refused so that
nothing a user handed in is ever overwritten.

A writer may name its format's reader (``verify``): the complete temporary file is read
back by it before it takes its name, so that what brdfkit writes is what brdfkit reads.
The reader is the one schema of its format; a file it refuses is never written.
"""

from __future__ import annotations

import contextlib
import os
import secrets
from typing import IO, Callable, Iterable, Iterator

from brdfkit.errors import BrdfkitError, InputError

__all__ = ["atomic_path", "atomic_paths", "atomic_open", "refuse_overwrite_of_inputs", "check_input_file",
           "UnreadableOutput"]


class UnreadableOutput(BrdfkitError):
    """What a writer made was refused by its own format's reader (a bug, reported in one
    line; the output is not written)."""

_TMP_PREFIX = ".brdfkit-tmp-"
_O_CLOEXEC = getattr(os, "O_CLOEXEC", 0)


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, verify: Callable[[str], object] | None = None) -> Iterator[str]:
    """Yield a temporary path in the target's folder; rename it onto ``path`` on success.

    The temporary file is removed if the body raises (``KeyboardInterrupt`` included).
    ``verify(tmp)``, when given, reads the complete file back with its format's reader
    first; a :class:`~brdfkit.errors.BrdfkitError` it raises becomes
    :class:`UnreadableOutput` and nothing is written.
    """
    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        raise InputError(f"{path}: output folder {folder} does not exist")
    if os.path.isdir(path):
        raise InputError(f"{path}: is a directory, expected an output file path")
    tmp = None
    try:
        # Created inside the try (not with mkstemp before it), so that a Ctrl-C landing
        # right after the file appears still removes it; mode 0666 & ~umask like any
        # output (mkstemp would make it private).
        while tmp is None:
            tmp = os.path.join(folder, f"{_TMP_PREFIX}{secrets.token_hex(8)}-{os.path.basename(path)}")
            try:
                os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | _O_CLOEXEC, 0o666))
            except FileExistsError:  # someone else's file: pick another name
                tmp = None
        mode = os.stat(tmp).st_mode & 0o777
        yield tmp
        if verify is not None:
            _read_back(verify, tmp, path)
        with open(tmp, "rb+") as f:
            os.fsync(f.fileno())
        # Some writers replace the file instead of filling it (safetensors' save_file
        # makes a new 0600 file): give it back the umask's mode every output has.
        if os.stat(tmp).st_mode & 0o777 != mode:
            os.chmod(tmp, mode)
        os.replace(tmp, path)
    except BaseException:
        if tmp is not None:
            with contextlib.suppress(OSError):  # never mask the error that got us here
                os.unlink(tmp)
        raise


@contextlib.contextmanager
def atomic_paths(*paths) -> Iterator[list]:
    """:func:`atomic_path` of several outputs of one command (``None`` entries skipped,
    and yielded as ``None``): all of them take their names only when the body has written
    every one, so that a failure writing the last leaves none of them (a table and the
    embedding it decodes from, say)."""
    with contextlib.ExitStack() as stack:
        yield [None if p is None else stack.enter_context(atomic_path(p)) for p in paths]


def _read_back(verify: Callable[[str], object], tmp: str, path: str) -> None:
    """``verify(tmp)``, its refusal as :class:`UnreadableOutput` naming ``path``."""
    try:
        verify(tmp)
    except BrdfkitError as e:
        reason = str(e).replace(tmp, path)
        raise UnreadableOutput(f"{path}: not written: brdfkit could not read back what it made ({reason})") from None


@contextlib.contextmanager
def atomic_open(path: str | os.PathLike, mode: str = "w", verify: Callable[[str], object] | None = None,
                **kwargs) -> Iterator[IO]:
    """``open`` for writing, atomically (see :func:`atomic_path`, and its ``verify``)."""
    if not mode.startswith("w"):
        raise ValueError("atomic_open is for writing only")
    with atomic_path(path, verify) as tmp:
        with open(tmp, mode, **kwargs) as f:
            yield f


def refuse_overwrite_of_inputs(output: str | os.PathLike | None,
                               inputs: Iterable[str | os.PathLike]) -> None:
    """Raise :class:`InputError` if ``output`` names the same file as any input, or
    cannot be written: its folder missing or not writable, or a folder by that name.

    Commands call this first, so that a bad output path fails in milliseconds, before
    minutes of rendering or training (a wrong ``-o`` used to fail after the work).
    """
    if output is None:
        return
    _check_writable(os.fspath(output))
    out = os.path.realpath(os.fspath(output))
    for item in inputs:
        if item is not None and os.path.realpath(os.fspath(item)) == out:
            raise InputError(f"{os.fspath(output)}: output path is also an input; refusing to overwrite it")


def _check_writable(path: str) -> None:
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        raise InputError(f"{path}: output folder {folder} does not exist")
    if os.path.isdir(path):
        raise InputError(f"{path}: is a directory, expected an output file path")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise InputError(f"{path}: output folder {folder} is not writable (permission denied)")


def check_input_file(path: str | os.PathLike) -> str:
    """Return ``path`` as a string if it names a readable regular file, else raise."""
    path = os.fspath(path)
    if not os.path.exists(path):
        raise InputError(f"{path}: no such file")
    if os.path.isdir(path):
        raise InputError(f"{path}: is a directory, expected a file")
    if not os.access(path, os.R_OK):
        raise InputError(f"{path}: not readable (permission denied)")
    return path
