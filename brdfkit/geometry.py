"""BRDF geometry: Rusinkiewicz half/difference coordinates and the MERL grid.

Conventions (Rusinkiewicz 1998, "A New Change of Variables for Efficient BRDF
Representation"; Matusik et al. 2003, the MERL ``BRDFRead.cpp`` reader):

* Directions are unit vectors in the local shading frame, ``z`` the surface normal.
  ``wi`` is the incident (light) direction, ``wo`` the outgoing (view) direction, both
  pointing away from the surface.
* ``h = normalize(wi + wo)`` with angles ``(theta_h, phi_h)``; the difference vector
  ``d = R_y(-theta_h) R_z(-phi_h) wi`` with angles ``(theta_d, phi_d)``. Angles are in
  radians.
* For an isotropic BRDF only ``(theta_h, theta_d, phi_d)`` matter; by reciprocity
  (swapping ``wi`` and ``wo`` maps ``phi_d`` to ``phi_d + pi``) ``phi_d`` is folded into
  ``[0, pi)``.
* The MERL grid is ``(90, 90, 180)`` over ``(theta_h, theta_d, phi_d)``. Cell ``i`` of
  ``theta_h`` sits at ``(i / 90)**2 * pi / 2`` (the square-root spacing that puts more
  cells near the specular peak); ``theta_d`` and ``phi_d`` are uniform, cell ``j`` at
  ``j / 90 * pi / 2`` and cell ``k`` at ``k / 180 * pi``. The flat index is
  ``phi_d + 180 * (theta_d + 90 * theta_h)``.
* The network input ("HD vector") is the 6 Cartesian numbers ``(hx, hy, hz, dx, dy, dz)``
  with ``phi_h = 0``, as in NBRDF (Sztrajman et al. 2021) and the hypernetwork paper
  (Gokbudak et al. 2024).

Every function accepts NumPy arrays or PyTorch tensors (of any leading shape) and returns
the same kind, so the model and the renderer share this one definition. NumPy inputs
are computed in float64.
"""

from __future__ import annotations

import functools
import math

import numpy as np

__all__ = [
    "N_THETA_H", "N_THETA_D", "N_PHI_D", "GRID_SHAPE", "TABLE_SHAPE", "N_CELLS",
    "half_diff_from_io", "io_from_half_diff", "hd_vectors", "cos_theta_i",
    "grid_angles", "cell_angles", "cell_index", "fractional_indices",
    "valid_mask", "valid_cells", "grid_hd", "grid_directions", "grid_cosine_weight",
    "lookup_nearest",
]

N_THETA_H, N_THETA_D, N_PHI_D = 90, 90, 180
GRID_SHAPE = (N_THETA_H, N_THETA_D, N_PHI_D)
# A BRDF table in memory: [theta_h, theta_d, phi_d, rgb] (brdfkit.merl.read_merl).
TABLE_SHAPE = GRID_SHAPE + (3,)
N_CELLS = N_THETA_H * N_THETA_D * N_PHI_D
HALF_PI = math.pi / 2


def _xp(x):
    """The array namespace of ``x``: ``torch`` for tensors, else ``numpy``."""
    if type(x).__module__.startswith("torch"):
        import torch
        return torch
    return np


def _asarray(x):
    xp = _xp(x)
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
    wi, wo = _asarray(wi), _asarray(wo)
    xp = _xp(wi)
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
    theta_h, theta_d, phi_d = _asarray(theta_h), _asarray(theta_d), _asarray(phi_d)
    xp = _xp(theta_h)
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
    theta_h, theta_d, phi_d = _asarray(theta_h), _asarray(theta_d), _asarray(phi_d)
    xp = _xp(theta_h)
    st = xp.sin(theta_h)
    sd = xp.sin(theta_d)
    return xp.stack([st, xp.zeros_like(st), xp.cos(theta_h),
                     sd * xp.cos(phi_d), sd * xp.sin(phi_d), xp.cos(theta_d)], -1)


def cos_theta_i(theta_h, theta_d, phi_d):
    """``cos(theta_i)`` (the ``z`` of ``wi``) at Rusinkiewicz angles; may be negative
    below the horizon."""
    theta_h, theta_d, phi_d = _asarray(theta_h), _asarray(theta_d), _asarray(phi_d)
    xp = _xp(theta_h)
    return -xp.sin(theta_h) * xp.sin(theta_d) * xp.cos(phi_d) + xp.cos(theta_h) * xp.cos(theta_d)


def grid_angles():
    """Angles of the MERL grid cells: ``(theta_h (90,), theta_d (90,), phi_d (180,))``,
    radians, float64."""
    i = np.arange(N_THETA_H, dtype=np.float64)
    theta_h = (i / N_THETA_H) ** 2 * HALF_PI
    theta_d = np.arange(N_THETA_D, dtype=np.float64) / N_THETA_D * HALF_PI
    phi_d = np.arange(N_PHI_D, dtype=np.float64) / N_PHI_D * math.pi
    return theta_h, theta_d, phi_d


def cell_angles(index):
    """Angles ``(theta_h, theta_d, phi_d)`` of flat MERL cell indices (any shape)."""
    index = index if _xp(index) is not np else np.asarray(index)
    xp = _xp(index)
    k = index % N_PHI_D
    j = (index // N_PHI_D) % N_THETA_D
    i = index // (N_PHI_D * N_THETA_D)
    if xp is np:
        i, j, k = (a.astype(np.float64) for a in (i, j, k))
    else:
        i, j, k = (a.to(xp.get_default_dtype()) for a in (i, j, k))
    return (i / N_THETA_H) ** 2 * HALF_PI, j / N_THETA_D * HALF_PI, k / N_PHI_D * math.pi


def fractional_indices(theta_h, theta_d, phi_d):
    """Continuous grid coordinates ``(u_h, u_d, u_p)``: cell ``i`` sits at ``u = i``.

    ``theta_h`` and ``theta_d`` are clamped to ``[0, pi/2]``; ``phi_d`` is folded into
    ``[0, pi)`` (reciprocity), so ``u_p`` lies in ``[0, 180)``.
    """
    theta_h, theta_d, phi_d = _asarray(theta_h), _asarray(theta_d), _asarray(phi_d)
    xp = _xp(theta_h)
    u_h = xp.sqrt(xp.clip(theta_h, 0.0, HALF_PI) / HALF_PI) * N_THETA_H
    u_d = xp.clip(theta_d, 0.0, HALF_PI) / HALF_PI * N_THETA_D
    u_p = (phi_d % math.pi) / math.pi * N_PHI_D
    # phi_d just below a multiple of pi can round up to exactly 180.
    u_p = xp.where(u_p >= N_PHI_D - 1e-9, u_p - N_PHI_D, u_p)
    u_p = xp.clip(u_p, 0.0, None)
    return u_h, u_d, u_p


def cell_index(theta_h, theta_d, phi_d):
    """Flat MERL index of the cell containing each direction, as MERL's own reader
    computes it (floor of the continuous coordinate, clamped; ``phi_d`` folded)."""
    u_h, u_d, u_p = fractional_indices(theta_h, theta_d, phi_d)
    xp = _xp(u_h)
    # The tolerance keeps a cell's own angles, recomputed in floating point (sqrt of a
    # square), in that cell rather than one below.
    tol = 1e-9
    fl = (lambda a, n: np.clip(np.floor(a + tol), 0, n - 1).astype(np.int64)) if xp is np else \
        (lambda a, n: xp.clip(xp.floor(a + tol), 0, n - 1).long())
    return fl(u_p, N_PHI_D) + N_PHI_D * (fl(u_d, N_THETA_D) + N_THETA_D * fl(u_h, N_THETA_H))


def valid_mask():
    """Boolean ``(90, 90, 180)``: cells whose ``wi`` and ``wo`` are both above the horizon
    (the cells a MERL file can hold a measurement for)."""
    th, td, pd = np.meshgrid(*grid_angles(), indexing="ij")
    wi, wo = io_from_half_diff(th, td, pd)
    return (wi[..., 2] > 0) & (wo[..., 2] > 0)


@functools.lru_cache(maxsize=1)
def valid_cells() -> np.ndarray:
    """Flat indices of the cells of :func:`valid_mask`, int64, sorted, read-only; computed
    once per process."""
    cells = np.flatnonzero(valid_mask().reshape(-1))
    cells.setflags(write=False)
    return cells


@functools.lru_cache(maxsize=1)
def grid_hd() -> np.ndarray:
    """HD vectors of all MERL grid cells, float32 ``(1458000, 6)`` in flat-index order,
    read-only.

    Computed once per process (float64, then rounded) and shared: decoding every table
    and encoding every dense file reuse it. With ``phi_h = 0`` the half vector depends on
    ``theta_h`` alone and the difference vector on ``(theta_d, phi_d)`` alone, so the
    90 + 16,200 distinct vectors are computed and broadcast: the same numbers bit for bit
    as ``hd_vectors(*cell_angles(index))`` for every cell, in a tenth of the time (0.05 s
    against 0.49 s; it is part of every ``brdfkit decode`` / ``sparse`` process,
    ``docs/performance.md``).
    """
    n_dp = N_THETA_D * N_PHI_D
    th = cell_angles(np.arange(N_THETA_H) * n_dp)[0]
    _, td, pd = cell_angles(np.arange(n_dp))
    hd = np.empty((N_THETA_H, n_dp, 6), dtype=np.float32)
    zeros_h = np.zeros(N_THETA_H)
    hd[:, :, :3] = hd_vectors(th, zeros_h, zeros_h)[:, None, :3]
    hd[:, :, 3:] = hd_vectors(np.zeros(n_dp), td, pd)[None, :, 3:]
    hd = hd.reshape(N_CELLS, 6)
    hd.setflags(write=False)
    return hd


@functools.lru_cache(maxsize=1)
def grid_directions() -> tuple[np.ndarray, np.ndarray]:
    """``(wi, wo)`` of every MERL cell (``phi_h = 0``), float64 ``(90, 90, 180, 3)`` each,
    read-only; computed once per process (a synthetic table spends ~40% of its time on
    them otherwise)."""
    th, td, pd = np.meshgrid(*grid_angles(), indexing="ij")
    wi, wo = io_from_half_diff(th, td, pd)
    wi.setflags(write=False)
    wo.setflags(write=False)
    return wi, wo


@functools.lru_cache(maxsize=1)
def grid_cosine_weight() -> np.ndarray:
    """``max(cos theta_i, 0) * max(cos theta_o, 0)`` at every MERL cell, float64 flat
    ``(N_CELLS,)``, read-only; computed once per process (the cosine weight of Nielsen
    et al. 2015, which every PCA decode needs)."""
    wi, wo = grid_directions()
    w = (np.clip(wi[..., 2], 0.0, None) * np.clip(wo[..., 2], 0.0, None)).reshape(N_CELLS)
    w.setflags(write=False)
    return w


def lookup_nearest(table, theta_h, theta_d, phi_d):
    """MERL's own lookup: the value of the cell containing each direction.

    ``table`` has shape ``(90, 90, 180, C)``; the result ``(..., C)``.
    """
    idx = cell_index(theta_h, theta_d, phi_d)
    return table.reshape(N_CELLS, -1)[idx]
