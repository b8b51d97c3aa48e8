"""Rusinkiewicz half/difference coordinates of a direction pair, and the network's input.

Conventions (Rusinkiewicz 1998, "A New Change of Variables for Efficient BRDF
Representation"):

* Directions are unit vectors in the local shading frame, ``z`` the surface normal.
  ``wi`` is the incident (light) direction, ``wo`` the outgoing (view) direction, both
  pointing away from the surface.
* ``h = normalize(wi + wo)`` with angles ``(theta_h, phi_h)``; the difference vector
  ``d = R_y(-theta_h) R_z(-phi_h) wi`` with angles ``(theta_d, phi_d)``. Angles are in
  radians.
* For an isotropic BRDF only ``(theta_h, theta_d, phi_d)`` matter; by reciprocity
  (swapping ``wi`` and ``wo`` maps ``phi_d`` to ``phi_d + pi``) ``phi_d`` is folded into
  ``[0, pi)``.
* The network input ("HD vector") is the 6 Cartesian numbers ``(hx, hy, hz, dx, dy, dz)``
  with ``phi_h = 0``, as in NBRDF (Sztrajman et al. 2021) and the hypernetwork paper
  (Gokbudak et al. 2024).

Every function accepts NumPy arrays or PyTorch tensors (of any leading shape) and returns
the same kind, so the model and the renderer share this one definition. NumPy inputs
are computed in float64.

Examples
--------
>>> import numpy as np
>>> wi, wo = io_from_half_diff(np.array([0.0]), np.array([0.3]), np.array([0.0]))
>>> theta_h, phi_h, theta_d, phi_d = half_diff_from_io(wi, wo)
>>> [round(float(a[0]), 6) for a in (theta_h, theta_d, phi_d)]
[0.0, 0.3, 0.0]
>>> hd_vectors(0.0, 0.0, 0.0).tolist()
[0.0, 0.0, 1.0, 0.0, 0.0, 1.0]
"""

from __future__ import annotations

import numpy as np

__all__ = ["array_module", "as_array", "half_diff_from_io", "io_from_half_diff", "hd_vectors", "cos_theta_i"]


def array_module(x):
    """The array namespace of ``x``: ``torch`` for tensors, else ``numpy``."""
    if type(x).__module__.startswith("torch"):
        import torch
        return torch
    return np


def as_array(x):
    xp = array_module(x)
    return x if xp is not np else np.asarray(x, dtype=np.float64)


def _normalize(v, xp):
    n = xp.sqrt((v * v).sum(-1, keepdims=True))
    return v / xp.clip(n, 1e-30, None)


def half_diff_from_io(wi, wo):
    """Rusinkiewicz angles of a pair of directions.

    Parameters
    ----------
    wi, wo
        Incident and outgoing unit vectors, shape ``(..., 3)``, local frame.

    Returns
    -------
    tuple
        ``(theta_h, phi_h, theta_d, phi_d)``, each of shape ``(...)``, radians;
        ``theta_h, theta_d`` in ``[0, pi]``, ``phi_h, phi_d`` in ``(-pi, pi]``
        (not folded: see :func:`cell_index` for the MERL folding).
    """
    wi, wo = as_array(wi), as_array(wo)
    xp = array_module(wi)
    h = _normalize(wi + wo, xp)
    # atan2 rather than arccos: arccos loses half the digits next to theta = 0.
    theta_h = xp.arctan2(xp.sqrt(h[..., 0] ** 2 + h[..., 1] ** 2), h[..., 2])
    phi_h = xp.arctan2(h[..., 1], h[..., 0])
    cp, sp = xp.cos(phi_h), xp.sin(phi_h)
    ct, st = xp.cos(theta_h), xp.sin(theta_h)
    # d = R_y(-theta_h) R_z(-phi_h) wi
    x1 = cp * wi[..., 0] + sp * wi[..., 1]
    y1 = -sp * wi[..., 0] + cp * wi[..., 1]
    z1 = wi[..., 2]
    dx = ct * x1 - st * z1
    dz = st * x1 + ct * z1
    theta_d = xp.arctan2(xp.sqrt(dx ** 2 + y1 ** 2), dz)
    phi_d = xp.arctan2(y1, dx)
    return theta_h, phi_h, theta_d, phi_d


def io_from_half_diff(theta_h, theta_d, phi_d, phi_h=0.0):
    """Incident and outgoing directions from Rusinkiewicz angles (inverse of
    :func:`half_diff_from_io`).

    Parameters
    ----------
    theta_h, theta_d, phi_d, phi_h
        Angles in radians, broadcastable to a common shape ``(...)``.

    Returns
    -------
    tuple
        ``(wi, wo)``, unit vectors of shape ``(..., 3)``. Directions below the horizon
        (negative ``z``) are returned as they are; :func:`valid_mask` tells them.
    """
    theta_h, theta_d, phi_d = as_array(theta_h), as_array(theta_d), as_array(phi_d)
    xp = array_module(theta_h)
    if xp is np:
        phi_h = np.asarray(phi_h, dtype=np.float64)
    elif not isinstance(phi_h, xp.Tensor):
        phi_h = xp.as_tensor(phi_h, dtype=theta_h.dtype, device=theta_h.device)
    theta_h, theta_d, phi_d, phi_h = (np.broadcast_arrays if xp is np else xp.broadcast_tensors)(
        theta_h, theta_d, phi_d, phi_h)
    st, ct = xp.sin(theta_h), xp.cos(theta_h)
    sd, cd = xp.sin(theta_d), xp.cos(theta_d)
    dx, dy, dz = sd * xp.cos(phi_d), sd * xp.sin(phi_d), cd
    # wi = R_z(phi_h) R_y(theta_h) d
    x1 = ct * dx + st * dz
    z1 = -st * dx + ct * dz
    cp, sp = xp.cos(phi_h), xp.sin(phi_h)
    wi = xp.stack([cp * x1 - sp * dy, sp * x1 + cp * dy, z1], -1)
    h = xp.stack([st * cp, st * sp, ct], -1)
    wo = 2 * (wi * h).sum(-1, keepdims=True) * h - wi
    return wi, wo


def hd_vectors(theta_h, theta_d, phi_d):
    """The 6-number network input ``(hx, hy, hz, dx, dy, dz)`` with ``phi_h = 0``.

    Returns an array of shape ``(..., 6)``. Float32 tensors stay float32.
    """
    theta_h, theta_d, phi_d = as_array(theta_h), as_array(theta_d), as_array(phi_d)
    xp = array_module(theta_h)
    st = xp.sin(theta_h)
    sd = xp.sin(theta_d)
    return xp.stack([st, xp.zeros_like(st), xp.cos(theta_h),
                     sd * xp.cos(phi_d), sd * xp.sin(phi_d), xp.cos(theta_d)], -1)


def cos_theta_i(theta_h, theta_d, phi_d):
    """``cos(theta_i)`` (the ``z`` of ``wi``) at Rusinkiewicz angles; may be negative
    below the horizon."""
    theta_h, theta_d, phi_d = as_array(theta_h), as_array(theta_d), as_array(phi_d)
    xp = array_module(theta_h)
    return -xp.sin(theta_h) * xp.sin(theta_d) * xp.cos(phi_d) + xp.cos(theta_h) * xp.cos(theta_d)
