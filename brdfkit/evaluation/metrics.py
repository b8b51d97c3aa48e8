"""Error metrics: BRDF space and rendered images.

BRDF space (Gokbudak et al. 2024, following NBRDF, Sztrajman et al. 2021): the
cosine-weighted log RMSE :func:`brdf_log_rmse` over the MERL grid.

Image space (the paper reports PSNR, Delta E 2000 and SSIM on rendered images): all three
metrics see the *same display-referred image* (:mod:`brdfkit.render.display`: exposure
:data:`~brdfkit.render.display.EXPOSURE`, clipped to ``[0, 1]``). PSNR and SSIM take it
sRGB-encoded (:func:`~brdfkit.render.display.display_encode`), so errors are weighted
roughly perceptually, as in an 8-bit PNG but without quantisation; Delta E takes it
linear, converted to CIE XYZ (sRGB primaries, D65) and then to CIE L*a*b* relative to the
D65 white (``Y = 1`` is ``L* = 100``).

PSNR uses a peak of 1 (``data_range = 1``) and is ``inf`` for identical images; the CLI's
JSON output caps it at :data:`PSNR_CAP` dB so the JSON stays standard. SSIM is scikit-image's
``structural_similarity`` (7x7 uniform window, ``data_range = 1``, per channel, averaged).
Each image metric takes an optional boolean object ``mask`` ``(H, W)``: the mean is then over
the masked pixels only (for SSIM, the mean of the SSIM map over the mask). Without a mask
the whole image counts.

Delta E 2000 is colour-science's (``RGB_to_XYZ``, ``XYZ_to_Lab``, ``delta_E(method="CIE
2000")``), imported inside the functions that score colour, so that ``import brdfkit`` and
the jobs that score no colour stay light. SSIM is computed in NumPy as scikit-image computes
it (``tests/test_metrics.py`` compares them to 1e-9): scikit-image is not a dependency.
"""

from __future__ import annotations

import functools

import numpy as np

from brdfkit.errors import InputError
# Re-exported: the metrics' own display encoding, defined with the renderer's.
from brdfkit.render.display import EXPOSURE, display_encode, display_linear, srgb_oetf

__all__ = ["EXPOSURE", "PSNR_CAP", "PEAK_THETA_H_DEG", "brdf_log_rmse", "dark_at_grazing", "grazing_ratio", "darkest_ratio",
           "highlights",
           "display_encode", "srgb_oetf",
           "psnr", "delta_e_2000", "delta_e_2000_map", "ssim", "image_metrics", "score"]

PSNR_CAP = 100.0
"""PSNR reported in JSON for identical images (``psnr`` itself returns ``inf``)."""


@functools.lru_cache(maxsize=1)
def _grid_cos_i() -> np.ndarray:
    """``max(cos theta_i, 0)`` at every cell's grid angles, ``(90, 90, 180)``, read-only;
    computed once (0.3 s) rather than per score: a benchmark scores thousands of tables."""
    from brdfkit.geometry import cos_theta_i, grid_angles

    th, td, pd = np.meshgrid(*grid_angles(), indexing="ij")
    cos = np.clip(cos_theta_i(th, td, pd), 0.0, None)
    cos.setflags(write=False)
    return cos


def brdf_log_rmse(pred, ref) -> float:
    """Cosine-weighted log RMSE between two MERL-grid BRDF tables.

    ``sqrt(mean((ln(1 + rho_pred cos_i) - ln(1 + rho_ref cos_i))^2))`` with
    ``cos_i = max(cos theta_i, 0)`` at each cell's grid angles, the mean taken over the 3
    channels of the cells measured (finite in all channels) in *both* tables.

    Parameters
    ----------
    pred, ref
        Array-like ``(90, 90, 180, 3)``, BRDF in 1/sr, NaN where not measured.

    Returns
    -------
    float
        The RMSE (dimensionless, log space); 0 for identical tables.

    Raises
    ------
    InputError
        Wrong shapes, no cell measured in both, or values so negative that the log is
        undefined (``rho cos_i <= -1``).

    Examples
    --------
    >>> from brdfkit.testing.examples import lambertian_table
    >>> brdf_log_rmse(lambertian_table(), lambertian_table())
    0.0
    >>> round(brdf_log_rmse(lambertian_table((0.4, 0.25, 0.1)), lambertian_table()), 4)
    0.0533
    """
    from brdfkit.geometry import GRID_SHAPE

    pred = np.asarray(pred, dtype=np.float64)
    ref = np.asarray(ref, dtype=np.float64)
    shape = GRID_SHAPE + (3,)
    for name, a in (("prediction", pred), ("reference", ref)):
        if a.shape != shape:
            raise InputError(f"brdf_log_rmse: {name} has shape {a.shape}, expected {shape}")
    both = np.isfinite(pred).all(-1) & np.isfinite(ref).all(-1)
    if not both.any():
        raise InputError("brdf_log_rmse: no cell is measured in both tables")
    cos = _grid_cos_i()[both][:, None]
    p = np.log1p(pred[both] * cos)
    r = np.log1p(ref[both] * cos)
    if not (np.isfinite(p).all() and np.isfinite(r).all()):
        raise InputError("brdf_log_rmse: a table holds values too negative for the log (rho cos_i <= -1)")
    return float(np.sqrt(np.mean((p - r) ** 2)))


def dark_at_grazing(pred, ref, above_deg: float = 80.0) -> float:
    """Share of the measured cells with ``theta_h > above_deg`` (degrees) where a channel
    of ``pred`` is below a tenth of ``ref``: a reconstruction "orders of magnitude below
    the data at grazing angles" (``docs/notes/generalisation.md``), which cosine-weighted errors and renders
    barely see. Both ``(90, 90, 180, 3)`` tables in 1/sr; cells where ``ref`` is below
    1e-4 /sr (black there) or either is NaN are not counted; 0 when none is left."""
    from brdfkit.geometry import grid_angles

    rows = np.degrees(grid_angles()[0]) > above_deg
    p, r = np.asarray(pred, np.float64)[rows], np.asarray(ref, np.float64)[rows]
    ok = np.isfinite(p) & np.isfinite(r) & (r > 1e-4)
    return float(np.mean(p[ok] < 0.1 * r[ok])) if ok.any() else 0.0


def grazing_ratio(pred, ref, above_deg: float = 80.0) -> float | None:
    """The median of ``pred / ref`` over the cells and channels with ``theta_h >=
    above_deg`` (degrees) where ``ref`` is positive: whether the grazing rows of a
    reconstruction follow the material (1), or sit a band too dark or too bright, which
    renders barely see and a plot of the table shows (``docs/notes/compression.md``,
    "Grazing rows"). Both ``(90, 90, 180, 3)`` tables in 1/sr; NaN cells are not counted;
    ``None`` where no cell is left.

    Examples
    --------
    >>> import numpy as np
    >>> ref = np.full((90, 90, 180, 3), 0.2)
    >>> pred = ref.copy(); pred[85:] *= 4.0
    >>> grazing_ratio(pred, ref), grazing_ratio(ref, ref)
    (4.0, 1.0)
    """
    from brdfkit.geometry import grid_angles

    rows = np.degrees(grid_angles()[0]) >= above_deg
    p, r = np.asarray(pred, np.float64)[rows], np.asarray(ref, np.float64)[rows]
    ok = np.isfinite(p) & np.isfinite(r) & (r > 0)
    return float(np.median(p[ok] / r[ok])) if ok.any() else None


def darkest_ratio(pred, ref, at_least: float = 1.0) -> float | None:
    """The smallest ``pred / ref`` over the cells and channels where ``ref`` is at least
    ``at_least`` (1/sr): a black corner, a bright part of the material decoded orders of
    magnitude too dark (a value below 1e-3 means one). Both ``(90, 90, 180, 3)`` tables in
    1/sr; NaN cells are not counted; ``None`` where ``ref`` reaches ``at_least`` nowhere.

    Examples
    --------
    >>> import numpy as np
    >>> ref = np.full((90, 90, 180, 3), 2.0)
    >>> pred = ref.copy(); pred[0, 0, 0, 1] = 1e-4
    >>> darkest_ratio(pred, ref), darkest_ratio(ref, ref * 0.1)
    (5e-05, None)
    """
    r = np.asarray(ref, np.float64)
    p = np.asarray(pred, np.float64)
    ok = np.isfinite(r) & np.isfinite(p) & (r >= at_least)
    return float((p[ok] / r[ok]).min()) if ok.any() else None


PEAK_THETA_H_DEG = 5.0
"""The specular peak's region: ``theta_h`` below this many degrees (MERL's first 21
``theta_h`` rows, the square-root spacing's densest part)."""

_LUMINANCE = np.array([0.2126, 0.7152, 0.0722])  # linear sRGB (ITU-R BT.709)


def highlights(pred, ref, grazing_deg: float = 60.0) -> dict:
    """Invented or lost highlights: the peak region's brightness of ``pred`` against
    ``ref``'s, where renders of one scene may not look.

    The region is ``theta_h < PEAK_THETA_H_DEG``, split at ``theta_d = grazing_deg``
    into the specular peak (``"peak"``) and the grazing band (``"grazing"``: near-mirror
    reflection at grazing incidence, which a scene lit from the camera's side barely
    sees). Each is ``log10`` of the ratio of the two tables' mean luminance over the
    cells measured in both: ``+0.3`` is a peak twice as bright as the table's (a
    highlight invented, or too strong), ``-1`` one ten times darker (a highlight lost).

    Parameters
    ----------
    pred, ref
        ``(90, 90, 180, 3)`` tables in 1/sr, NaN where unmeasured.
    grazing_deg
        ``theta_d`` in degrees where the grazing band starts.

    Returns
    -------
    dict
        ``{"peak": float, "grazing": float}``; ``None`` for a region no cell of which is
        measured in both, or whose reference is black (below 1e-6 /sr).

    Examples
    --------
    >>> from brdfkit.testing.examples import lambertian_table
    >>> highlights(lambertian_table(), lambertian_table())
    {'peak': 0.0, 'grazing': 0.0}
    >>> twice = lambertian_table() * 2
    >>> round(highlights(twice, lambertian_table())["peak"], 4)
    0.301
    """
    from brdfkit.geometry import grid_angles

    th, td, _ = (np.degrees(a) for a in grid_angles())
    p = np.asarray(pred, np.float64)[th < PEAK_THETA_H_DEG] @ _LUMINANCE  # (rows, 90, 180)
    r = np.asarray(ref, np.float64)[th < PEAK_THETA_H_DEG] @ _LUMINANCE
    out = {}
    for key, band in (("peak", td < grazing_deg), ("grazing", td >= grazing_deg)):
        a, b = p[:, band], r[:, band]
        ok = np.isfinite(a) & np.isfinite(b)
        mean_a, mean_b = (float(x[ok].mean()) if ok.any() else float("nan") for x in (a, b))
        good = ok.any() and mean_b > 1e-6
        out[key] = round(float(np.log10(max(mean_a, 1e-12) / mean_b)), 6) if good else None
    return out


def _check_pair(pred, ref, mask):
    a = np.asarray(pred, dtype=np.float64)
    b = np.asarray(ref, dtype=np.float64)
    if a.ndim != 3 or a.shape[-1] != 3:
        raise InputError(f"image metrics: prediction has shape {a.shape}, expected (H, W, 3)")
    if b.shape != a.shape:
        raise InputError(f"image metrics: image sizes differ: {a.shape[:2]} and {b.shape[:2]}")
    if not (np.isfinite(a).all() and np.isfinite(b).all()):
        raise InputError("image metrics: an image holds NaN or infinite pixels")
    if mask is not None:
        mask = np.asarray(mask, dtype=bool)
        if mask.shape != a.shape[:2]:
            raise InputError(f"image metrics: mask has shape {mask.shape}, expected {a.shape[:2]}")
        if not mask.any():
            raise InputError("image metrics: the mask selects no pixel")
    return a, b, mask


def psnr(pred, ref, mask=None) -> float:
    """Peak signal-to-noise ratio (dB) of display-encoded images, peak 1.

    Parameters
    ----------
    pred, ref
        Linear-sRGB images ``(H, W, 3)``.
    mask
        Optional boolean ``(H, W)``: the mean squared error is taken over these pixels.

    Returns
    -------
    float
        ``10 log10(1 / MSE)``; ``inf`` for identical display images.

    Examples
    --------
    >>> import numpy as np
    >>> ref = np.full((8, 8, 3), 0.5)
    >>> psnr(ref, ref)
    inf
    >>> round(psnr(ref * 1.01, ref), 2)  # a 1% brighter render
    49.67
    """
    a, b, mask = _check_pair(pred, ref, mask)
    d = (display_encode(a) - display_encode(b)) ** 2
    mse = float(d[mask].mean() if mask is not None else d.mean())
    return float("inf") if mse == 0.0 else float(10.0 * np.log10(1.0 / mse))


def _lab(img_linear):
    """CIE L*a*b* (D65 white, CIE 1931 2 degree observer, ``Y = 1`` is ``L* = 100``) of
    linear sRGB ``(..., 3)``, by colour-science (sRGB primaries, no decoding)."""
    import colour

    xyz = colour.RGB_to_XYZ(img_linear, colour.RGB_COLOURSPACES["sRGB"], apply_cctf_decoding=False)
    d65 = colour.CCS_ILLUMINANTS["CIE 1931 2 Degree Standard Observer"]["D65"]
    return colour.XYZ_to_Lab(xyz, illuminant=d65)


def delta_e_2000(pred, ref, mask=None) -> float:
    """Mean CIEDE2000 colour difference (Sharma et al. 2005) per pixel.

    Linear sRGB times :data:`EXPOSURE`, clipped to ``[0, 1]``, -> CIE XYZ (sRGB primaries,
    D65) -> CIE L*a*b* (D65 white, CIE 1931 2 degree observer) -> colour-science's
    ``delta_E(..., method="CIE 2000")``, mean over pixels (over ``mask`` if given).

    Returns
    -------
    float
        Mean Delta E 2000 (0 for identical display images; about 1 is a just-noticeable
        difference).

    Examples
    --------
    >>> import numpy as np
    >>> ref = np.full((8, 8, 3), 0.5)
    >>> delta_e_2000(ref, ref)
    0.0
    >>> round(delta_e_2000(ref * [1.1, 1.0, 1.0], ref), 2)  # 10% more red
    4.04
    """
    a, b, mask = _check_pair(pred, ref, mask)
    de = delta_e_2000_map(a, b)
    return float(de[mask].mean() if mask is not None else de.mean())


def delta_e_2000_map(pred, ref) -> np.ndarray:
    """Per-pixel CIEDE2000 of two linear-sRGB images ``(H, W, 3)``: ``(H, W)``, the values
    :func:`delta_e_2000` averages (same display encoding), e.g. for false-colour error
    images (``brdfkit.figures.comparison_sheet``)."""
    import colour

    a, b, _ = _check_pair(pred, ref, None)
    return colour.delta_E(_lab(display_linear(a)), _lab(display_linear(b)), method="CIE 2000")


def ssim(pred, ref, mask=None) -> float:
    """Structural similarity of display-encoded images (Wang et al. 2004).

    scikit-image's ``structural_similarity`` (in NumPy) with ``data_range=1``, ``channel_axis=-1`` and
    its default 7x7 uniform window; the SSIM map averaged over ``mask`` if given.

    Returns
    -------
    float
        In ``[-1, 1]``, 1 for identical display images.

    Examples
    --------
    >>> import numpy as np
    >>> ref = np.random.default_rng(0).uniform(0, 1, (16, 16, 3))
    >>> ssim(ref, ref)
    1.0
    """
    a, b, mask = _check_pair(pred, ref, mask)
    if min(a.shape[:2]) < 7:
        raise InputError(f"ssim: images of {a.shape[0]}x{a.shape[1]} pixels are smaller than the 7x7 window")
    smap = _ssim_map(display_encode(a), display_encode(b))
    value = smap[3:-3, 3:-3].mean(axis=(0, 1)).mean() if mask is None else smap.mean(-1)[mask].mean()
    # the map's mean can round to 1 + 1e-16 for identical pixels
    return float(np.clip(value, -1.0, 1.0))


def _box7(x):
    """7 x 7 mean filter of ``(H, W, C)`` with ``scipy.ndimage``'s ``reflect`` edges
    (``uniform_filter``), by cumulative sums along each axis."""
    for axis in (0, 1):
        p = np.pad(x, [(3, 3) if i == axis else (0, 0) for i in range(3)], mode="symmetric")
        c = np.cumsum(p, axis=axis, dtype=np.float64)
        c = np.concatenate([np.zeros_like(np.take(c, [0], axis=axis)), c], axis=axis)
        n = x.shape[axis]
        x = (np.take(c, np.arange(7, 7 + n), axis=axis) - np.take(c, np.arange(n), axis=axis)) / 7
    return x


def _ssim_map(x, y):
    """The SSIM map ``(H, W, C)`` of two images in ``[0, 1]`` (scikit-image's
    ``structural_similarity`` with ``data_range=1``, its 7 x 7 uniform window and sample
    covariance, per channel), in NumPy."""
    c1, c2, norm = 0.01 ** 2, 0.03 ** 2, 49 / 48
    ux, uy = _box7(x), _box7(y)
    vx = norm * (_box7(x * x) - ux * ux)
    vy = norm * (_box7(y * y) - uy * uy)
    vxy = norm * (_box7(x * y) - ux * uy)
    return ((2 * ux * uy + c1) * (2 * vxy + c2)) / ((ux * ux + uy * uy + c1) * (vx + vy + c2))


def image_metrics(pred, ref, mask=None) -> dict:
    """``{"psnr", "delta_e", "ssim"}`` of a pair of linear-sRGB images (see the functions)."""
    return {"psnr": psnr(pred, ref, mask), "delta_e": delta_e_2000(pred, ref, mask),
            "ssim": ssim(pred, ref, mask)}


def score(pred_img, ref_img, pred_table=None, ref_table=None) -> dict:
    """Every error of a prediction against a reference, as ``brdfkit metrics`` and
    ``brdfkit bench`` report them.

    Parameters
    ----------
    pred_img, ref_img
        Linear-sRGB images ``(H, W, 3)`` (renders of the BRDFs, or given images).
    pred_table, ref_table
        The BRDF tables ``(90, 90, 180, 3)`` (1/sr) when both are BRDFs, else ``None``.

    Returns
    -------
    dict
        ``{"psnr", "delta_e", "ssim", "brdf_log_rmse"}``: :func:`image_metrics` with PSNR
        capped at :data:`PSNR_CAP` (so JSON stays standard), and :func:`brdf_log_rmse`
        (``None`` without both tables).

    Examples
    --------
    >>> import numpy as np
    >>> img = np.full((8, 8, 3), 0.5)
    >>> score(img, img)
    {'psnr': 100.0, 'delta_e': 0.0, 'ssim': 1.0, 'brdf_log_rmse': None}
    """
    out = image_metrics(pred_img, ref_img)
    out["psnr"] = min(out["psnr"], PSNR_CAP)
    both = pred_table is not None and ref_table is not None
    out["brdf_log_rmse"] = brdf_log_rmse(pred_table, ref_table) if both else None
    return out
