"""Errors that brdfkit reports to a user rather than as a traceback.

Every problem with what a user handed in (a file, an option, a CSV row) is raised as
:class:`BrdfkitError` or a subclass. The CLI turns it into one line on stderr and exit
code 2; the library lets it propagate so callers can catch it.
"""

from __future__ import annotations

import os

__all__ = ["BrdfkitError", "InputError", "FormatError", "ModelMismatchError", "TrainingError", "require_counts"]


class BrdfkitError(Exception):
    """A problem the user can fix; its message is one line, fit for stderr."""

    exit_code = 2

    def __str__(self) -> str:
        # One line whatever a file smuggles into the message: metadata values, parser
        # errors quoting the file, names with line breaks or terminal escapes (found by
        # benchmarks/fuzz_parsers.py; docs/stability.md).
        text = super().__str__()
        return text if text.isprintable() else "".join(c if c.isprintable() else " " for c in text)


class InputError(BrdfkitError, ValueError):
    """An input (file, value or option) that cannot be used as given."""


class FormatError(InputError):
    """A file whose content does not follow the format it claims.

    Parameters
    ----------
    path
        The offending file.
    problem
        What is wrong, as a short clause ("truncated: 12 of 34992012 bytes").
    """

    def __init__(self, path: str | os.PathLike, problem: str):
        self.path = os.fspath(path)
        self.problem = problem
        super().__init__(f"{self.path}: {problem}")


class ModelMismatchError(InputError):
    """An embedding or file made with a different model than the one given."""


class TrainingError(BrdfkitError):
    """Training could not go on (e.g. the loss stayed non-finite); exit code 1, since
    nothing the user handed in was wrong."""

    exit_code = 1


def require_counts(settings, names, prefix: str = "") -> None:
    """Refuse, as an :class:`InputError`, a count field of a settings dataclass below 1:
    ``"{prefix}{name} must be >= 1, got {value!r}"``."""
    for name in names:
        value = getattr(settings, name)
        if int(value) < 1:
            raise InputError(f"{prefix}{name} must be >= 1, got {value!r}")
