"""Plots of BRDFs as BRDF Explorer shows them: in-plane lobes and theta_h / theta_d slices.

Two views of one or more isotropic BRDFs side by side (a measured table against its
reconstructions, say), written as one PNG with matplotlib's Agg backend:

* **In-plane lobes** (polar): the BRDF in the plane of incidence for a few incident
  angles ``theta_i``. The incident direction comes in from the left at ``-theta_i``; the
  outgoing angle ``theta_o`` runs from -90 (back towards the light) to 90 degrees (past
  the mirror direction ``+theta_i``). The radius is ``log10`` of the BRDF over a fixed
  number of decades below the largest value of all inputs (or the BRDF itself, linearly),
  optionally times ``cos(theta_o)``. One line per input, the same colour in every panel.
* **Slices** (images): the table at a fixed ``phi_d`` over ``theta_d`` (x) and
  ``theta_h`` (y), in the MERL grid's own coordinates (``theta_h`` cell ``i`` at
  ``(i / 90)^2 * 90`` degrees, so the specular peak at small ``theta_h`` is spread out),
  ``log10`` colours on one scale shared by every image: black at the scale's bottom and
  below (zero included: a value a decoder gives as 0 shows black), grey where not measured;
  the title says which of the two the images hold.

Values are one channel (``red``, ``green``, ``blue``) or the luminance
``Y = 0.2126 R + 0.7152 G + 0.0722 B`` (Rec. 709 primaries, linear), in 1/sr.
Lobes are looked up trilinearly in the table (:func:`brdfkit.geometry.trilinear.lookup_trilinear`).

Inputs are MERL tables (``.binary``) or embeddings (``.emb``), which are decoded to a
table with their model (that alone imports torch; plotting tables does not).
"""

from __future__ import annotations

import math
import os
import textwrap
from typing import Sequence

import numpy as np

from brdfkit.errors import InputError

__all__ = ["CHANNELS", "VIEWS", "input_labels", "load_tables", "channel_values", "inplane_lobe",
           "check_options", "plot_brdfs", "plot_figure"]

CHANNELS = ("luminance", "red", "green", "blue")
VIEWS = ("both", "lobes", "slices")
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
# theta_o samples of a lobe: 0.5 degree steps, stopping short of the horizon.
THETA_O_DEG = np.linspace(-89.5, 89.5, 359)
# Tick positions of the theta_h axis of a slice, degrees (non-uniform grid).
THETA_H_TICKS = (0, 1, 5, 10, 20, 30, 45, 60, 90)
COLOURS = ("#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#17becf")
STYLES = ("-", "--", "-.", ":", (0, (5, 1, 1, 1, 1, 1)))


def input_labels(paths: Sequence[str]) -> list[str]:
    """Names of inputs for legends and titles: file stems; where two stems are equal, the
    file names with their extension; where those are equal too, numbered ``name (2)``."""
    labels = [os.path.splitext(os.path.basename(p))[0] for p in paths]
    dup = {x for x in labels if labels.count(x) > 1}
    labels = [os.path.basename(p) if x in dup else x for x, p in zip(labels, paths)]
    seen: dict[str, int] = {}
    out = []
    for x in labels:
        seen[x] = seen.get(x, 0) + 1
        out.append(x if labels.count(x) == 1 else f"{x} ({seen[x]})")
    return out


def load_tables(paths: Sequence[str | os.PathLike], model_path: str | os.PathLike | None = None
                ) -> dict[str, np.ndarray]:
    """Read MERL tables and decode embeddings: ``{label: (90, 90, 180, 3) table}`` in the
    order given, labels the file stems (unique; see :func:`input_labels`).

    An ``.emb`` decodes with ``model_path`` (the decoder that made it: a file or a
    built-in's name; ``None``: the installed built-in part whose digest it records).
    """
    from brdfkit.files.brdf_file import EmbeddingDecoders, file_type, read_table

    paths = [os.fspath(p) for p in paths]
    if not paths:
        raise InputError("plot: no input (give MERL .binary tables and/or .emb embeddings)")
    for path in paths:  # every name checked before anything is read or decoded
        file_type(path)
    models = EmbeddingDecoders(model_path)
    return {label: read_table(path, models) for label, path in zip(input_labels(paths), paths)}


def channel_values(rgb: np.ndarray, channel: str) -> np.ndarray:
    """One channel, or the luminance, of RGB values ``(..., 3)``: ``(...)``."""
    if channel == "luminance":
        return rgb @ LUMINANCE
    if channel not in CHANNELS:
        raise InputError(f"channel {channel!r}: expected one of {', '.join(CHANNELS)}")
    return rgb[..., CHANNELS.index(channel) - 1]


def inplane_lobe(table: np.ndarray, theta_i_deg: float, channel: str = "luminance",
                 cosine: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """The BRDF in the plane of incidence.

    Parameters
    ----------
    table
        ``(90, 90, 180, 3)``, 1/sr, NaN where not measured.
    theta_i_deg
        Incident angle, degrees; ``wi = (-sin theta_i, 0, cos theta_i)``.
    channel
        One of :data:`CHANNELS`.
    cosine
        Multiply by ``cos(theta_o)`` (the outgoing radiance under a unit irradiance
        from ``wi``, up to ``cos(theta_i)``).

    Returns
    -------
    tuple
        ``(theta_o, values)``: :data:`THETA_O_DEG` in degrees, and the values ``(359,)``,
        NaN where the table has no measured neighbour.
    """
    from brdfkit.geometry import half_diff_from_io
    from brdfkit.geometry.trilinear import lookup_trilinear

    ti = math.radians(theta_i_deg)
    to = np.radians(THETA_O_DEG)
    wi = np.broadcast_to(np.array([-math.sin(ti), 0.0, math.cos(ti)]), (to.size, 3))
    wo = np.stack([np.sin(to), np.zeros_like(to), np.cos(to)], axis=-1)
    theta_h, _, theta_d, phi_d = half_diff_from_io(wi, wo)
    values = channel_values(lookup_trilinear(table, theta_h, theta_d, phi_d), channel)
    if cosine:
        values = values * np.cos(to)
    return THETA_O_DEG.copy(), values


def _log_range(arrays, decades: float) -> tuple[float, float]:
    """``(lo, hi)`` of ``log10`` values: whole decades, ``hi`` at or above the largest
    finite positive value over all arrays, ``lo`` ``ceil(decades)`` below (so that grid
    rings and colour-bar ticks fall on powers of ten)."""
    peak = max((float(np.nanmax(np.where(a > 0, a, np.nan))) for a in arrays
                if np.any(np.isfinite(a) & (a > 0))), default=1.0)
    hi = math.ceil(math.log10(peak) - 1e-9)
    return float(hi - math.ceil(decades)), float(hi)


def check_options(theta_i: Sequence[float], phi_d: Sequence[float], channel: str = "luminance",
                  decades: float = 6.0, view: str = "both") -> None:
    """Raise :class:`InputError` for options :func:`plot_brdfs` cannot draw (cheap: call
    before reading any input)."""
    if view not in VIEWS:
        raise InputError(f"view {view!r}: expected one of {', '.join(VIEWS)}")
    if channel not in CHANNELS:
        raise InputError(f"channel {channel!r}: expected one of {', '.join(CHANNELS)}")
    if not theta_i or any(not 0.0 <= float(t) < 90.0 for t in theta_i):
        raise InputError(f"--theta-i {','.join(f'{t:g}' for t in theta_i)}: incident angles must "
                         "lie in [0, 90) degrees")
    if not phi_d or any(not 0.0 <= float(p) < 180.0 for p in phi_d):
        raise InputError(f"--phi-d {','.join(f'{p:g}' for p in phi_d)}: phi_d must lie in [0, 180) degrees")
    if not (math.isfinite(decades) and 0 < decades <= 30):
        raise InputError(f"--decades {decades:g}: must lie in (0, 30]")
    if len(theta_i) > 12 or len(phi_d) > 12:
        raise InputError("--theta-i / --phi-d: at most 12 angles each")


def _wrap(text: str, inches: float, size: float) -> str:
    """``text`` in lines that fit ``inches`` at ``size`` pt (the layout makes room for
    a title's height, never for its width): 0.6 em a character is DejaVu Sans' widest
    for these titles (file stems: 0.57 em; prose: 0.49 em)."""
    return textwrap.fill(text, max(int(inches * 72 / (0.6 * size)), 12))


def _decade_label(x: float) -> str:
    return f"$10^{{{int(round(x))}}}$"


def _polar_frame(ax, rmax: float, lo: float | None, decades: float) -> None:
    """A half-disc polar grid on Cartesian axes: rings at each decade (``lo`` given) or at
    fifths of ``rmax``, spokes every 30 degrees from the normal, labels outside."""
    ax.set_aspect("equal")
    ax.axis("off")
    ang = np.linspace(-math.pi / 2, math.pi / 2, 181)
    if lo is not None:
        step = 1.0 if decades <= 5 else 2.0
        rings = np.arange(step, math.floor(decades) + 1, step)
        labels = [_decade_label(lo + k) for k in rings]
    else:
        rings = np.linspace(rmax / 5, rmax, 5)
        labels = [f"{k:.3g}" for k in rings]
    for k, text in zip(rings, labels):
        ax.plot(k * np.sin(ang), k * np.cos(ang), color="0.85", lw=0.7, zorder=0)
        ax.text(k, -0.03 * rmax, text, ha="center", va="top", fontsize=7, color="0.3")
    if lo is not None:
        ax.text(0, -0.03 * rmax, _decade_label(lo), ha="center", va="top", fontsize=7, color="0.3")
    ax.plot(rmax * np.sin(ang), rmax * np.cos(ang), color="0.4", lw=0.9, zorder=0)
    ax.plot([-rmax, rmax], [0, 0], color="0.4", lw=0.9, zorder=0)
    for deg in (-60, -30, 0, 30, 60):
        a = math.radians(deg)
        ax.plot([0, rmax * math.sin(a)], [0, rmax * math.cos(a)], color="0.85", lw=0.7, zorder=0)
    for deg in (-90, -60, -30, 0, 30, 60, 90):
        a = math.radians(deg)
        ax.text(1.09 * rmax * math.sin(a), 1.07 * rmax * math.cos(a), f"{deg}\u00b0", ha="center",
                va="center", fontsize=7, color="0.3")
    ax.set_xlim(-1.17 * rmax, 1.17 * rmax)
    ax.set_ylim(-0.16 * rmax, 1.17 * rmax)


def plot_brdfs(tables: dict[str, np.ndarray], output: str | os.PathLike, **options) -> str:
    """Write the lobes and/or slices of ``tables`` side by side as a PNG (atomically):
    :func:`plot_figure` of ``tables`` and ``options`` (``theta_i``, ``phi_d``,
    ``channel``, ``cosine``, ``log``, ``decades``, ``view``, ``dpi``) at the path
    ``output``; returns ``output``."""
    from brdfkit.atomic import atomic_path

    fig = plot_figure(tables, **options)
    import matplotlib.pyplot as plt

    output = os.fspath(output)
    try:
        with atomic_path(output) as tmp:
            fig.savefig(tmp, format="png")
    finally:
        plt.close(fig)
    return output


def plot_figure(tables: dict[str, np.ndarray], *, theta_i: Sequence[float] = (0.0, 30.0, 60.0, 75.0),
                phi_d: Sequence[float] = (90.0,), channel: str = "luminance", cosine: bool = False,
                log: bool = True, decades: float = 6.0, view: str = "both", dpi: int = 110):
    """The figure :func:`plot_brdfs` writes (matplotlib, Agg backend; close it with
    ``matplotlib.pyplot.close``).

    Parameters
    ----------
    tables
        ``{label: (90, 90, 180, 3) table}`` (:func:`load_tables`); labels name the
        inputs in the legend and the slice titles.
    theta_i
        Incident angles of the lobes, degrees in ``[0, 90)``.
    phi_d
        ``phi_d`` of the slices, degrees in ``[0, 180)``; one row of images each.
    channel
        One of :data:`CHANNELS`.
    cosine
        Lobes times ``cos(theta_o)``.
    log
        Lobe radius ``log10`` over ``decades`` decades (else linear from 0).
    decades
        Decades of the log scales (lobes and slices), below the largest value.
    view
        ``"both"``, ``"lobes"`` or ``"slices"``.
    dpi
        Pixels an inch.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    check_options(theta_i, phi_d, channel, decades, view)
    if not tables:
        raise InputError("plot: no input")
    theta_i = [float(t) for t in theta_i]
    phi_d = [float(p) for p in phi_d]
    want_lobes, want_slices = view in ("both", "lobes"), view in ("both", "slices")
    unit = "BRDF x cos(theta_o) (1/sr)" if cosine else "BRDF (1/sr)"

    n_lobes, n_cols = len(theta_i), len(tables)
    # Inches: a lobe panel; a slice image (square: it fills its axes, and the layout
    # makes room for every title and label only around axes it does not shrink) and
    # what a column and a row of them add around it (titles, ticks, labels, colour bar).
    panel, image = 3.3, 2.6
    slices_width = n_cols * (image + 0.15) + 1.5
    width = max(n_lobes * panel if want_lobes else 0, slices_width if want_slices else 0, 6.0)
    heights = (([panel * 0.56 + 1.0] if want_lobes else [])
               + ([(image + 0.45) * len(phi_d) + 0.9] if want_slices else []))
    fig = plt.figure(figsize=(width, sum(heights)), dpi=dpi, layout="constrained")
    # Room between a view's title and its panels' titles, and at the figure's edges.
    fig.get_layout_engine().set(h_pad=6 / 72, w_pad=6 / 72)
    subfigs = iter(fig.subfigures(len(heights), 1, height_ratios=heights, squeeze=False)[:, 0])
    if want_lobes:
        _draw_lobes(next(subfigs), tables, theta_i, channel, cosine, log, decades,
                    f"{channel}, {unit}", width)
    if want_slices:
        # Empty columns either side keep the images square and centred in a figure wider
        # than they need (the lobes').
        side = (width - slices_width) / 2 / (image + 0.15)
        _draw_slices(next(subfigs), tables, phi_d, channel, unit, decades, width, side, image)
    return fig


def _draw_lobes(sub, tables: dict[str, np.ndarray], theta_i: list[float], channel: str, cosine: bool,
                log: bool, decades: float, what: str, width: float) -> None:
    """The in-plane lobes of :func:`plot_figure` in the subfigure ``sub``: one polar panel
    per incident angle of ``theta_i`` (degrees), one line per table, a shared legend;
    ``what`` names the values in the title, ``width`` (inches) wraps it."""
    labels = list(tables)
    n_lobes = len(theta_i)
    lobes = {(lab, t): inplane_lobe(tables[lab], t, channel, cosine)[1]
             for lab in labels for t in theta_i}
    if log:
        lo, hi = _log_range(lobes.values(), decades)
    else:
        hi = max((float(np.nanmax(v)) for v in lobes.values() if np.any(np.isfinite(v))), default=1.0)
    axes = sub.subplots(1, n_lobes, squeeze=False)[0]
    to = np.radians(THETA_O_DEG)
    rmax = hi - lo if log else hi * 1.05
    for ax, t in zip(axes, theta_i):
        _polar_frame(ax, rmax, lo if log else None, rmax)
        for n, lab in enumerate(labels):
            v = lobes[(lab, t)]
            r = v
            if log:
                with np.errstate(divide="ignore", invalid="ignore"):
                    r = np.clip(np.log10(np.where(v > 0, v, np.nan)) - lo, 0.0, None)
                r = np.where(np.isfinite(v) & (v <= 0), 0.0, r)
            # Colour and dash both change per input: a reconstruction lying on its
            # reference must still show.
            ax.plot(r * np.sin(to), r * np.cos(to), color=COLOURS[n % len(COLOURS)],
                    ls=STYLES[n % len(STYLES)], lw=1.7, label=lab)
        ti = math.radians(t)
        ax.annotate("", xy=(0, 0), xytext=(-rmax * math.sin(ti), rmax * math.cos(ti)),
                    arrowprops=dict(arrowstyle="->", color="0.3", lw=1.3))
        ax.plot([0, rmax * math.sin(ti)], [0, rmax * math.cos(ti)], color="0.5", lw=0.9, ls=":")
        ax.set_title(f"theta_i = {t:g} deg", fontsize=10)
    handles, names = axes[0].get_legend_handles_labels()
    sub.suptitle(_wrap(f"In-plane lobes ({what}, {'log' if log else 'linear'} radius; light along the "
                       "arrow, dotted: mirror direction)", width - 0.4, 10), fontsize=10)
    sub.legend(handles, names, loc="outside lower center", ncol=min(len(labels), 6), fontsize=9,
               frameon=False)


def _draw_slices(sub, tables: dict[str, np.ndarray], phi_d: list[float], channel: str, unit: str,
                 decades: float, width: float, side: float, image: float) -> None:
    """The slices of :func:`plot_figure` in the subfigure ``sub``: one row of ``log10``
    images per ``phi_d`` (degrees), one column per table, one colour bar. ``unit`` names
    the values, ``width`` (inches) wraps the title, ``side`` is the width of the empty
    columns either side (in image columns; none when not positive), ``image`` the width
    of an image (inches) that wraps its title."""
    import matplotlib

    labels = list(tables)
    n_cols = len(labels)
    ks = [int(round(p / 180.0 * 180)) % 180 for p in phi_d]
    images = {(lab, k): channel_values(tables[lab][:, :, k, :], channel) for lab in labels for k in ks}
    lo_s, hi_s = _log_range(images.values(), decades)
    ratios = [side, *[1.0] * n_cols, side] if side > 0 else [1.0] * n_cols
    grid = sub.add_gridspec(len(ks), len(ratios), width_ratios=ratios)
    first = 1 if side > 0 else 0
    axes = np.array([[sub.add_subplot(grid[i, first + j]) for j in range(n_cols)] for i in range(len(ks))])
    cmap = matplotlib.colormaps["magma"].with_extremes(bad="0.82")
    th_ticks = [90.0 * math.sqrt(d / 90.0) for d in THETA_H_TICKS]
    im = None
    for i, (k, p) in enumerate(zip(ks, phi_d)):
        for j, lab in enumerate(labels):
            ax = axes[i, j]
            v = images[(lab, k)]
            with np.errstate(divide="ignore", invalid="ignore"):
                lv = np.log10(np.where(v > 0, v, np.nan))
            lv = np.where(np.isfinite(v) & (v <= 0), lo_s, lv)
            im = ax.imshow(lv, origin="lower", cmap=cmap, vmin=lo_s, vmax=hi_s, aspect="auto",
                           extent=(-0.5, 89.5, -0.5, 89.5), interpolation="nearest")
            ax.set_title(f"{_wrap(lab, image, 9)}\nphi_d = {p:g} deg", fontsize=9)
            ax.set_xticks([0, 15, 30, 45, 60, 75, 89])
            ax.set_xticklabels(["0", "15", "30", "45", "60", "75", "90"], fontsize=7)
            ax.set_yticks(th_ticks)
            ax.set_yticklabels([f"{d:g}" for d in THETA_H_TICKS], fontsize=7)
            if i == len(ks) - 1:
                ax.set_xlabel("theta_d (deg)", fontsize=8)
            else:
                ax.tick_params(labelbottom=False)
            if j == 0:
                ax.set_ylabel("theta_h (deg)", fontsize=8)
            else:
                ax.tick_params(labelleft=False)
    cb = sub.colorbar(im, ax=axes, shrink=0.85, aspect=25, pad=0.02)
    ticks = np.arange(math.ceil(lo_s), math.floor(hi_s) + 1)
    cb.set_ticks(ticks)
    cb.set_ticklabels([_decade_label(x) for x in ticks])
    cb.set_label(f"{unit.replace(' x cos(theta_o)', '')}, {channel}", fontsize=8)
    sub.suptitle(_wrap(f"Slices at fixed phi_d ({channel}, log colour scale shared by all; "
                       f"{_slice_legend(images.values(), lo_s)})", width - 0.4, 10), fontsize=10)


def _slice_legend(images, lo: float) -> str:
    """What the slices' dark colours mean, of what ``images`` hold: black, values at the
    scale's bottom ``10^lo`` or below (a zero included), where any; grey, cells not
    measured (NaN), where any (at ``phi_d`` = 90 degrees every cell is above the horizon)."""
    parts = []
    with np.errstate(invalid="ignore"):
        if any(np.any(np.isfinite(v) & (v <= 10.0 ** lo)) for v in images):
            parts.append(f"black: {_decade_label(lo)} or less, 0 included")
    if any(np.isnan(v).any() for v in images):
        parts.append("grey: not measured")
    return "; ".join(parts) or "darker: smaller"
