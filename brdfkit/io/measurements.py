"""Measurements as an instrument writes them: angle conventions, spectral or RGB values,
and the checks that turn them into a :class:`~brdfkit.io.samples.SampleSet`.

A gonioreflectometer's file gives each sample as a direction pair and a value per
channel. brdfkit reads the direction pair in these conventions (``docs/formats.md``,
"Measurement CSV"), named by a file's header (a ``_deg`` suffix: degrees):

* ``spherical``: ``theta_i,phi_i,theta_o,phi_o``, the polar angle and azimuth of ``wi``
  (toward the light) and of ``wo``, radians; ``spherical_deg``: the same names with
  ``_deg``, degrees;
* ``rusinkiewicz``: ``theta_h,theta_d,phi_d`` (Rusinkiewicz 1998), radians;
  ``rusinkiewicz_deg``: with ``_deg``, degrees;
* ``vectors``: ``wi_x,wi_y,wi_z,wo_x,wo_y,wo_z``, unit vectors in the local frame;

and the values as ``r,g,b`` (linear sRGB, 1/sr) or one column per wavelength, named
by the wavelength in nanometres (``400`` or ``400nm``), converted to linear sRGB by
:mod:`brdfkit.io.spectral` (CIE 1931 2 degree observer, D65).

:func:`measured_samples` checks the rows and makes the sample set. Refused, with the
line and how many rows share the problem: NaN or infinite values, polar angles outside
``[0, pi/2]`` (90 degrees) or azimuths outside ``[-2 pi, 2 pi]`` (360 degrees), with a
hint when radian columns hold what look like degrees (and a refusal of degree columns
whose polar angles all stay below ``pi/2``: radians, then), a direction below the
horizon, and negative values beyond rounding (:data:`ROUNDING` of the file's largest
value: rounding residues are read as 0, as in RGL's files).

May import: the ground floor, :mod:`brdfkit.geometry`, the other modules of
:mod:`brdfkit.io`; numpy.
"""

from __future__ import annotations

import math
import re

import numpy as np

from brdfkit.errors import FormatError, InputError
from brdfkit.geometry import HALF_PI, half_diff_from_io
from brdfkit.io.csvfile import CsvTable
from brdfkit.io.directions import HORIZON_TOLERANCE, checked_angles, checked_vectors, fold_phi_d
from brdfkit.io.samples import SampleSet

__all__ = ["ANGLE_SETS", "ROUNDING", "header_columns", "measured_samples", "spherical_vectors", "EXPECTED"]

ANGLE_SETS = {
    "spherical": ("theta_i", "phi_i", "theta_o", "phi_o"),
    "spherical_deg": ("theta_i_deg", "phi_i_deg", "theta_o_deg", "phi_o_deg"),
    "rusinkiewicz": ("theta_h", "theta_d", "phi_d"),
    "rusinkiewicz_deg": ("theta_h_deg", "theta_d_deg", "phi_d_deg"),
    "vectors": ("wi_x", "wi_y", "wi_z", "wo_x", "wo_y", "wo_z"),
}
"""Angle conventions by kind, their columns in order."""
RGB = ("r", "g", "b")
ROUNDING = 1e-6
"""A value at or above ``-ROUNDING`` times the file's largest magnitude is rounding of 0
(read as 0); one below it is refused."""
EXPECTED = ("angle columns theta_i,phi_i,theta_o,phi_o (radians; theta_i_deg,... for degrees), "
            "theta_h,theta_d,phi_d (or _deg) or wi_x,...,wo_z, then r,g,b or one column per wavelength "
            "in nm (400,410,... or 400nm,...)")
_WAVELENGTH = re.compile(r"([0-9]+(?:\.[0-9]*)?(?:e[+-]?[0-9]+)?)\s*(?:nm)?")
_TINY_SLACK = 1e-9


def _wavelength(column: str):
    m = _WAVELENGTH.fullmatch(column)
    return float(m.group(1)) if m else None


def header_columns(columns) -> dict:
    """The column set a measurement CSV's header names: ``{"ANGLES+VALUES": columns}``
    in the order :func:`measured_samples` takes them (the angles of one
    :data:`ANGLE_SETS` kind, then ``r,g,b`` or the wavelengths ascending); when the
    header names no such set, sets of every known name that cannot match it, so that
    :func:`brdfkit.io.csvfile.read_csv_table` names the unknown columns.

    Examples
    --------
    >>> header_columns(("theta_i", "phi_i", "theta_o", "phi_o", "410nm", "400nm"))
    {'spherical+spectral': ('theta_i', 'phi_i', 'theta_o', 'phi_o', '400nm', '410nm')}
    >>> "spherical+spectral" in header_columns(("theta_i", "phi_i", "theta_o", "phi_o", "x"))
    False
    """
    kind = next((k for k, cols in ANGLE_SETS.items() if set(cols) <= set(columns)), None)
    if kind is not None:
        rest = [c for c in columns if c not in ANGLE_SETS[kind]]
        if sorted(rest) == sorted(RGB):
            return {f"{kind}+rgb": ANGLE_SETS[kind] + RGB}
        nm = [_wavelength(c) for c in rest]
        if rest and all(w is not None for w in nm) and len(set(nm)) == len(nm):
            return {f"{kind}+spectral": ANGLE_SETS[kind] + tuple(c for _, c in sorted(zip(nm, rest)))}
    # No set: every known name, in sets that cannot match, so that the reader names the
    # columns it does not know (or says the known ones are not a set).
    known = {f"{k}+rgb": cols + RGB for k, cols in ANGLE_SETS.items()}
    known["wavelengths"] = tuple(c for c in columns if _wavelength(c) is not None) + ("",)
    return known


def spherical_vectors(theta_i, phi_i, theta_o, phi_o):
    """``(wi, wo)`` float64 ``(N, 3)`` of polar angles and azimuths in radians (``z`` the
    normal)."""
    def unit(t, p):
        t, p = np.asarray(t, np.float64), np.asarray(p, np.float64)
        return np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1)

    return unit(theta_i, phi_i), unit(theta_o, phi_o)


def _check_range(table: CsvTable, values, name: str, degrees: bool, polar: bool, hint: str) -> None:
    """Refuse values of column ``name`` outside a polar angle's or an azimuth's range."""
    top = (90.0 if polar else 360.0) if degrees else (HALF_PI if polar else 2 * math.pi)
    low = 0.0 if polar else -top
    bad = (values < low - _TINY_SLACK) | (values > top + _TINY_SLACK)
    unit = "degrees" if degrees else "radians"
    shown = ("[0, 90]" if polar else "[-360, 360]") if degrees else ("[0, pi/2]" if polar else "[-2 pi, 2 pi]")
    problem = f"{name} outside {shown} {unit}"
    if bad.any() and not degrees:
        # Degrees: beyond any angle's radians (2 pi) somewhere, and within degrees' range.
        in_deg = (values >= -_TINY_SLACK) & (values <= 90 + _TINY_SLACK) if polar else np.abs(values) <= 360
        if in_deg.all() and float(np.abs(values).max()) > 2 * math.pi:
            problem += f" ({float(values[bad][0]):g}: these look like degrees; {hint})"
    table.refuse(bad, problem)


def _directions(table: CsvTable, angles: str, data, hint: str):
    """``(theta_h, theta_d, phi_d)`` of the rows, each ``(N,)``, checked."""
    degrees = angles.endswith("_deg")
    names = ANGLE_SETS[angles]
    if angles == "vectors":
        wi, wo = checked_vectors(table, data[:, 0:3], data[:, 3:6])
    elif angles.startswith("spherical"):
        for k, name in enumerate(names):
            _check_range(table, data[:, k], name, degrees, k in (0, 2), hint)
        if degrees:
            _refuse_radians_as_degrees(table, data[:, [0, 2]], names[0::2])
        a = np.radians(data) if degrees else data
        wi, wo = spherical_vectors(a[:, 0], a[:, 1], a[:, 2], a[:, 3])
        table.refuse((wi[:, 2] < -HORIZON_TOLERANCE) | (wo[:, 2] < -HORIZON_TOLERANCE),
                     "direction below the horizon")
    else:
        for k, name in enumerate(names):
            _check_range(table, data[:, k], name, degrees, k < 2, hint)
        if degrees:
            _refuse_radians_as_degrees(table, data[:, 0:2], names[0:2])
        a = np.radians(data) if degrees else data
        wi, wo = checked_angles(table, a[:, 0], a[:, 1], a[:, 2])
    th, _, td, pd = half_diff_from_io(wi, wo)
    return np.asarray(th, np.float64), np.asarray(td, np.float64), fold_phi_d(pd)


def _refuse_radians_as_degrees(table: CsvTable, polar, names) -> None:
    if polar.shape[0] > 1 and float(np.abs(polar).max()) <= HALF_PI:
        raise FormatError(table.path, f"columns {','.join(names)} hold no polar angle above "
                                      f"{float(np.abs(polar).max()):.4g}: radians in degree columns? (name them "
                                      f"{','.join(n[:-4] for n in names)})")


def measured_samples(table: CsvTable, angles: str, wavelengths=None, *, hint: str) -> SampleSet:
    """Check a file's measurement rows and make them a sample set.

    Parameters
    ----------
    table
        The rows (:class:`brdfkit.io.csvfile.CsvTable`): the angles of the ``angles``
        kind (:data:`ANGLE_SETS`), then ``r,g,b`` or one value per wavelength.
    angles
        A kind of :data:`ANGLE_SETS`.
    wavelengths
        ``(W,)`` nm of spectral values, or ``None`` for ``r,g,b``.
    hint
        What to say of angles that look like degrees in radian columns (how the file
        names its unit).

    Returns
    -------
    SampleSet
        Linear sRGB values (1/sr), ``note`` saying how spectra were converted.

    Raises
    ------
    FormatError
        Naming the file, the first bad line and how many rows share the problem.
    """
    data = table.data
    table.refuse(~np.isfinite(data).all(axis=1), "NaN or infinite value")
    n_angles = len(ANGLE_SETS[angles])
    values = data[:, n_angles:]
    largest = float(np.abs(values).max()) if values.size else 0.0
    table.refuse((values < -ROUNDING * largest).any(axis=1), "negative BRDF value")
    values = np.maximum(values, 0.0)
    th, td, pd = _directions(table, angles, data[:, :n_angles], hint)
    note = ""
    if wavelengths is not None:
        from brdfkit.io.spectral import COLORIMETRY, check_wavelengths, spectra_to_rgb

        try:
            wl = check_wavelengths(wavelengths)
        except InputError as e:
            raise FormatError(table.path, str(e)) from None
        rgb, clipped = spectra_to_rgb(values, wl)
        note = (f"{values.shape[1]} wavelengths, {wl[0]:g}-{wl[-1]:g} nm, converted to RGB: {COLORIMETRY}"
                + (f"; {clipped} channel value(s) outside the sRGB gamut clipped to 0" if clipped else ""))
    else:
        rgb = values
    import os

    return SampleSet(th, td, pd, np.ascontiguousarray(rgb, np.float64), os.path.basename(table.path), note)
