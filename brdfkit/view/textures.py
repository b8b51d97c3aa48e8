"""Tables as float16 3D textures, and the page's binary blobs.

A MERL-grid table ``(90, 90, 180, 3)`` travels as an ``RGB16F`` 3D texture of width 180
(``phi_d``), height 90 (``theta_d``) and depth 90 (``theta_h``): the MERL file's own flat
order, 8.75 MB where the file has 35 MB of float64. Unmeasured cells (NaN) hold ``-1``
in every channel (a measured value is never negative: one below 0 is stored as 0), so
that the shader leaves them out of the trilinear lookup as
:func:`brdfkit.geometry.trilinear.lookup_trilinear` does. Values are multiplied by a
power of two that keeps the table's largest one below ``2^14`` (float16's range ends at
65504); the shader multiplies back.

A blob is bytes in the page: base64 text (4 bytes a 3), and, unless the page is written
for a browser without ``DecompressionStream``, gzip-compressed first (level 9, no time
stamp: the same bytes every run). Before compression, float16 arrays are split into
their low and high bytes (byte planes): the high bytes (sign, exponent, top mantissa
bits) of a smooth table repeat, and gzip finds them.

Examples
--------
>>> import numpy as np
>>> t = np.full((90, 90, 180, 3), 0.25)
>>> t[0, 0, 0] = np.nan
>>> half, scale = table_texture(t)
>>> half.dtype, half.shape, scale, float(half[0, 0]), float(half[1, 0])
(dtype('float16'), (1458000, 3), 65536.0, -1.0, 16384.0)
"""

from __future__ import annotations

import base64
import gzip
import math

import numpy as np

from brdfkit.errors import InputError

__all__ = ["table_texture", "blob", "encode_planes", "TOP"]

TOP = 2.0 ** 14
"""The largest stored value of a table texture (after its scale)."""


def table_texture(table, name: str = "table") -> tuple[np.ndarray, float]:
    """A dense table as float16 texels ``(1458000, 3)`` (MERL flat order) and the power of
    two it was multiplied by (``stored = value * scale``; ``-1``: not measured)."""
    t = np.asarray(table, np.float64).reshape(-1, 3)
    if t.shape[0] != 90 * 90 * 180:
        raise InputError(f"{name}: not a MERL-grid table ({np.asarray(table).shape})")
    measured = np.isfinite(t).all(axis=1)
    if np.isinf(t).any():
        raise InputError(f"{name}: the table holds infinite values")
    top = float(np.max(np.where(measured[:, None], t, 0.0), initial=0.0))
    scale = 2.0 ** int(math.floor(math.log2(TOP / top))) if top > 0 else 1.0
    scale = float(min(max(scale, 2.0 ** -60), 2.0 ** 60))
    out = np.where(measured[:, None], np.clip(t, 0.0, None) * scale, -1.0)
    return out.astype(np.float16), scale


def encode_planes(array: np.ndarray) -> bytes:
    """The bytes of a 2-byte array as byte planes (all low bytes, then all high bytes)."""
    raw = np.ascontiguousarray(array).view(np.uint8).reshape(-1, 2)
    return raw[:, 0].tobytes() + raw[:, 1].tobytes()


def blob(data: bytes, compress: bool = True, planes: bool = False) -> dict:
    """A blob of the page: ``{"enc": "gzip" | "raw", "planes": bool, "bytes": n, "data":
    base64}`` (``bytes``: the length once decoded)."""
    payload = gzip.compress(data, 9, mtime=0) if compress else data
    return {"enc": "gzip" if compress else "raw", "planes": bool(planes), "bytes": len(data),
            "data": base64.b64encode(payload).decode("ascii")}
