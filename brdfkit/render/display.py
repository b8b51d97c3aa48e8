"""The display encoding: how a linear render becomes what a screen shows, in one place.

Every image metric, every PNG, the render-aligned error and the render design see the
same display-referred image (``docs/render.md``):

1. the linear-sRGB radiance times the fixed exposure :data:`EXPOSURE` (1.0: the
   reference scene's environment is scaled so that a white Lambertian sphere peaks near 1);
2. clipped to ``[0, 1]`` (what a display shows);
3. encoded with the sRGB OETF (IEC 61966-2-1), :func:`srgb_oetf`.

:func:`display_encode` does it in NumPy, :func:`display_encode_torch` in torch
(differentiable where not clipped: the screen error's gradient), and
:func:`display_slope` gives its derivative (the render design's Jacobian).

Examples
--------
>>> import numpy as np
>>> np.round(display_encode(np.array([[[0.0, 1.0, 2.0]]])), 6).tolist()  # clipped at 1
[[[0.0, 1.0, 1.0]]]
>>> float(np.round(srgb_oetf(0.5), 4))
0.7354
"""

from __future__ import annotations

import numpy as np

__all__ = ["EXPOSURE", "srgb_oetf", "display_linear", "display_encode", "display_encode_torch", "display_slope"]

EXPOSURE = 1.0
"""Fixed exposure (multiplier of linear radiance) applied before clipping to ``[0, 1]``."""

_KNEE = 0.0031308  # IEC 61966-2-1: linear below, power law above


def srgb_oetf(x):
    """The sRGB transfer function (IEC 61966-2-1) of linear values in ``[0, 1]``."""
    x = np.asarray(x)
    return np.where(x <= _KNEE, 12.92 * x, 1.055 * np.power(np.clip(x, _KNEE, None), 1 / 2.4) - 0.055)


def display_linear(img) -> np.ndarray:
    """Linear radiance times :data:`EXPOSURE`, clipped to ``[0, 1]``: the display's light
    before encoding (Delta E 2000 converts this to CIE L*a*b*)."""
    return np.clip(np.asarray(img, dtype=np.float64) * EXPOSURE, 0.0, 1.0)


def display_encode(img) -> np.ndarray:
    """Linear-sRGB radiance ``(H, W, 3)`` -> display values in ``[0, 1]``: times
    :data:`EXPOSURE`, clipped to ``[0, 1]``, sRGB OETF. What PSNR, SSIM and PNGs use."""
    return srgb_oetf(display_linear(img))


def display_encode_torch(img):
    """:func:`display_encode` in torch, differentiable where not clipped."""
    import torch

    x = torch.clamp(img * EXPOSURE, 0.0, 1.0)
    lo = x * 12.92
    hi = 1.055 * torch.clamp(x, min=_KNEE) ** (1 / 2.4) - 0.055
    return torch.where(x <= _KNEE, lo, hi)


def display_slope(img) -> np.ndarray:
    """``d display_encode / d img`` elementwise: the exposure times the OETF's slope, 0
    where the display clips."""
    x = np.asarray(img, dtype=np.float64) * EXPOSURE
    slope = np.where(x <= _KNEE, 12.92, 1.055 / 2.4 * np.clip(x, _KNEE, None) ** (1 / 2.4 - 1))
    return np.where((x >= 1.0) | (x <= 0.0), 0.0, slope) * EXPOSURE
