"""What a training run shows on stderr (:func:`brdfkit.hypernet.training.loop.fit`): its
log lines and a progress bar, on rank 0 only, through :mod:`brdfkit.console`.

Kept apart from the step loop, which calls it whether or not anything is shown: a
disabled display is a silent no-op. Rich is imported on first use only.
"""

from __future__ import annotations

__all__ = ["TrainingDisplay"]


class TrainingDisplay:
    """Rank 0's progress on stderr (Rich); silent when ``progress`` is off.

    Parameters
    ----------
    enabled
        Show anything at all (``progress`` on, and rank 0).
    """

    def __init__(self, enabled: bool):
        self.enabled = enabled
        self.console = None
        self.bar = None
        if enabled:
            from brdfkit.console import console
            self.console = console()

    def print(self, *args, **kw):
        """A log line (Rich markup), as :meth:`rich.console.Console.print` takes it."""
        if self.console:
            self.console.print(*args, **kw)

    def start(self, description: str):
        """Start a progress bar named ``description``; returns ``self``."""
        if not self.enabled:
            return self
        from brdfkit.console import ProgressBar

        self.bar = ProgressBar(f"[bold]{description}", total=1.0, status=True, transient=False,
                               out=self.console).start()
        return self

    def update(self, fraction: float, status: str):
        """Move the bar to ``fraction`` (clipped to [0, 1]) with the ``status`` text."""
        if self.bar is not None:
            self.bar.update(min(max(fraction, 0.0), 1.0), status=status)

    def stop(self):
        """Stop the bar, if one runs (the next :meth:`start` makes a new one)."""
        if self.bar is not None:
            self.bar.stop()
            self.bar = None
