"""Interpolation strips: the paper's material-editing figure (Gokbudak et al. 2024,
Sec. 5) in one PNG.

``steps`` materials evenly spaced from embedding A (``t = 0``) to B (``t = 1``), each the
blend ``(1 - t) A + t B`` (:func:`brdfkit.api.interpolate`: of the basis's coefficients, or
of the hypernetwork's latents) decoded by the model and rendered in the reference scene by the
quadrature renderer, all in one pass (:func:`brdfkit.render.quadrature.render_many`).
The renders sit side by side, one screen pixel per render pixel (their silhouettes
antialiased: :func:`brdfkit.figures.canvas.antialias_silhouette`), each labelled with its
``t``; a caption names A and B. ``brdfkit interpolate A B --sheet strip.png`` draws it.
"""

from __future__ import annotations

import math
import os

import numpy as np

from brdfkit.errors import InputError

__all__ = ["STEPS", "SIZE", "MAX_STEPS", "MIN_SIZE", "MAX_SIZE", "MAX_WIDTH", "strip_ts", "check_strip",
           "interpolation_strip"]

STEPS = 5
SIZE = 128
# Bounds that catch a typo (``--steps 500``) before minutes of rendering. The renders of
# one pass sum in float64 (24 bytes a pixel per tile), so the strip's width also bounds
# its memory: 16 tiles of 1024 px take 0.4 GB.
MAX_STEPS = 100
MIN_SIZE, MAX_SIZE = 8, 1024
MAX_WIDTH = 16384
FONT_PT = 9.0
MARGIN_PX = 6


def strip_ts(steps: int) -> list[float]:
    """The ``steps`` blend weights from 0 to 1, evenly spaced; the ends exactly 0 and 1,
    so the first and last tiles are A and B themselves."""
    return [float(t) for t in np.linspace(0.0, 1.0, steps)]


def _label(t: float) -> str:
    return f"t = {t:.3g}"


def check_strip(steps, size) -> None:
    """Refuse a strip shape out of bounds (:class:`~brdfkit.errors.InputError`): ``steps``
    2 to :data:`MAX_STEPS`, ``size`` :data:`MIN_SIZE` to :data:`MAX_SIZE` pixels, and
    ``steps x size`` at most :data:`MAX_WIDTH` pixels."""
    if isinstance(steps, bool) or not isinstance(steps, int) or not 2 <= steps <= MAX_STEPS:
        raise InputError(f"steps = {steps!r}: a strip needs a whole number of materials from 2 (t = 0 and t = 1) "
                         f"to {MAX_STEPS}")
    if isinstance(size, bool) or not isinstance(size, int) or not MIN_SIZE <= size <= MAX_SIZE:
        raise InputError(f"size = {size!r}: a tile is a whole number of pixels from {MIN_SIZE} to {MAX_SIZE}")
    if steps * size > MAX_WIDTH:
        raise InputError(f"{steps} tiles of {size} px (steps, tile) make a strip {steps * size:,} px wide, more "
                         f"than {MAX_WIDTH:,}: take fewer steps or smaller tiles")


def interpolation_strip(decoder, a, b, output: str | os.PathLike, *, steps: int = STEPS, size: int = SIZE,
                        progress: bool = True, dpi: float = 100.0) -> list[tuple[float, np.ndarray]]:
    """Render the blends of ``a`` and ``b`` and draw them as one labelled strip (PNG).

    Parameters
    ----------
    decoder
        The :class:`~brdfkit.embeddings.Decoder` that made both embeddings
        (:func:`brdfkit.embeddings.decoder_for`).
    a, b
        :class:`~brdfkit.io.embedding.Embedding` at ``t = 0`` and ``t = 1``; their
        ``source`` (a file name) is shown in the caption.
    output
        PNG path, written atomically.
    steps
        Number of materials, ``t = 0, 1 / (steps - 1), ..., 1`` (2 to :data:`MAX_STEPS`).
    size
        Render resolution, pixels per tile side (:data:`MIN_SIZE` to :data:`MAX_SIZE`);
        each render is drawn at one screen pixel per render pixel.
    progress
        A render progress bar on stderr (drawn only on a terminal).
    dpi
        Dots per inch of the PNG: the label font's size in pixels, not the tiles'.

    Returns
    -------
    list
        ``(t, image)`` per tile, left to right: ``image`` the float32 ``(size, size, 3)``
        linear RGB render (background 0).

    Raises
    ------
    InputError
        ``steps`` or ``size`` out of range (:func:`check_strip`).
    ModelMismatchError
        ``a`` and ``b`` differ in kind, size or decoder, or ``decoder`` did not make them.
    """
    from brdfkit.console import ProgressBar
    from brdfkit.embeddings import interpolate, open_embedding
    from brdfkit.render.scene import reference_scene
    from brdfkit.render.quadrature import render_many
    from brdfkit.figures.canvas import antialias_silhouette, pyplot, save_png, show_render

    check_strip(steps, size)
    ts = strip_ts(steps)
    blends = [interpolate(a, b, t) for t in ts]  # refuses embeddings of two models first
    open_embedding(a, decoder, a.source or "A")  # checked, named as the user gave it, not as a blend
    brdfs = [open_embedding(e, decoder) for e in blends]
    with ProgressBar(f"quadrature {steps} blends", enabled=progress) as bar:
        done = render_many(brdfs, reference_scene(size), progress=bar if progress else None)
    images = [img for img, _ in done]
    shown = antialias_silhouette(brdfs, images)  # the pictures' silhouettes; the images returned as rendered

    names = [os.path.basename(e.source) if e.source else n for e, n in ((a, "A"), (b, "B"))]
    fig = pyplot().figure(dpi=dpi)
    labels = [fig.text(0, 0, _label(t), ha="center", va="bottom", fontsize=FONT_PT) for t in ts]
    blended = f"{a.kind} embeddings"
    caption = fig.text(0, 0, f"A = {names[0]}, B = {names[1]}: {blended} (1 - t) A + t B, reference scene",
                       ha="center", va="bottom", fontsize=FONT_PT, color="0.3")
    renderer = fig.canvas.get_renderer()
    text_px = [math.ceil(x.get_window_extent(renderer).width) for x in (*labels, caption)]
    # Integer pixel boxes, so that each render lands on the PNG's pixel grid unresampled;
    # a column is wide enough for its label even when the tile is small.
    line = math.ceil(FONT_PT * dpi / 72.0 * 1.4)
    col = max(size + MARGIN_PX, max(text_px[:-1]) + 2 * MARGIN_PX)
    width = max(steps * col, text_px[-1]) + 2 * MARGIN_PX
    height = MARGIN_PX + line + size + line + MARGIN_PX
    fig.set_size_inches(width / dpi, height / dpi)
    left = (width - steps * col) // 2
    for i, (label, img) in enumerate(zip(labels, shown)):
        x = left + i * col + (col - size) // 2
        show_render(fig.add_axes((x / width, (MARGIN_PX + line) / height, size / width, size / height)), img,
                    interpolation="nearest")  # one PNG pixel per render pixel: nothing to resample
        label.set_position(((x + size / 2) / width, (MARGIN_PX + line + size + 2) / height))
    caption.set_position((0.5, MARGIN_PX / height))
    save_png(fig, output)
    return list(zip(ts, images))
