"""RGL ``.bsdf`` files (Dupuy and Jakob 2018): read, evaluate, write.

The format of RGL's measured-material database and of the renderers that read it
(Mitsuba 3's ``measured`` BSDF, pbrt-v4's ``measured`` material; reference loader
``powitacq``): a Mitsuba tensor file (:mod:`brdfkit.io.rgl.container`) holding the
adaptive parameterization of "An Adaptive Parameterization for Efficient Material
Acquisition and Rendering" (ACM TOG 37(6), 2018):

=============== =========================== ===========================================
field           dtype, shape                what
=============== =========================== ===========================================
``description`` uint8 ``(n,)``              UTF-8 text
``jacobian``    uint8 ``(1,)``              1: values are multiplied by ``D / 4 sigma``
``theta_i``     float32 ``(T,)``            incident elevations (radians, increasing)
``phi_i``       float32 ``(P,)``            incident azimuths (``P <= 2``: isotropic)
``ndf``         float32 ``(h, w)``          ``D`` over ``u_m`` (bilinear)
``sigma``       float32 ``(h, w)``          projected area over ``u_wi``
``vndf``        float32 ``(P, T, h, w)``    the warp's density over ``u_m``
``luminance``   float32 ``(P, T, N, N)``    sampling density over sample space
``rgb``         float32 ``(P, T, 3, N, N)`` values over sample space (RGB files), or
``spectra``     float32 ``(P, T, W, N, N)`` values per wavelength, with
``wavelengths`` float32 ``(W,)``            nanometres (spectral files)
=============== =========================== ===========================================

A reader evaluates ``f(wi, wo) cos(theta_o)`` at a direction pair by mapping the half
vector ``m`` to ``u_m = (sqrt(2 theta_m / pi), (phi_m - phi_i + pi) / 2 pi)``, inverting
the ``vndf`` warp there (parameters ``(phi_i, theta_i)``) to a sample-space point,
interpolating the values there, and (``jacobian = 1``) multiplying by
``D(u_m) / (4 sigma(u_wi))``. :class:`RglBsdf` does exactly that in NumPy
(:meth:`RglBsdf.eval`); :func:`read_bsdf_table` evaluates it at the MERL grid.
:func:`write_bsdf` fits the parameterization to a MERL table
(:mod:`brdfkit.io.rgl.fit`) and writes it, RGB or spectral.

brdfkit reads isotropic RGB files; a spectral or anisotropic file is refused in one
line, as is anything malformed; density values within float32 rounding of zero
(:data:`ROUNDING`) are read as 0. A measured file is not reciprocal: a table of it
(:meth:`RglBsdf.reciprocal_table`) combines the two conditionings by a rule
(:data:`RULES`); a render evaluates the file itself (:mod:`brdfkit.render.measured`).
Negative RGB values (a spectrum outside the sRGB gamut) are clipped to 0 in the tables.

May import: the ground floor, :mod:`brdfkit.geometry`, :mod:`brdfkit.io.rgl`; numpy
(colour-science inside :func:`brdfkit.io.rgl.spectral.spectral_basis`).
"""

from __future__ import annotations

import functools
import math
import os

import numpy as np

from brdfkit.errors import FormatError, InputError
from brdfkit.geometry import TABLE_SHAPE
from brdfkit.io.rgl.container import read_tensor_file, write_tensor_file
from brdfkit.io.rgl.fit import FitSettings, fit_fields, phi2u, theta2u
from brdfkit.io.rgl.marginal import Marginal2D
from brdfkit.io.rgl.spectral import SPECTRAL_TOLERANCE, rgb_to_spectra, spectral_basis

__all__ = ["RglBsdf", "read_bsdf", "read_bsdf_table", "write_bsdf", "rgb_to_spectra", "spectral_basis",
           "SPECTRAL_TOLERANCE", "FitSettings", "KIND", "ROUNDING", "RULES", "DEFAULT_RULE"]

KIND = "an RGL .bsdf file"
_FLOAT_FIELDS = ("theta_i", "phi_i", "ndf", "sigma", "vndf", "luminance")
ROUNDING = 1e-6
"""A density field's value at or above ``-ROUNDING`` times the field's largest magnitude
is rounding of zero (float32 holds 7 digits) and read as 0; one below it is refused."""
_CHUNK = 1 << 14  # pairs evaluated at once: their temporaries stay in the cache (a table: 1.3 s CPU, 2.0 s at 1 << 18)
_RANKS = {"theta_i": 1, "phi_i": 1, "ndf": 2, "sigma": 2, "vndf": 4, "luminance": 4, "rgb": 5,
          "description": 1, "jacobian": 1}


class RglBsdf:
    """An isotropic RGB ``.bsdf`` material, checked, ready to evaluate.

    Parameters
    ----------
    fields
        Field name -> array, as :func:`read_bsdf` checked them.
    path
        The file (for messages).

    Attributes
    ----------
    description
        The file's description text.
    theta_i
        Incident elevations, radians ``(T,)``.
    resolution
        ``N`` of the sample-space grid.
    """

    def __init__(self, fields: dict, path: str = "<memory>"):
        self.path = path
        self.description = bytes(fields["description"]).decode("utf-8", "replace")
        self.jacobian = bool(fields["jacobian"][0])
        self.theta_i = fields["theta_i"].astype(np.float64)
        self.phi_i = fields["phi_i"].astype(np.float64)
        self.resolution = int(fields["rgb"].shape[-1])
        params = (self.phi_i, self.theta_i)
        self._ndf = Marginal2D(fields["ndf"], normalize=False, sampling=False)
        self._sigma = Marginal2D(fields["sigma"], normalize=False, sampling=False)
        self._vndf = Marginal2D(fields["vndf"], params)
        self._rgb = Marginal2D(fields["rgb"], params, normalize=False, sampling=False, channels=True)

    def eval(self, wi, wo) -> np.ndarray:
        """What Mitsuba 3's ``measured`` BSDF returns: ``f(wi, wo) cos(theta_o)``.

        Parameters
        ----------
        wi, wo
            Unit directions ``(M, 3)`` in the local frame (``z`` the normal); ``wi`` is
            the direction the parameterization is conditioned on (Mitsuba's ``si.wi``).

        Returns
        -------
        numpy.ndarray
            float64 ``(M, 3)``, 1/sr times the cosine; 0 where either direction is at or
            below the horizon. Negative values of the file pass through.
        """
        wi = np.asarray(wi, np.float64).reshape(-1, 3)
        wo = np.asarray(wo, np.float64).reshape(-1, 3)
        out = np.zeros((wi.shape[0], 3))
        up = np.flatnonzero((wi[:, 2] > 0) & (wo[:, 2] > 0))
        for s in range(0, up.size, _CHUNK):  # chunks whose temporaries stay in the cache
            idx = up[s:s + _CHUNK]
            out[idx] = self._eval_up(wi[idx], wo[idx])
        return out

    def _eval_up(self, a, b):
        """:meth:`eval` of pairs above the horizon."""
        m = a + b
        m /= np.linalg.norm(m, axis=1, keepdims=True)
        theta_i = np.arctan2(np.hypot(a[:, 0], a[:, 1]), a[:, 2])
        phi_i = np.arctan2(a[:, 1], a[:, 0])
        theta_m = np.arctan2(np.hypot(m[:, 0], m[:, 1]), m[:, 2])
        phi_m = np.arctan2(m[:, 1], m[:, 0])
        v = phi2u(phi_m - phi_i)
        u_m = np.stack([theta2u(theta_m), v - np.floor(v)], -1)
        u_wi = np.stack([theta2u(theta_i), phi2u(phi_i)], -1)
        corners = self._vndf.corners((phi_i, theta_i))  # the rgb field's grids are the same
        sample, _ = self._vndf.invert(u_m, corners=corners)
        spec = self._rgb.eval(sample, corners=corners)
        if self.jacobian:
            spec *= (self._ndf.eval(u_m) / (4.0 * self._sigma.eval(u_wi)))[:, None]
        return spec

    def conditioned(self, wi, wo):
        """``(f_wi, f_wo)``, 1/sr ``(M, 3)`` each: ``eval(wi, wo) / cos(theta_o)`` (the
        parameterization conditioned on ``wi``) and ``eval(wo, wi) / cos(theta_i)``, which
        differ for a measured file; 0 at or below the horizon or where a file's warp has
        an empty row (NaN in Mitsuba too)."""
        wi = np.asarray(wi, np.float64).reshape(-1, 3)
        wo = np.asarray(wo, np.float64).reshape(-1, 3)
        up = ((wi[:, 2] > 0) & (wo[:, 2] > 0))[:, None]
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            a = self.eval(wi, wo) / wo[:, 2:3]
            b = self.eval(wo, wi) / wi[:, 2:3]
        return np.where(up & np.isfinite(a), a, 0.0), np.where(up & np.isfinite(b), b, 0.0)

    def brdf(self, wi, wo, rule: str = "least-squares") -> np.ndarray:
        """A reciprocal BRDF ``f(wi, wo) = f(wo, wi)`` in 1/sr ``(M, 3)``, non-negative,
        from the two conditionings ``a`` (on ``wi``) and ``b`` (on ``wo``) of
        :meth:`conditioned` by ``rule`` (:data:`RULES`):

        * ``least-squares``: ``(a cos_o^2 + b cos_i^2) / (cos_o^2 + cos_i^2)``, the value
          whose ``f cos`` is nearest, in the mean square, to what a renderer computes
          with either direction toward the camera (``a cos_o`` with the camera at
          ``wi``, ``b cos_i`` with it at ``wo``). Each conditioning weighs by the cosine
          it was divided by, so the one divided by a grazing cosine (where a file's
          interpolants are least exact) counts least;
        * ``mean``: ``(a + b) / 2``;
        * ``grazing``: the one conditioned on the more grazing direction (divided by the
          larger cosine; brdfkit's rule before these were measured);
        * ``steep``: the one conditioned on the direction nearer the normal.

        ``docs/rgl-bsdf.md`` measures them against renders of the file itself."""
        if rule not in RULES:
            raise InputError(f"unknown reciprocity rule {rule!r}; known: {', '.join(RULES)}")
        wi = np.asarray(wi, np.float64).reshape(-1, 3)
        wo = np.asarray(wo, np.float64).reshape(-1, 3)
        a, b = (np.maximum(f, 0.0) for f in self.conditioned(wi, wo))
        return _combine(a, b, wi[:, 2:3], wo[:, 2:3], rule)

    def reciprocal_table(self, rule: str = "least-squares"):
        """The material at the MERL grid's directions (Matusik et al. 2003) made
        reciprocal by ``rule`` (:meth:`brdf`), and the file's non-reciprocity.

        Returns
        -------
        tuple
            ``(table, non_reciprocity)``: float64 ``(90, 90, 180, 3)``, 1/sr, NaN below
            the horizon; the log RMS between the conditionings ``a``, ``b`` over the
            measurable cells and channels, ``sqrt(mean((ln(1 + a c) - ln(1 + b c))^2))``,
            ``c = cos theta_i cos theta_o`` (``a c``, ``b c``: the file's own ``f cos``
            times the other cosine, no division by a grazing one; ``brdf_log_rmse``'s
            mapping but for the second cosine), 0 for a reciprocal file.
        """
        if rule not in RULES:
            raise InputError(f"unknown reciprocity rule {rule!r}; known: {', '.join(RULES)}")
        wi, wo, cells = _grid_pairs()
        table = np.full((wi.shape[0], 3), np.nan)
        square, step = 0.0, _CHUNK
        for s in range(0, cells.size, step):
            idx = cells[s:s + step]
            a, b = (np.maximum(f, 0.0) for f in self.conditioned(wi[idx], wo[idx]))
            ci, co = wi[idx, 2:3], wo[idx, 2:3]
            table[idx] = _combine(a, b, ci, co, rule)
            square += float(np.sum((np.log1p(a * ci * co) - np.log1p(b * ci * co)) ** 2))
        return table.reshape(TABLE_SHAPE), float(np.sqrt(square / max(1, 3 * cells.size)))

    def to_table(self, rule: str = "least-squares") -> np.ndarray:
        """The table of :meth:`reciprocal_table`, without the non-reciprocity."""
        return self.reciprocal_table(rule)[0]


RULES = ("least-squares", "mean", "grazing", "steep")
"""The rules of :meth:`RglBsdf.brdf` (two conditionings to one reciprocal BRDF), the default first."""
DEFAULT_RULE = RULES[0]
"""The rule of ``brdfkit convert`` and of every table read from a ``.bsdf`` file."""


def _combine(a, b, cos_i, cos_o, rule):
    """``rule`` on the conditionings ``a`` (on ``wi``), ``b`` (on ``wo``), ``(M, 3)``; cosines ``(M, 1)``."""
    if rule == "least-squares":
        wa, wb = cos_o * cos_o, cos_i * cos_i
        return (a * wa + b * wb) / (wa + wb)
    if rule == "mean":
        return 0.5 * (a + b)
    return np.where((cos_i > cos_o) == (rule == "grazing"), b, a)


@functools.lru_cache(maxsize=1)
def _grid_pairs():
    """``(wi, wo, cells)`` of every MERL cell (``phi_h = 0``), float64 ``(N_CELLS, 3)`` each
    (read-only, computed once), from the grid's 1-D angles by broadcasting (as
    :func:`brdfkit.geometry.grid_directions`, several times faster than evaluating the
    trigonometry per cell), and the cells with both above the horizon."""
    from brdfkit.geometry import grid_angles

    th, td, pd = grid_angles()
    sh, ch = np.sin(th)[:, None, None], np.cos(th)[:, None, None]
    dx = (np.sin(td)[:, None] * np.cos(pd)[None, :])[None]
    dy = np.broadcast_to((np.sin(td)[:, None] * np.sin(pd)[None, :])[None], (th.size, td.size, pd.size))
    dz = np.cos(td)[None, :, None]
    wi = np.stack(np.broadcast_arrays(ch * dx + sh * dz, dy, ch * dz - sh * dx), -1)
    # wo = 2 (wi . h) h - wi, and wi . h = cos(theta_d)
    wo = np.stack(np.broadcast_arrays(2 * dz * sh - wi[..., 0], -dy, 2 * dz * ch - wi[..., 2]), -1)
    wi, wo = wi.reshape(-1, 3), wo.reshape(-1, 3)
    cells = np.flatnonzero((wi[:, 2] > 0) & (wo[:, 2] > 0))
    for a in (wi, wo, cells):
        a.flags.writeable = False
    return wi, wo, cells


def _check_fields(fields: dict, path: str) -> None:
    """Refuse what no reader could use: a spectral, anisotropic, incomplete or
    misshapen file, or values that are not finite or negative where a density is."""
    if "spectra" in fields or "wavelengths" in fields:
        raise FormatError(path, "spectral .bsdf file (fields 'spectra', 'wavelengths'): brdfkit reads RGB "
                                "files (field 'rgb'; RGL's database offers each material as RGB too)")
    missing = [k for k in _RANKS if k not in fields]
    if missing:
        raise FormatError(path, f"not an RGL .bsdf file: missing field{'s' if len(missing) > 1 else ''} "
                                f"{', '.join(repr(k) for k in missing)}")
    for name, rank in _RANKS.items():
        a = fields[name]
        want = np.uint8 if name in ("description", "jacobian") else np.float32
        if a.ndim != rank or a.dtype != want:
            raise FormatError(path, f"field '{name}': {a.dtype} of shape {a.shape}, expected {np.dtype(want)} "
                                    f"of rank {rank}")
    t, p = fields["theta_i"].size, fields["phi_i"].size
    if p > 2:
        raise FormatError(path, f"anisotropic material ({p} incident azimuths): brdfkit's tables are "
                                "isotropic; this file is refused rather than averaged")
    n = fields["rgb"].shape[-1]
    expect = {"vndf": (p, t) + fields["vndf"].shape[2:], "luminance": (p, t, n, n), "rgb": (p, t, 3, n, n),
              "jacobian": (1,)}
    for name, shape in expect.items():
        if fields[name].shape != shape:
            raise FormatError(path, f"field '{name}' has shape {fields[name].shape}, expected {shape}")
    for name in ("ndf", "sigma", "vndf", "luminance", "rgb"):
        if min(fields[name].shape[-2:]) < 2:
            raise FormatError(path, f"field '{name}' has shape {fields[name].shape}: a grid needs at least 2 x 2")
    if t < 1 or p < 1:
        raise FormatError(path, f"fields 'theta_i' and 'phi_i' hold {t} and {p} values: at least 1 each")
    for name in (*_FLOAT_FIELDS, "rgb"):
        a = fields[name]
        if not np.isfinite(a).all():
            bad = "NaN" if np.isnan(a).any() else "infinite"
            raise FormatError(path, f"field '{name}' holds {bad} values")
        if name != "rgb" and name != "phi_i" and (a < 0).any():
            # RGL's own files hold a few float32 rounding residues below zero (ilm_solo_m_68's
            # luminance: -3.98e-10 against a largest value near 1): zero, not a reason to refuse.
            if float(a.min()) < -ROUNDING * float(np.abs(a).max()):
                raise FormatError(path, f"field '{name}' holds negative values ({float(a.min()):.3g})")
            fields[name] = np.maximum(a, np.float32(0))
    for name in ("theta_i", "phi_i"):
        if (np.diff(fields[name].astype(np.float64)) <= 0).any():
            raise FormatError(path, f"field '{name}' is not strictly increasing")
    if fields["theta_i"].max() > math.pi / 2 + 1e-4:
        raise FormatError(path, f"field 'theta_i' goes past pi/2 ({float(fields['theta_i'].max()):.4f} rad)")
    if not (fields["sigma"] > 0).all():
        raise FormatError(path, "field 'sigma' holds zeros: the projected area must be positive")
    for name in ("vndf", "luminance"):
        sums = fields[name].reshape(p * t, -1).astype(np.float64).sum(1)
        if not (sums > 0).all():
            raise FormatError(path, f"field '{name}' has an all-zero slice: not a distribution")


def read_bsdf(path) -> RglBsdf:
    """Read and check an RGL ``.bsdf`` file.

    Parameters
    ----------
    path
        An isotropic RGB file (RGL's ``*_rgb.bsdf``, or one :func:`write_bsdf` wrote).

    Returns
    -------
    RglBsdf
        Ready to evaluate.

    Raises
    ------
    FormatError
        A malformed container (truncated, another magic or version), a missing or
        misshapen field, NaN, infinite or negative data, a spectral or anisotropic file.

    Examples
    --------
    >>> import numpy as np
    >>> from brdfkit.testing.examples import lambertian_table
    >>> write_bsdf("white.bsdf", lambertian_table((1.0, 1.0, 1.0)), FitSettings(resolution=16))
    >>> bsdf = read_bsdf("white.bsdf")
    >>> bsdf.theta_i.shape, bsdf.resolution
    ((48,), 16)
    >>> up = np.array([[0.0, 0.0, 1.0]])
    >>> [round(float(v), 5) for v in bsdf.brdf(up, up)[0] * np.pi]  # albedo 1, at a node of the grid
    [1.0, 1.0, 1.0]
    """
    path = os.fspath(path)
    fields = read_tensor_file(path, KIND)
    _check_fields(fields, path)
    return RglBsdf(fields, path)


def read_bsdf_table(path, rule: str = DEFAULT_RULE) -> np.ndarray:
    """An RGL ``.bsdf`` file at the MERL grid, made reciprocal by ``rule``
    (:meth:`RglBsdf.brdf`): float64 ``(90, 90, 180, 3)`` in 1/sr, NaN below the horizon
    (:meth:`RglBsdf.to_table`)."""
    return read_bsdf(path).to_table(rule)


def write_bsdf(path, table, settings: FitSettings = FitSettings(), *, spectral: bool = False,
               description: str = "") -> None:
    """Write a MERL table as an RGL ``.bsdf`` file, atomically.

    Parameters
    ----------
    path
        Output file.
    table
        ``(90, 90, 180, 3)``, 1/sr, NaN where not measured; evaluated between cells with
        :func:`brdfkit.geometry.trilinear.lookup_trilinear`.
    settings
        Resolutions (:class:`brdfkit.io.rgl.fit.FitSettings`).
    spectral
        Write ``spectra`` and ``wavelengths`` (:func:`rgb_to_spectra`; what pbrt-v4 and
        Mitsuba's spectral variants read) instead of ``rgb`` (Mitsuba's RGB variants).
    description
        Stored in the file's ``description``.

    Raises
    ------
    InputError
        A table of another shape, or with infinite or negative values.
    """
    from brdfkit.geometry import half_diff_from_io
    from brdfkit.geometry.trilinear import lookup_trilinear

    arr = np.asarray(table, np.float64)
    if arr.shape != TABLE_SHAPE:
        raise InputError(f"{os.fspath(path)}: cannot write a table of shape {arr.shape}, expected {TABLE_SHAPE}")
    if np.isinf(arr).any() or (arr < 0).any():
        raise InputError(f"{os.fspath(path)}: table holds infinite or negative values")

    def brdf(wi, wo):
        th, _, td, pd = half_diff_from_io(wi, wo)
        return lookup_trilinear(arr, th, td, pd)

    fields = fit_fields(brdf, settings)
    out = {"description": description, "jacobian": np.array([1], np.uint8),
           "theta_i": fields["theta_i"].astype(np.float32), "phi_i": np.zeros(1, np.float32)}
    for name in ("ndf", "sigma", "vndf", "luminance"):
        out[name] = fields[name].astype(np.float32)
    if spectral:
        spectra, wavelengths = rgb_to_spectra(fields["rgb"], axis=2)
        out["spectra"] = spectra.astype(np.float32)
        out["wavelengths"] = wavelengths.astype(np.float32)
    else:
        out["rgb"] = fields["rgb"].astype(np.float32)
    write_tensor_file(path, out)
