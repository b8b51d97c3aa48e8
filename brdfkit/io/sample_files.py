"""Any file of BRDF samples, opened by one reader: :func:`read_sample_file`.

``brdfkit sparse``, ``validate``, ``metrics`` and ``plan --within`` take measurements
as their labs wrote them:

* a ``*.brdf`` file: pbrt-v2 / Cornell spectral samples
  (:func:`brdfkit.io.pbrt_brdf.read_pbrt_brdf`);
* a CSV naming ``theta_h,theta_d,phi_d,r,g,b`` or ``wi_x,...,wo_z,r,g,b``: brdfkit's
  sample CSV (:func:`brdfkit.io.samples.read_samples`);
* any other CSV: a measurement CSV (:func:`read_measurement_csv`), the angle conventions
  of :data:`brdfkit.io.measurements.ANGLE_SETS` (radians or degrees, named by the
  header), values ``r,g,b`` or one column per wavelength (nm).

Spectral values become linear sRGB by colour-science (:mod:`brdfkit.io.spectral`: CIE
1931 2 degree observer, D65). Every reader refuses a bad file in one line.

May import: the ground floor, :mod:`brdfkit.io`; numpy.
"""

from __future__ import annotations

import os

from brdfkit.io.samples import SampleSet

__all__ = ["read_sample_file", "read_measurement_csv", "is_sample_file", "SAMPLE_SUFFIXES"]

SAMPLE_SUFFIXES = (".csv", ".brdf")
"""The suffixes of sample files (a CSV by its header, a pbrt-v2 ``.brdf``)."""


def is_sample_file(path) -> bool:
    """Whether ``path`` is named as a sample file (:data:`SAMPLE_SUFFIXES`)."""
    return os.path.splitext(os.fspath(path))[1].lower() in SAMPLE_SUFFIXES


def _header(path: str):
    """The lower-case column names of a CSV's header (first line neither blank nor a
    ``#`` comment, within the first MiB), or ``None``; unreadable files are left to the
    reader, which says why."""
    try:
        with open(path, "rb") as f:
            head = f.read(1 << 20).decode("utf-8-sig", "replace")
    except OSError:
        return None
    for line in head.replace("\r", "\n").split("\n"):
        if line.strip() and not line.lstrip().startswith("#"):
            return tuple(c.strip().lower() for c in line.split(","))
    return None


def read_measurement_csv(path) -> SampleSet:
    """Read a measurement CSV: a header naming one angle convention
    (:data:`brdfkit.io.measurements.ANGLE_SETS`) and the values, ``r,g,b`` or one column
    per wavelength (``400`` or ``400nm``), then one sample per line; the CSV rules
    (comments, blank lines, numbers) are those of the sample CSV (``docs/formats.md``).

    Returns
    -------
    SampleSet
        Linear sRGB values, 1/sr.

    Raises
    ------
    FormatError
        The CSV errors of :func:`brdfkit.io.csvfile.read_csv_table` (a row with another
        number of fields than the header: a wrong count of wavelength values), and the
        row refusals of :func:`brdfkit.io.measurements.measured_samples`.

    Examples
    --------
    >>> with open("m.csv", "w") as f:
    ...     _ = f.write("theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg,400,550,700\\n30,0,30,180,0.1,0.1,0.1\\n")
    >>> s = read_measurement_csv("m.csv")
    >>> len(s), round(float(s.theta_d[0]), 4)  # the mirror direction: theta_d = theta_i
    (1, 0.5236)
    """
    from brdfkit.io.csvfile import read_csv_table
    from brdfkit.io.measurements import ANGLE_SETS, EXPECTED, header_columns, measured_samples
    from brdfkit.io.samples import MAX_ROWS

    t = read_csv_table(path, header_columns, expected=EXPECTED, noun="sample", max_rows=MAX_ROWS)
    angles, values = t.kind.split("+")
    wavelengths = None
    if values == "spectral":
        names = header_columns(_header(t.path) or ())[t.kind][len(ANGLE_SETS[angles]):]
        wavelengths = [float(n[:-2] if n.endswith("nm") else n) for n in names]
    hint = "name the columns " + ",".join(f"{c}_deg" for c in ANGLE_SETS[angles])
    return measured_samples(t, angles, wavelengths, hint=hint)


def read_sample_file(path) -> SampleSet:
    """Read BRDF samples from any sample file, as its suffix and header say.

    Parameters
    ----------
    path
        A pbrt-v2 / Cornell ``.brdf`` file, brdfkit's sample CSV, or a measurement CSV
        (radians or degrees, RGB or spectral).

    Returns
    -------
    SampleSet
        Rusinkiewicz angles and linear sRGB values (1/sr); ``note`` says how spectral
        values were converted.

    Raises
    ------
    FormatError, InputError
        The reader's one-line refusal.
    """
    from brdfkit.atomic import check_input_file
    from brdfkit.io.pbrt_brdf import is_pbrt_brdf, read_pbrt_brdf
    from brdfkit.io.samples import ANGLE_COLUMNS, VECTOR_COLUMNS, read_samples

    path = check_input_file(path)
    if is_pbrt_brdf(path):
        return read_pbrt_brdf(path)
    header = _header(path)
    if header is not None and set(header) in (set(ANGLE_COLUMNS), set(VECTOR_COLUMNS)):
        return read_samples(path)
    return read_measurement_csv(path)
