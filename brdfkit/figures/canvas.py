"""What every PNG sheet shares: the pyplot import (Agg backend), bare axes, a render shown
as displayed (resampled smoothly to its tile), the PNG written atomically."""

from __future__ import annotations

import os

__all__ = ["SMOOTH", "pyplot", "bare_axes", "show_render", "show_image", "save_png"]

SMOOTH = "lanczos"
"""How a sheet resamples an image to its tile's pixels (matplotlib's ``interpolation``, on
the displayed colours): Lanczos, so that a render enlarged by a factor that is not whole
(a 128 px render in a tile of about 237 px) has smooth edges, not rows and columns of
pixels drawn twice. Deterministic: the same image gives the same PNG. A drawing that puts
one render pixel on one PNG pixel (the interpolation strip) passes ``"nearest"``."""


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


def show_image(ax, image, interpolation: str = SMOOTH, **kwargs):
    """``ax.imshow(image, **kwargs)`` resampled by ``interpolation`` (default
    :data:`SMOOTH`) on the displayed colours (``interpolation_stage="rgba"``: a colour
    map's colours are blended, never a value outside the data's range); returns the
    image artist."""
    return ax.imshow(image, interpolation=interpolation, interpolation_stage="rgba", **kwargs)


def show_render(ax, image, title: str | None = None, fontsize: float = 10, interpolation: str = SMOOTH) -> None:
    """Draw a linear RGB render ``(H, W, 3)`` as displayed
    (:func:`brdfkit.render.display.display_encode`: exposure 1, clipped, sRGB), resampled
    to the axes by ``interpolation`` (:func:`show_image`), on bare axes, with ``title``
    above it."""
    from brdfkit.render.display import display_encode

    show_image(ax, display_encode(image), interpolation)
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
