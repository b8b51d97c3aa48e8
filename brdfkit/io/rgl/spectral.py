"""Spectra of RGB values for spectral ``.bsdf`` files (:func:`brdfkit.io.rgl_bsdf.write_bsdf`
with ``spectral=True``): the linear decomposition of Mallett and Yuksel 2019, at the
fewest wavelengths whose linear interpolation reproduces it.

May import: numpy; colour-science inside :func:`spectral_basis`.
"""

from __future__ import annotations

import numpy as np

__all__ = ["rgb_to_spectra", "spectral_basis", "SPECTRAL_TOLERANCE"]


def rgb_to_spectra(rgb: np.ndarray, axis: int = 0):
    """Spectra of linear sRGB values by Mallett and Yuksel 2019 ("Spectral Primary
    Decomposition for Rendering with sRGB Reflectance"), colour-science's
    ``RGB_to_sd_Mallett2019`` basis.

    The decomposition is *linear*: a value's spectrum is ``r S_r + g S_g + b S_b`` with
    non-negative basis spectra summing to 1, so it keeps a BRDF value's spectrum
    proportional to its RGB whatever its magnitude (BRDF values exceed 1, where the
    bounded sigmoid spectra of Jakob and Hanika 2019 cannot go), it commutes with the
    readers' interpolation, and white stays flat.

    Parameters
    ----------
    rgb
        Linear sRGB values with the channels on ``axis``.
    axis
        The channel axis.

    Returns
    -------
    tuple
        ``(spectra, wavelengths)``: the spectra with ``W`` wavelengths on ``axis``, and
        the wavelengths in nanometres ``(W,)`` (:func:`spectral_basis`).
    """
    values, wavelengths = spectral_basis()
    moved = np.moveaxis(np.asarray(rgb, np.float64), axis, -1)
    return np.moveaxis(moved @ values.T, -1, axis), wavelengths


SPECTRAL_TOLERANCE = 0.005
"""How far the readers' linear interpolation of the stored basis may stray from
colour-science's 5 nm basis (whose three functions sum to 1)."""


def spectral_basis(tolerance: float = SPECTRAL_TOLERANCE):
    """The basis of :func:`rgb_to_spectra` at the wavelengths a file stores: ``(values (W,
    3), wavelengths (W,) nm)``.

    colour-science's basis is sampled every 5 nm from 380 to 780 nm (81 wavelengths) and
    has sharp steps (green to red over 10 nm at 585 nm: every other sample would miss
    them by 0.25). The readers interpolate linearly between the stored wavelengths (and
    hold the end values outside), so the stored ones are the fewest of the 81, chosen
    greedily (the worst-interpolated wavelength added until none strays more than
    ``tolerance``), whose interpolant reproduces all 81 samples: 44 at the default.
    """
    from colour.recovery import MSDS_BASIS_FUNCTIONS_sRGB_MALLETT2019 as basis

    values = np.asarray(basis.values, np.float64)
    nm = np.asarray(basis.wavelengths, np.float64)
    keep = [0, nm.size - 1]
    while True:
        k = sorted(keep)
        error = np.abs(np.stack([np.interp(nm, nm[k], values[k, c]) for c in range(3)], -1) - values).max(1)
        if error.max() <= tolerance:
            return values[k], nm[k]
        keep.append(int(error.argmax()))
