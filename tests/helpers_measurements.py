"""Small measurement files written by the tests: a pbrt-v2 / Cornell ``.brdf`` file and
measurement CSVs (spherical angles in radians or degrees, spectral or RGB values), and
their malformed variants for the bad-input battery (``test_bad_input_measurements.py``).

The material is a Lambertian of a known spectrum, so that every reader's result is known:
a flat spectrum ``rho`` gives linear sRGB ``(rho, rho, rho)``.
"""

from __future__ import annotations

import numpy as np

WAVELENGTHS = np.arange(400.0, 701.0, 10.0)  # Cornell's 31


def directions(n: int = 60, seed: int = 0):
    """``(theta_i, phi_i, theta_o, phi_o)`` radians ``(n,)`` each: incident azimuth 0, as
    Cornell's files have it, polar angles below 80 degrees."""
    rng = np.random.default_rng(seed)
    ti = rng.uniform(0.05, 1.35, n)
    to = rng.uniform(0.0, 1.38, n)
    po = rng.uniform(-np.pi, np.pi, n)
    return ti, np.zeros(n), to, po


def spectra(n: int, flat: float = 0.2, seed: int = 0):
    """``(n, 31)`` flat spectra of value ``flat``, with a random factor per sample."""
    rng = np.random.default_rng(seed)
    return np.outer(rng.uniform(0.5, 1.5, n), np.full(WAVELENGTHS.size, flat))


def brdf_text(angles, values, wavelengths=WAVELENGTHS, count=None) -> str:
    """A ``.brdf`` file's text, laid out as Cornell's (comments, one sample a line)."""
    lines = ["# num wls", str(len(wavelengths) if count is None else count), "", "# wls",
             " ".join(f"{w:g}" for w in wavelengths), "", "# theta i, phi i, theta s, phi_s, spectral sample values"]
    for a, v in zip(np.column_stack(angles), values):
        lines.append(" ".join(f"{x:.6f}" for x in (*a, *v)))
    return "\n".join(lines) + "\n"


def write_brdf(path, n: int = 60, seed: int = 0, **kw):
    angles = directions(n, seed)
    path.write_text(brdf_text(angles, spectra(n, seed=seed), **kw))
    return path


def csv_text(angles, values, header_angles=("theta_i", "phi_i", "theta_o", "phi_o"), degrees=False,
             value_names=None) -> str:
    names = list(header_angles) + list(value_names if value_names is not None else
                                       [f"{w:g}" for w in WAVELENGTHS])
    a = np.degrees(np.column_stack(angles)) if degrees else np.column_stack(angles)
    rows = [",".join(f"{x:.9g}" for x in (*r, *v)) for r, v in zip(a, values)]
    return ",".join(names) + "\n" + "\n".join(rows) + "\n"


def write_csv(path, n: int = 60, seed: int = 0, degrees=False):
    angles = directions(n, seed)
    names = tuple(f"{c}_deg" for c in ("theta_i", "phi_i", "theta_o", "phi_o")) if degrees else \
        ("theta_i", "phi_i", "theta_o", "phi_o")
    path.write_text(csv_text(angles, spectra(n, seed=seed), names, degrees))
    return path


def bad_measurement_files(folder) -> dict:
    """name -> (path, the message after "PATH: ") of malformed .brdf and CSV files."""
    n = 12
    angles = directions(n)
    good = spectra(n)
    out = {}

    def brdf(name, text, message):
        p = folder / f"{name}.brdf"
        p.write_text(text)
        out[f"brdf_{name}"] = (p, message)

    full = brdf_text(angles, good)
    body = full.splitlines()
    brdf("truncated", "\n".join(body[:-1]) + "\n" + " ".join(body[-1].split()[:20]) + "\n",
         "line 19: truncated or misshapen: 405 values after the wavelengths are not whole samples of 4 angles "
         "and 31 values (11 whole, then 20 values; is the wavelength count right?)")
    brdf("empty", "# nothing\n", "empty: no wavelength count, wavelengths or samples")
    nan = good.copy()
    nan[3, 5] = np.nan
    brdf("nan", brdf_text(angles, nan), "line 11: NaN or infinite value (1 such row)")
    neg = good.copy()
    neg[4, 2] = -0.05
    brdf("negative", brdf_text(angles, neg), "line 12: negative BRDF value (1 such row)")
    brdf("count", brdf_text(angles, good, count=30),
         "line 19: truncated or misshapen: 421 values after the wavelengths are not whole samples of 4 angles and 30 "
         "values (12 whole, then 13 values; is the wavelength count right?)")
    brdf("count_fraction", full.replace("\n31\n", "\n31.5\n", 1),
         "line 2: the number of wavelengths is 31.5, not a whole number from 1 to 10000")
    brdf("wavelengths_short", brdf_text(angles, good[:, :16], wavelengths=WAVELENGTHS[:16]),
         "wavelengths 400 to 550 nm do not cover 400-700 nm: not enough of the visible range for a colour")
    wide = list(angles)
    wide[2] = wide[2].copy()
    wide[2][6] = 1.7
    brdf("theta_range", brdf_text(wide, good), "line 14: theta_o outside [0, pi/2] radians (1 such row)")
    deg = [np.degrees(a) for a in angles]
    brdf("degrees", brdf_text(deg, good),
         f"line 8: theta_i outside [0, pi/2] radians ({deg[0][0]:g}: these look like degrees; the .brdf format holds "
         f"radians) ({int((deg[0] > np.pi / 2).sum())} such rows)")
    brdf("word", full.replace("400 410", "400 four", 1), "line 5: 'four' is not a number")

    def csv(name, text, message):
        p = folder / f"{name}.csv"
        p.write_text(text)
        out[f"csv_{name}"] = (p, message)

    header = ("theta_i", "phi_i", "theta_o", "phi_o")
    good_csv = csv_text(angles, good, header)
    lines = good_csv.splitlines()
    csv("truncated", "\n".join(lines[:-1]) + "\n" + ",".join(lines[-1].split(",")[:20]) + "\n",
        "line 13: 20 fields, the header names 35")
    csv("nan", csv_text(angles, nan, header), "line 5: NaN or infinite value (1 such row)")
    csv("negative", csv_text(angles, neg, header), "line 6: negative BRDF value (1 such row)")
    csv("wavelength_count", "\n".join([lines[0]] + [",".join(r.split(",")[:-1]) for r in lines[1:]]) + "\n",
        "line 2: 34 fields, the header names 35")
    csv("theta_range", csv_text(wide, good, header), "line 8: theta_o outside [0, pi/2] radians (1 such row)")
    shown = float(f"{deg[0][0]:.9g}")  # as the CSV holds it
    csv("degrees", csv_text(angles, good, header, degrees=True),
        f"line 2: theta_i outside [0, pi/2] radians ({shown:g}: these look like degrees; name the columns "
        f"theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg) ({int((deg[0] > np.pi / 2).sum())} such rows)")
    csv("radians_as_degrees", csv_text(angles, good, tuple(f"{c}_deg" for c in header)),
        f"columns theta_i_deg,theta_o_deg hold no polar angle above {max(angles[0].max(), angles[2].max()):.4g}: "
        f"radians in degree columns? (name them theta_i,theta_o)")
    csv("unknown", good_csv.replace("theta_o,", "theta_x,", 1),
        "line 1: unknown column(s) 'theta_x'; expected " + _expected())
    csv("wavelengths_short", csv_text(angles, good[:, :16], header, value_names=[f"{w:g}" for w in WAVELENGTHS[:16]]),
        "wavelengths 400 to 550 nm do not cover 400-700 nm: not enough of the visible range for a colour")
    return out


def _expected():
    from brdfkit.io.measurements import EXPECTED

    return EXPECTED
