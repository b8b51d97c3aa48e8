"""Messages and progress bars on stderr, for the library and the command line alike.

stdout stays clean for ``--json`` and CSV output, so everything a person watches goes to
stderr through :func:`console`. :class:`ProgressBar` is the one progress display of
brdfkit (training, rendering, the benchmark, the demo, ``brdfkit encode``); a disabled
bar is a silent no-op, so callers need no ``if progress`` around it.

Rich is imported on first use, so importing this module stays light.
"""

from __future__ import annotations

__all__ = ["console", "ProgressBar"]


def console():
    """A Rich console on stderr. Messages are not cut into lines (``soft_wrap``): Rich
    breaks a token longer than the rest of a line, a path among them, where the terminal
    would only wrap it, so a path it printed could not be copied whole."""
    from rich.console import Console

    return Console(stderr=True, soft_wrap=True)


class ProgressBar:
    """A Rich progress bar on stderr with one task.

    Parameters
    ----------
    description
        Text left of the bar.
    total
        Units of work (``None``: unknown until the first :meth:`update` gives it).
    enabled
        ``False`` makes every method a no-op; so does a console that is not a terminal.
    count
        Show ``done/total`` instead of a percentage.
    status
        Show a free text (``update(status=...)``) right of the bar.
    transient
        Remove the bar when it stops.
    out
        Rich console to draw on (default :func:`console`).

    Notes
    -----
    Use as a context manager, or :meth:`start` / :meth:`stop`; ``bar(done, total)`` is
    the ``progress(done, total)`` callback the renderers take.
    """

    def __init__(self, description: str = "", total: float | None = None, *, enabled: bool = True,
                 count: bool = False, status: bool = False, transient: bool = True, out=None):
        self._bar = None
        if enabled and out is None:
            out = console()
        # Only on a terminal: in a pipe or a log file a live bar leaves blank lines (or
        # its last frame) before the output a script reads.
        self.enabled = enabled and out.is_terminal
        if not self.enabled:
            return
        from rich.progress import (BarColumn, MofNCompleteColumn, Progress, TextColumn,
                                   TimeElapsedColumn, TimeRemainingColumn)

        columns = [TextColumn("{task.description}"), BarColumn(),
                   MofNCompleteColumn() if count else TextColumn("{task.percentage:>3.0f}%"),
                   TimeElapsedColumn()]
        columns.append(TextColumn("{task.fields[status]}") if status else TimeRemainingColumn())
        self._bar = Progress(*columns, console=out, transient=transient)
        self._task = self._bar.add_task(description, total=total, status="")

    def start(self) -> "ProgressBar":
        if self._bar is not None:
            self._bar.start()
        return self

    def stop(self) -> None:
        if self._bar is not None:
            self._bar.stop()

    def __enter__(self) -> "ProgressBar":
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()

    def update(self, done: float | None = None, total: float | None = None, *, advance: float | None = None,
               description: str | None = None, status: str | None = None) -> None:
        """Set the work done (or ``advance`` it), the total, the description, the status."""
        if self._bar is None:
            return
        kw = {k: v for k, v in (("completed", done), ("total", total), ("advance", advance),
                                ("description", description), ("status", status)) if v is not None}
        self._bar.update(self._task, **kw)

    def __call__(self, done: float, total: float) -> None:
        self.update(done, total)
