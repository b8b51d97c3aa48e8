"""pbrt-v2's ``.brdf`` files: unstructured spectral BRDF samples (Cornell's measurements).

The format pbrt-v2 reads for its ``measured`` material (``src/materials/measured.cpp``,
``ReadFloatFile``), in which its ``scenes/brdfs`` ship five materials measured with
Cornell's gonioreflectometer (``acryl_blue``, ``cayman``, ``garnet_red``,
``krylon_blue``, ``mystique``: 1,439 samples at 31 wavelengths each). A text file of
numbers separated by white space, ``#`` starting a comment to the end of its line:

1. ``W``, the number of wavelengths;
2. the ``W`` wavelengths, nanometres;
3. then per sample ``theta_i phi_i theta_o phi_o`` (radians: polar angle and azimuth of
   the incident direction, toward the light, and of the outgoing one) and ``W`` BRDF
   values (1/sr), as many samples as the file holds.

:func:`read_pbrt_brdf` reads and checks it (the rows' checks are
:func:`brdfkit.io.measurements.measured_samples`') and converts the spectra to linear
sRGB (:mod:`brdfkit.io.spectral`). Refused in one line: a file that is not text, a
token that is not a number, a wavelength count that is not a positive whole number,
wavelengths not increasing or not covering 400-700 nm, values that do not make whole
samples (a truncated file, or a wavelength count that does not match the samples),
no samples, and the row refusals of the measurements (NaN, negative values, angles out
of range or in degrees).

May import: the ground floor, :mod:`brdfkit.io`; numpy.
"""

from __future__ import annotations

import os

import numpy as np

from brdfkit.atomic import check_input_file
from brdfkit.errors import FormatError
from brdfkit.io.csvfile import CsvTable, decode_text, read_text_bytes
from brdfkit.io.measurements import measured_samples
from brdfkit.io import samples as _samples
from brdfkit.io.samples import SampleSet

__all__ = ["read_pbrt_brdf", "MAX_WAVELENGTHS"]

MAX_WAVELENGTHS = 10_000
"""The most wavelengths a file may declare (RGL's spectral files hold 195)."""


def _numbers(path: str):
    """The file's numbers and the line of each, float64 and int64 ``(T,)``."""
    text = decode_text(path, read_text_bytes(path, ".brdf"))
    values, lines = [], []
    for number, line in enumerate(text.replace("\r\n", "\n").replace("\r", "\n").split("\n"), 1):
        tokens = line.split("#", 1)[0].split()
        for token in tokens:
            try:
                values.append(float(token))
            except ValueError:
                raise FormatError(path, f"line {number}: {token!r} is not a number") from None
        lines.extend([number] * len(tokens))
    return np.asarray(values, np.float64), np.asarray(lines, np.int64)


def read_pbrt_brdf(path) -> SampleSet:
    """Read a pbrt-v2 / Cornell ``.brdf`` file as a sample set in linear sRGB.

    Parameters
    ----------
    path
        The ``.brdf`` text file.

    Returns
    -------
    SampleSet
        One sample per measurement, values in linear sRGB (1/sr; spectra outside the
        sRGB gamut clipped to 0, counted in ``note``).

    Raises
    ------
    FormatError
        Naming the file (and the line where there is one): see the module's list.

    Examples
    --------
    >>> with open("tiny.brdf", "w") as f:
    ...     _ = f.write("# num wls\\n3\\n400 550 700\\n0.5 0 0.5 3.14159 0.2 0.2 0.2\\n")
    >>> s = read_pbrt_brdf("tiny.brdf")
    >>> len(s), [round(float(v), 2) for v in s.rgb[0]]
    (1, [0.2, 0.2, 0.2])
    """
    path = check_input_file(path)
    values, lines = _numbers(path)
    if values.size == 0:
        raise FormatError(path, "empty: no wavelength count, wavelengths or samples")
    count = values[0]
    if not (np.isfinite(count) and count == int(count) and 1 <= count <= MAX_WAVELENGTHS):
        raise FormatError(path, f"line {int(lines[0])}: the number of wavelengths is {count:g}, not a whole number "
                                f"from 1 to {MAX_WAVELENGTHS}")
    w = int(count)
    if values.size < 1 + w:
        raise FormatError(path, f"truncated: {values.size - 1} wavelength(s) after the count of {w}")
    wavelengths = values[1:1 + w]
    rest, rest_lines = values[1 + w:], lines[1 + w:]
    per = 4 + w
    if rest.size == 0:
        raise FormatError(path, "no samples after the wavelengths")
    if rest.size % per:
        whole = rest.size // per
        raise FormatError(path, f"line {int(rest_lines[whole * per])}: truncated or misshapen: {rest.size} values "
                                f"after the wavelengths are not whole samples of 4 angles and {w} values "
                                f"({whole} whole, then {rest.size % per} values; is the wavelength count right?)")
    limit = _samples.MAX_ROWS  # read when called, as every sample reader reads it
    if rest.size // per > limit:
        raise FormatError(path, f"{rest.size // per} samples, more than the limit of {limit}")
    table = CsvTable(path, "spherical+spectral", rest.reshape(-1, per), rest_lines[::per].copy())
    return measured_samples(table, "spherical", wavelengths, hint="the .brdf format holds radians")


def is_pbrt_brdf(path) -> bool:
    """Whether ``path`` is named as a ``.brdf`` file."""
    return os.path.splitext(os.fspath(path))[1].lower() == ".brdf"
