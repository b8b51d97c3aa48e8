"""Spectral BRDF values to linear sRGB: the colour of a spectral measurement.

A gonioreflectometer measures a BRDF per wavelength; brdfkit's tables and models hold
linear sRGB, what MERL's tables hold. A spectral value ``rho(lambda)`` (1/sr) becomes
linear sRGB as a reflectance spectrum does under the sRGB white (colour-science):

1. CIE 1931 2 degree standard observer, CIE illuminant D65 (sRGB's white point, so no
   chromatic adaptation), ``X = k sum rho(lambda) S(lambda) xbar(lambda) dlambda`` (and
   ``Y``, ``Z``), ``k`` such that ``rho = 1`` at every wavelength gives ``Y = 1``;
2. the sums by ASTM E308-15's tristimulus weighting factors when the wavelengths are
   evenly spaced at 1, 5, 10 or 20 nm (``colour.sd_to_XYZ``'s default; its practice for a
   range narrower than 360-780 nm adds the weights outside it to the end wavelengths),
   else by integration every nanometre of the values interpolated linearly between the
   given wavelengths (colour-science holding the end values beyond them);
3. IEC 61966-2-1 sRGB's ``XYZ -> RGB`` matrix, no transfer function (linear).

Every step is linear in ``rho``, so the conversion is one ``(W, 3)`` matrix per set of
wavelengths (:func:`spectral_to_rgb_matrix`), built from colour-science's conversion of
each unit spectrum; a flat ``rho = c`` gives ``(c, c, c)``. A spectrum outside the sRGB
gamut (a saturated blue paint) gives a negative channel, which
:func:`spectra_to_rgb` clips to 0 and counts.

May import: the ground floor, numpy; colour-science inside the functions.
"""

from __future__ import annotations

import functools

import numpy as np

from brdfkit.errors import InputError

__all__ = ["spectral_to_rgb_matrix", "spectra_to_rgb", "check_wavelengths", "COVERED", "LIMITS",
           "COLORIMETRY"]

COVERED = (400.0, 700.0)
"""nm: the range a spectral measurement must cover (at least from 400 to 700 nm), where
the CIE 1931 observer's functions hold 99.7% of ``Y`` under D65."""
LIMITS = (300.0, 1100.0)
"""nm: wavelengths outside are refused (a unit slip: micrometres, metres, frequencies);
those outside 360-830 nm, the observer's range, weigh nothing."""
COLORIMETRY = "CIE 1931 2 degree observer, illuminant D65, linear sRGB (colour-science)"
"""The conversion, in words, for messages and records."""


def check_wavelengths(wavelengths) -> np.ndarray:
    """``wavelengths`` (nm) as float64 ``(W,)``, checked: finite, strictly increasing,
    within :data:`LIMITS`, covering :data:`COVERED`; InputError (a message without the
    file's name, which the reader adds) otherwise."""
    wl = np.asarray(wavelengths, np.float64).reshape(-1)
    if wl.size < 2 or not np.isfinite(wl).all():
        raise InputError(f"{wl.size} wavelength(s){'' if np.isfinite(wl).all() else ', not all finite'}: a "
                         f"spectrum needs at least 2 finite ones")
    if (np.diff(wl) <= 0).any():
        raise InputError("wavelengths not strictly increasing")
    if wl[0] < LIMITS[0] or wl[-1] > LIMITS[1]:
        raise InputError(f"wavelengths {wl[0]:g} to {wl[-1]:g}: outside {LIMITS[0]:g}-{LIMITS[1]:g} nm "
                         f"(nanometres expected)")
    if wl[0] > COVERED[0] or wl[-1] < COVERED[1]:
        raise InputError(f"wavelengths {wl[0]:g} to {wl[-1]:g} nm do not cover {COVERED[0]:g}-{COVERED[1]:g} nm: "
                         f"not enough of the visible range for a colour")
    return wl


@functools.lru_cache(maxsize=16)
def _matrix(wavelengths: tuple) -> np.ndarray:
    import warnings

    import colour

    wl = np.asarray(wavelengths, np.float64)
    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    illuminant = colour.SDS_ILLUMINANTS["D65"]
    steps = np.diff(wl)
    even = np.allclose(steps, steps[0], rtol=0, atol=1e-6) and float(steps[0]) in (1.0, 5.0, 10.0, 20.0)
    out = np.zeros((wl.size, 3))
    with warnings.catch_warnings():
        # colour-science warns when it aligns or interpolates a spectrum's shape: expected here.
        warnings.simplefilter("ignore")
        for j in range(wl.size):
            unit = np.zeros(wl.size)
            unit[j] = 1.0
            sd = colour.SpectralDistribution(dict(zip(wl, unit)))
            if even:
                xyz = colour.sd_to_XYZ(sd, cmfs, illuminant, method="ASTM E308")
            else:  # linear between the given wavelengths, every nanometre
                grid = np.arange(np.ceil(wl[0]), np.floor(wl[-1]) + 1.0)
                fine = colour.SpectralDistribution(np.interp(grid, wl, unit), grid)
                xyz = colour.sd_to_XYZ(fine, cmfs, illuminant, method="Integration")
            out[j] = xyz / 100.0  # colour-science scales a perfect reflector's Y to 100
    to_rgb = np.asarray(colour.RGB_COLOURSPACES["sRGB"].matrix_XYZ_to_RGB, np.float64)
    return out @ to_rgb.T


def spectral_to_rgb_matrix(wavelengths) -> np.ndarray:
    """The linear map of spectral values at ``wavelengths`` (nm) to linear sRGB.

    Parameters
    ----------
    wavelengths
        ``(W,)`` nm, strictly increasing, covering 400-700 nm (:func:`check_wavelengths`).

    Returns
    -------
    numpy.ndarray
        float64 ``(W, 3)``: ``rgb = values @ M`` for values ``(N, W)``.

    Raises
    ------
    InputError
        Wavelengths that :func:`check_wavelengths` refuses.

    Examples
    --------
    >>> import numpy as np
    >>> m = spectral_to_rgb_matrix(np.arange(400, 701, 10))
    >>> m.shape
    (31, 3)
    >>> [round(float(v), 3) for v in np.full(31, 0.5) @ m]  # a flat spectrum is grey
    [0.5, 0.5, 0.5]
    """
    wl = check_wavelengths(wavelengths)
    return _matrix(tuple(float(w) for w in wl)).copy()


def spectra_to_rgb(values, wavelengths):
    """Spectral values ``(N, W)`` (1/sr) as linear sRGB ``(N, 3)``, negatives clipped.

    Returns
    -------
    tuple
        ``(rgb, clipped)``: float64 ``(N, 3)`` non-negative, and the number of channel
        values that came out negative (spectra outside the sRGB gamut) and were set to 0.
    """
    rgb = np.asarray(values, np.float64) @ spectral_to_rgb_matrix(wavelengths)
    negative = rgb < 0
    return np.where(negative, 0.0, rgb), int(negative.sum())
