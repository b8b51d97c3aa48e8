"""Comparison sheets: renders of predictions beside their reference, each labelled with
its errors, and a false-colour error image under each; in the reference scene or another
scene of the suite.

One PNG: the first column is the reference, then one column per prediction. The top row
holds the renders as displayed (:func:`brdfkit.render.display.display_encode`: exposure 1,
clipped, sRGB; resampled to their tiles by Lanczos, :data:`brdfkit.figures.canvas.SMOOTH`,
so a render enlarged by a factor that is not whole keeps smooth edges), each prediction captioned with the errors ``brdfkit metrics`` reports
(:func:`brdfkit.evaluation.metrics.score`: PSNR, mean CIEDE2000, SSIM, and the BRDF log RMSE when
both are BRDF files). The bottom row holds the per-pixel CIEDE2000 against the reference
(:func:`brdfkit.evaluation.metrics.delta_e_2000_map`) on one colour scale for all predictions.
The pictures' silhouettes are antialiased (each pixel the sphere's outline crosses, the
mean of 4 x 4 points, as ``brdfkit render --supersample 4`` gives it:
:func:`brdfkit.figures.canvas.antialias_silhouette`); the scores, and the mean and
largest Delta E under each error image, are those of the renders themselves, as ``brdfkit
metrics`` computes them.

Inputs are what ``brdfkit metrics`` takes: MERL tables (``.binary``) and embeddings
(``.emb``, with their model), rendered in the reference scene by the quadrature renderer
(:class:`brdfkit.evaluation.comparison.FileLoader`), or ``.exr`` images of the same size.
"""

from __future__ import annotations

import os
from typing import Sequence

import numpy as np

from brdfkit.errors import InputError
from brdfkit.figures.canvas import antialias_silhouette, bare_axes, pyplot, save_png, show_image, show_render

__all__ = ["comparison_sheet", "DELTA_E_SCALE"]

# Lowest top of the error colour scale: a few units of Delta E 2000 (about 1 is just
# noticeable), so that near-identical images do not show amplified noise.
DELTA_E_SCALE = 5.0


def _caption(scores: dict) -> str:
    rows = [f"PSNR {scores['psnr']:.2f} dB", f"Delta E 2000 {scores['delta_e']:.2f}",
            f"SSIM {scores['ssim']:.3f}"]
    if scores.get("brdf_log_rmse") is not None:
        rows.append(f"BRDF log RMSE {scores['brdf_log_rmse']:.3f}")
    return "\n".join(rows)


def _antialiased(loader, paths, images, scene: str) -> list:
    """The sheet's pictures: ``images`` (the renders of ``paths``) with their silhouettes
    antialiased (:func:`brdfkit.figures.canvas.antialias_silhouette`) when every input is a
    BRDF file (an ``.exr`` is shown as it is, and so then are the others)."""
    if any(p.lower().endswith(".exr") for p in paths):
        return images
    from brdfkit.files.brdf_file import load_brdf
    from brdfkit.render.renderable import TableBRDF
    from brdfkit.render.scene_suite import scene_env

    brdfs = [TableBRDF(loader.table(p)) if p.lower().endswith(".binary") else load_brdf(p, model_path=loader.model_path)
             for p in paths]
    return antialias_silhouette(brdfs, images, env=scene_env(scene))


def comparison_sheet(ref: str | os.PathLike, preds: Sequence[str | os.PathLike],
                     output: str | os.PathLike, *, model_path: str | os.PathLike | None = None,
                     resolution: int | None = None, progress: bool = True, dpi: int = 110,
                     before_torch=None, scene: str = "reference", loader=None) -> dict:
    """Render, score and draw ``preds`` against ``ref`` into the PNG ``output``.

    Parameters
    ----------
    ref
        The reference: ``.binary``, ``.emb`` or ``.exr``.
    preds
        One or more predictions of the same kinds.
    output
        PNG path (written atomically).
    model_path
        Model of the ``.emb`` inputs.
    resolution
        Render size of BRDF inputs (default: the reference scene's 256; an ``.exr``
        reference sets it).
    progress
        Render progress bars on stderr (drawn only on a terminal).
    before_torch
        Called once before the first render (:class:`brdfkit.evaluation.comparison.FileLoader`): a
        sheet of images only never imports torch.
    scene
        The suite scene BRDF inputs are rendered in (:mod:`brdfkit.render.scene_suite`;
        default the reference scene).
    loader
        A :class:`brdfkit.evaluation.comparison.FileLoader` to read and render through
        (``model_path``, ``resolution``, ``progress`` and ``before_torch`` are then its
        own): sheets of the same files in several scenes read each file once, when it
        keeps as many tables as they have inputs (``FileLoader(..., keep=N)``).

    Returns
    -------
    dict
        ``{label: scores}`` per prediction, labels the file stems (unique), scores as
        :func:`brdfkit.evaluation.metrics.score` returns them.
    """
    from brdfkit.atomic import check_input_file
    from brdfkit.evaluation.comparison import FileLoader
    from brdfkit.evaluation.metrics import delta_e_2000_map, score
    from brdfkit.figures.brdf_plot import input_labels
    from brdfkit.render.scene_suite import scene_env

    scene_env(scene)  # an unknown scene is refused before anything is read or rendered
    ref = os.fspath(ref)
    preds = [os.fspath(p) for p in preds]
    if not preds:
        raise InputError("compare: give a reference and at least one prediction")
    # every input's table kept: the check, the renders, the scores and the antialiasing each read them
    loader = loader or FileLoader(model_path, resolution, progress, before_torch=before_torch, keep=len(preds) + 1)
    for path in [ref, *preds]:  # every input readable before the first render
        check_input_file(path)
        loader.check(path)
    is_image = {p: p.lower().endswith(".exr") for p in [ref, *preds]}
    img_ref = loader.image(ref, scene=scene) if is_image[ref] else None
    size = None if img_ref is None else img_ref.shape[0]
    brdfs = [p for p in [ref, *preds] if not is_image[p]]
    if len(brdfs) > 1:
        loader.renders(brdfs, size, scene)  # all BRDF inputs in one quadrature pass (then cached)
    if img_ref is None:
        img_ref = loader.image(ref, scene=scene)
    table_ref = None if is_image[ref] else loader.table(ref)
    labels = input_labels([ref, *preds])
    rows, images, maps = {}, [], []
    for label, path in zip(labels[1:], preds):
        img = loader.image(path, size, scene)
        if img.shape != img_ref.shape:
            raise InputError(f"{path}, {ref}: image sizes differ ({img.shape[1]}x{img.shape[0]} "
                             f"and {img_ref.shape[1]}x{img_ref.shape[0]})")
        table = None if is_image[path] or table_ref is None else loader.table(path)
        rows[label] = score(img, img_ref, table, table_ref)
        images.append(img)
        maps.append(delta_e_2000_map(img, img_ref))
    top = max(DELTA_E_SCALE, float(np.ceil(max(np.percentile(m, 99.5) for m in maps))))
    # The pictures' silhouettes antialiased; the scores and the captions' numbers stay the renders'.
    shown = _antialiased(loader, [ref, *preds], [img_ref, *images], scene)

    n = len(preds) + 1
    fig, axes = pyplot().subplots(2, n, figsize=(2.6 * n + 0.9, 6.4), dpi=dpi, squeeze=False,
                                  layout="constrained")
    show_render(axes[0, 0], shown[0], f"reference\n{labels[0]}")
    axes[1, 0].text(0.5, 0.5, "per-pixel error\nagainst the\nreference\n(Delta E 2000)",
                    ha="center", va="center", fontsize=9, color="0.3", transform=axes[1, 0].transAxes)
    im = None
    for j, (label, img, de) in enumerate(zip(labels[1:], shown[1:], maps), start=1):
        show_render(axes[0, j], img, label)
        axes[0, j].set_xlabel(_caption(rows[label]), fontsize=8.5, loc="left")
        im = show_image(axes[1, j], delta_e_2000_map(img, shown[0]), cmap="inferno", vmin=0.0, vmax=top)
        axes[1, j].set_xlabel(f"mean {rows[label]['delta_e']:.2f}, max {float(de.max()):.1f}", fontsize=8.5)
    for ax in axes.ravel():
        bare_axes(ax)
    cb = fig.colorbar(im, ax=axes[1, 1:].tolist(), shrink=0.9, aspect=20, pad=0.02)
    cb.set_label("Delta E 2000", fontsize=9)
    fig.suptitle(f"{scene[:1].upper()}{scene[1:]} scene, quadrature renders (exposure 1, sRGB)", fontsize=10)

    save_png(fig, output)
    return rows
