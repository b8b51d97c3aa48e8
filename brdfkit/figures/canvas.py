"""What every PNG sheet shares: the pyplot import (Agg backend), bare axes, a render shown
as displayed, the PNG written atomically."""

from __future__ import annotations

import os

__all__ = ["pyplot", "bare_axes", "show_render", "save_png"]


def pyplot():
    """``matplotlib.pyplot`` on the Agg backend: a sheet is a file, never a window, and
    needs no display."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def bare_axes(ax) -> None:
    """No ticks and no frame: the axes shows an image or text only."""
    ax.set_xticks([])
    ax.set_yticks([])
    for spine in ax.spines.values():
        spine.set_visible(False)


def show_render(ax, image, title: str | None = None, fontsize: float = 10) -> None:
    """Draw a linear RGB render ``(H, W, 3)`` as displayed
    (:func:`brdfkit.render.display.display_encode`: exposure 1, clipped, sRGB), nearest-pixel,
    on bare axes, with ``title`` above it."""
    from brdfkit.render.display import display_encode

    ax.imshow(display_encode(image), interpolation="nearest")
    if title is not None:
        ax.set_title(title, fontsize=fontsize)
    bare_axes(ax)


def save_png(fig, output: str | os.PathLike) -> None:
    """Write ``fig`` to the PNG ``output`` atomically (:func:`brdfkit.atomic.atomic_path`)
    at the figure's own dpi, then close it."""
    from brdfkit.atomic import atomic_path

    with atomic_path(os.fspath(output)) as tmp:
        fig.savefig(tmp, format="png", dpi=fig.dpi)
    pyplot().close(fig)
