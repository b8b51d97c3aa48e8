"""The adaptive parameterization of Dupuy and Jakob 2018, fitted to an isotropic BRDF.

"An Adaptive Parameterization for Efficient Material Acquisition and Rendering" (ACM
TOG 37(6), SIGGRAPH Asia 2018) stores a material in the fields a ``.bsdf`` file holds:

* ``ndf``: a microfacet distribution ``D(m)``, the dominant eigenvector of the operator
  that maps ``D`` to ``4 cos(theta) f(w, w) sigma_D(w)``: retro-reflection ``f(w, w)`` of
  the material itself determines it (Dupuy et al. 2015, "Extracting Microfacet-based BRDF
  Parameters from Arbitrary Materials with Power Iterations"), found here by power
  iteration;
* ``sigma``: its projected area ``sigma(w) = integral D(m) max(0, m . w) dm``;
* ``vndf``: per incident elevation ``theta_i``, the distribution of visible normals
  ``D(m) max(0, wi . m) / sigma(wi)`` as a density over ``u = (sqrt(2 theta_m / pi),
  (phi_m - phi_i + pi) / 2 pi)``, whose sampling warp maps the unit square ("sample
  space") onto half vectors;
* ``rgb`` (or ``spectra``): the material on an ``N x N`` grid of sample space per
  ``theta_i``, stored as ``f(wi, wo) cos(theta_o) 4 sigma(wi) / D(m)`` (``jacobian = 1``:
  the readers multiply back ``D(m) / (4 sigma(wi))``), so that it is smooth where ``f``
  is peaked;
* ``luminance``: the luminance of ``f cos(theta_o)`` over the warp's density, on the same
  grid, which the renderers sample before the warp.

Three choices of brdfkit's, where the format leaves the writer free (readers only
interpolate what is stored):

* the warp's density is not the visible normals alone (:func:`_warp_density`): their
  ``u``-space density vanishes like ``u^3`` at the pole ``theta_m = 0``, where every
  isotropic material has its specular peak, so that a peak's core gets one column of
  sample space: the Jacobian of ``u`` -> solid angle enters with the power
  :attr:`FitSettings.pole` (2/3); a share :attr:`FitSettings.adapt` (0.3) follows the
  material's own ``f cos`` at each ``theta_i`` (a grazing sheen, which the NDF from
  retro-reflection does not show), and a share :attr:`FitSettings.mix` (0.1) the half
  vectors of cosine-distributed outgoing directions, which keeps the broad part of a
  peaked material covered (the luminance field compensates, so sampling stays
  proportional to ``f cos``);
* the NDF is kept above :data:`NDF_FLOOR` of its peak (retro-reflection vanishes at
  ``theta = pi/2``, and a fit's output can be exactly 0), so that ``f / D`` stays finite;
* every stored value is computed with the ``ndf`` and ``sigma`` *interpolants* the
  readers use, so that a reader's value at a grid node is the material's own (to float32
  rounding). Nodes whose outgoing direction falls below the horizon store 0.

May import: numpy, :mod:`brdfkit.errors`, :mod:`brdfkit.io.rgl.marginal`.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from brdfkit.io.rgl.marginal import Marginal2D

__all__ = ["FitSettings", "theta2u", "u2theta", "phi2u", "u2phi", "projected_area", "power_iteration_ndf",
           "fit_fields", "LUMINANCE"]

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
"""Rec. 709 / sRGB luminance weights of linear RGB."""
NDF_FLOOR = 1e-6
"""The fitted NDF is kept above this fraction of its peak."""


@dataclasses.dataclass(frozen=True)
class FitSettings:
    """Resolutions of a written file and the shape of its warp.

    Attributes
    ----------
    resolution
        ``N``: the sample-space grid of ``rgb`` / ``luminance`` is ``N x N`` per
        ``theta_i`` (the file grows as ``N^2``; ``docs/rgl-bsdf.md`` has error against
        size).
    theta_i
        Number of incident elevations, even in ``theta`` from 0 to
        :attr:`theta_i_max` degrees.
    ndf
        Nodes of the ``ndf`` and ``sigma`` interpolants over ``u_theta``.
    vndf
        ``(rows over phi, columns over theta)`` of each ``vndf`` slice.
    mix
        Share of the half vectors of cosine-distributed outgoing directions in the
        warp's density.
    adapt
        Share of the half vectors of outgoing directions distributed as the material's
        own ``Y(f) cos(theta_o)`` at each ``theta_i``.
    pole
        Power of the ``u`` -> solid angle Jacobian in the warp's microfacet part (1: the
        visible normals of Dupuy and Jakob).
    theta_i_max
        Largest incident elevation stored, degrees (beyond it the readers hold the last
        slice).
    iterations
        Power iterations of the NDF.
    """

    resolution: int = 64
    theta_i: int = 48
    ndf: int = 256
    vndf: tuple = (64, 128)
    mix: float = 0.1
    adapt: float = 0.3
    pole: float = 2.0 / 3.0
    theta_i_max: float = 89.0
    iterations: int = 60

    def check(self) -> "FitSettings":
        """``self``, or InputError naming the first setting out of range."""
        from brdfkit.errors import InputError

        for name, lo, hi in (("resolution", 2, 1024), ("theta_i", 2, 1024), ("ndf", 2, 1 << 16)):
            if not lo <= int(getattr(self, name)) <= hi:
                raise InputError(f"{name} must be in [{lo}, {hi}], got {getattr(self, name)!r}")
        if len(self.vndf) != 2 or min(self.vndf) < 2:
            raise InputError(f"vndf must be (rows, columns), each >= 2, got {self.vndf!r}")
        if not (0.0 <= self.mix and 0.0 <= self.adapt and self.mix + self.adapt < 1.0
                and 0.0 <= self.pole <= 1.0 and 0.0 < self.theta_i_max <= 90.0):
            raise InputError(f"mix, adapt >= 0 with mix + adapt < 1, pole in [0, 1], theta_i_max in (0, 90]: got "
                             f"{self.mix!r}, {self.adapt!r}, {self.pole!r}, {self.theta_i_max!r}")
        return self


def theta2u(theta):
    """Elevation (radians) -> the format's ``u = sqrt(2 theta / pi)``."""
    return np.sqrt(np.maximum(theta, 0.0) * (2.0 / math.pi))


def u2theta(u):
    """``u`` -> elevation ``u^2 pi / 2`` (radians)."""
    return np.square(u) * (math.pi / 2.0)


def phi2u(phi):
    """Azimuth (radians) -> ``(phi + pi) / (2 pi)``."""
    return (phi + math.pi) / (2.0 * math.pi)


def u2phi(u):
    """``u`` -> azimuth ``(2 u - 1) pi`` (radians)."""
    return (2.0 * u - 1.0) * math.pi


def theta_i_grid(settings: FitSettings) -> np.ndarray:
    """The incident elevations of a written file, radians ``(T,)``: even in ``theta``
    from 0 to ``theta_i_max``."""
    return np.linspace(0.0, math.radians(settings.theta_i_max), settings.theta_i)


def _azimuthal(theta, theta_m):
    """``integral_0^{2 pi} max(0, m . w) dphi`` for unit ``w`` at ``theta`` and ``m`` at
    ``theta_m`` (closed form), broadcast."""
    a = np.sin(theta) * np.sin(theta_m)
    b = np.cos(theta) * np.cos(theta_m)
    with np.errstate(invalid="ignore", divide="ignore"):
        phi0 = np.arccos(np.clip(-b / np.where(a > 0, a, 1.0), -1.0, 1.0))
    partial = 2.0 * (b * phi0 + a * np.sin(phi0))
    return np.where(a <= np.abs(b), 2.0 * math.pi * np.maximum(b, 0.0), partial)


def projected_area(ndf_nodes: np.ndarray, theta, fine: int = 2048) -> np.ndarray:
    """``sigma(w) = integral D(m) max(0, m . w) dm`` of an isotropic NDF given at evenly
    spaced ``u`` nodes (linear in ``u`` between them, as the readers interpolate it).

    Parameters
    ----------
    ndf_nodes
        ``D`` at ``u = k / (n - 1)``, ``(n,)``, 1/sr.
    theta
        Elevations of ``w``, radians ``(M,)``.
    fine
        Quadrature intervals over ``u`` (midpoint rule; ``d theta = pi u du``).

    Returns
    -------
    numpy.ndarray
        ``(M,)``, dimensionless (1 at ``theta = 0`` for a normalised ``D``).
    """
    return _area_matrix(ndf_nodes.size, np.asarray(theta, np.float64), fine) @ ndf_nodes


def _area_matrix(n: int, theta: np.ndarray, fine: int = 2048) -> np.ndarray:
    """The linear map of :func:`projected_area`: ``(M, n)``."""
    u = (np.arange(fine) + 0.5) / fine
    tm = u2theta(u)
    weight = np.sin(tm) * math.pi * u / fine  # sin(theta_m) d theta_m, per interval
    k = _azimuthal(theta[:, None], tm[None, :]) * weight[None, :]  # (M, fine)
    pos = u * (n - 1)
    i0 = np.minimum(pos.astype(np.int64), n - 2)
    f = pos - i0
    interp = np.zeros((fine, n))
    interp[np.arange(fine), i0] = 1.0 - f
    interp[np.arange(fine), i0 + 1] += f
    return k @ interp


def power_iteration_ndf(retro: np.ndarray, iterations: int = 60) -> np.ndarray:
    """The NDF whose microfacet retro-reflection is the material's (Dupuy et al. 2015).

    Iterates ``D <- 4 cos(theta) f_r(theta) sigma_D(theta)``, normalised so that
    ``sigma_D(0) = integral D(m) cos(theta_m) dm = 1``.

    Parameters
    ----------
    retro
        Luminance of ``f(w, w)`` at ``u_k = k / (n - 1)`` (``theta = u^2 pi / 2``),
        ``(n,)``, 1/sr, finite and non-negative.
    iterations
        Power iterations (the dominant eigenvector is reached in a few tens).

    Returns
    -------
    numpy.ndarray
        ``D`` at the same nodes, ``(n,)``, 1/sr; positive wherever ``retro`` is.
    """
    n = retro.size
    theta = u2theta(np.linspace(0.0, 1.0, n))
    area = _area_matrix(n, theta)
    gain = 4.0 * np.cos(theta) * np.maximum(retro, 0.0)
    d = np.ones(n)
    for _ in range(iterations):
        d = gain * (area @ d)
        s0 = area[0] @ d
        if not s0 > 0:
            return np.ones(n) / math.pi  # a black material: any NDF stores zeros
        d = d / s0
    return d


def _interp_u(nodes: np.ndarray, u) -> np.ndarray:
    """Linear interpolation of values at ``u = k / (n - 1)`` (clamped), as the readers'
    bilinear interpolants do along ``u``."""
    n = nodes.size
    pos = np.clip(u, 0.0, 1.0) * (n - 1)
    i0 = np.minimum(pos.astype(np.int64), n - 2)
    f = pos - i0
    return nodes[i0] * (1.0 - f) + nodes[i0 + 1] * f


def _half_vectors(u_m: np.ndarray, phi_i: float = 0.0) -> np.ndarray:
    """Unit half vectors of ``u`` coordinates ``(M, 2)`` (isotropic: azimuth relative to
    ``phi_i``)."""
    tm, pm = u2theta(u_m[:, 0]), u2phi(u_m[:, 1]) + phi_i
    return np.stack([np.cos(pm) * np.sin(tm), np.sin(pm) * np.sin(tm), np.cos(tm)], -1)


def _warp_density(brdf, ndf_nodes, wi, u_m, shape, settings):
    """The warp's density over ``u`` on the grid ``u_m`` ``(rows * cols, 2)`` for incident
    ``wi``, ``(rows, cols)``: a mixture, each part normalised on the grid, of

    * ``D(m) max(0, wi . m) J^pole`` (``pole = 1``: Dupuy and Jakob's visible normals),
    * the half vectors of outgoing directions distributed as the material's own
      ``Y(f) cos(theta_o)`` at this ``wi`` (share ``adapt``): what a sampler of ``f cos``
      draws, so that features of ``f`` that ``D`` (from retro-reflection) does not show,
      a grazing sheen, get sample space, also with ``J^pole``,
    * the half vectors of cosine-distributed ``wo`` (share ``mix``),

    where ``J = 2 pi^2 u sin(theta_m)`` is the Jacobian of ``u`` -> solid angle."""
    m = _half_vectors(u_m)
    dot = np.maximum(m @ wi, 0.0)
    wo = 2.0 * dot[:, None] * m - wi
    up = wo[:, 2] > 0
    jac = 2.0 * math.pi ** 2 * u_m[:, 0] * np.sin(u2theta(u_m[:, 0]))
    f = np.zeros(u_m.shape[0])
    if settings.adapt > 0 and up.any():
        f[up] = np.nan_to_num(brdf(np.broadcast_to(wi, (int(up.sum()), 3)), wo[up]), nan=0.0) @ LUMINANCE
    cos_o = np.maximum(wo[:, 2], 0.0)
    shares = (1.0 - settings.mix - settings.adapt, settings.adapt, settings.mix)
    densities = (_interp_u(ndf_nodes, u_m[:, 0]) * dot * jac ** settings.pole,
                 np.maximum(f, 0.0) * cos_o * dot * jac ** settings.pole, dot * cos_o * jac)
    out = np.zeros(shape)
    for share, density in zip(shares, densities):
        p = density.reshape(shape)
        total = Marginal2D(p).marg[0, -1] if share > 0 else 0.0
        if total > 0:
            out += share * p / total
    return out


def fit_fields(brdf, settings: FitSettings = FitSettings()) -> dict:
    """The parameterization's fields of an isotropic BRDF.

    Parameters
    ----------
    brdf
        ``brdf(wi, wo) -> (M, 3)``: the BRDF in 1/sr (linear RGB) at unit direction pairs
        ``(M, 3)`` above the horizon; NaN where unknown (stored as 0).
    settings
        Resolutions (:class:`FitSettings`).

    Returns
    -------
    dict
        float64 arrays: ``theta_i (T,)``, ``ndf (2, n)``, ``sigma (2, n)``,
        ``vndf (1, T, rows, cols)``, ``luminance (1, T, N, N)``, ``rgb (1, T, 3, N, N)``
        (what :mod:`brdfkit.io.rgl_bsdf` writes, in the readers' layout).
    """
    n = settings.ndf
    u_nodes = np.linspace(0.0, 1.0, n)
    t_nodes = u2theta(u_nodes)
    retro_dirs = np.stack([np.sin(t_nodes), np.zeros(n), np.cos(t_nodes)], -1)
    retro = np.nan_to_num(brdf(retro_dirs, retro_dirs) @ LUMINANCE, nan=0.0)
    ndf = power_iteration_ndf(retro, settings.iterations)
    # Where retro-reflection vanishes (at theta = pi/2 always, and wherever a fit's
    # output is exactly 0) so does D: a floor keeps f / D finite and the ratio smooth.
    ndf = np.maximum(ndf, NDF_FLOOR * ndf.max())
    sigma = projected_area(ndf, t_nodes)
    theta_i = theta_i_grid(settings)
    rows, cols = settings.vndf
    uu, vv = np.meshgrid(np.linspace(0, 1, cols), np.linspace(0, 1, rows))
    grid_u = np.stack([uu.reshape(-1), vv.reshape(-1)], -1)
    res = settings.resolution
    sx, sy = np.meshgrid(np.linspace(0, 1, res), np.linspace(0, 1, res))
    nodes = np.stack([sx.reshape(-1), sy.reshape(-1)], -1)
    vndf = np.empty((1, theta_i.size, rows, cols))
    lum = np.empty((1, theta_i.size, res, res))
    rgb = np.empty((1, theta_i.size, 3, res, res))
    for t, th in enumerate(theta_i):  # isotropic: wi in the xz plane, azimuths relative
        wi = np.array([math.sin(th), 0.0, math.cos(th)])
        sigma_i = float(_interp_u(sigma, theta2u(th)))
        vndf[0, t] = _warp_density(brdf, ndf, wi, grid_u, (rows, cols), settings)
        rgb[0, t], lum[0, t] = _slice_values(brdf, ndf, sigma_i, wi, vndf[0, t], nodes, res)
    return {"theta_i": theta_i, "ndf": np.stack([ndf, ndf]), "sigma": np.stack([sigma, sigma]),
            "vndf": vndf, "luminance": lum, "rgb": rgb}


def _slice_values(brdf, ndf, sigma_i, wi, density, nodes, res):
    """``rgb (3, N, N)`` and ``luminance (N, N)`` of one incident elevation: the BRDF
    where the warp of ``density`` takes each sample-space node."""
    u_m, pdf_u = Marginal2D(density).sample(nodes)
    m = _half_vectors(u_m)
    dot = m @ wi
    wo = 2.0 * dot[:, None] * m - wi
    # Below the horizon the value is 0 (readers return 0 there; the odd continuation
    # -f(mirror image) |cos| was tried and renders worse: it goes negative near it).
    up = wo[:, 2] > 0
    f = np.zeros((nodes.shape[0], 3))
    if up.any():
        f[up] = np.nan_to_num(brdf(np.broadcast_to(wi, (int(up.sum()), 3)), wo[up]), nan=0.0)
    f = np.maximum(f, 0.0) * np.maximum(wo[:, 2:3], 0.0)  # f cos(theta_o)
    d = _interp_u(ndf, u_m[:, 0])
    value = f * (4.0 * sigma_i) / np.maximum(d, 1e-30)[:, None]
    jac = np.maximum(2.0 * math.pi ** 2 * u_m[:, 0] * np.sin(u2theta(u_m[:, 0])), 1e-6) * 4.0 * np.maximum(dot, 1e-6)
    lum = (f @ LUMINANCE) / np.maximum(pdf_u / jac, 1e-30)
    floor = 1e-3 * lum.mean() if lum.mean() > 0 else 1.0
    lum = np.maximum(lum, floor)
    return value.T.reshape(3, res, res), lum.reshape(res, res)
