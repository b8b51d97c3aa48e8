"""Measurement directions (``brdfkit.io.directions``) and ``brdfkit sample --at``: the
directions CSV read and written, its bad forms refused in one line, and a table
measured at given directions (``brdfkit.acquisition.sampling.measure_samples``)."""

from __future__ import annotations

import numpy as np
import pytest

from brdfkit.io.directions import AGREEMENT_TOLERANCE, ANGLE_COLUMNS, VECTOR_COLUMNS, DirectionSet, \
    pair_disagreement, read_directions, write_directions
from brdfkit.errors import FormatError, InputError
from brdfkit.geometry import N_CELLS, cell_angles, valid_cells
from brdfkit.geometry.trilinear import lookup_trilinear
from brdfkit.io.merl import read_merl, write_merl
from brdfkit.io.samples import read_samples
from brdfkit.acquisition.sampling import draw_samples, measure_samples

from conftest import tmp_leftovers
from conftest import one_error_line, run_cli
from helpers_bad_input import nothing_written
from helpers_foundation import proxy_material
from helpers_model import material_table

BOTH = ",".join(ANGLE_COLUMNS + VECTOR_COLUMNS)


def _cells(n=50, seed=1):
    rng = np.random.default_rng(seed)
    return rng.choice(valid_cells(), size=n, replace=False)


def _directions(n=50, seed=1):
    return DirectionSet(*cell_angles(_cells(n, seed)))


def _write(path, header, rows):
    path.write_text(header + "\n" + "".join(",".join(repr(float(v)) for v in r) + "\n" for r in rows))
    return path


def _rot_z(v, a):
    c, s = np.cos(a), np.sin(a)
    return np.stack([c * v[:, 0] - s * v[:, 1], s * v[:, 0] + c * v[:, 1], v[:, 2]], 1)


# --- the file -------------------------------------------------------------------------------

def test_write_read_round_trip(tmp_path):
    d = _directions()
    write_directions(tmp_path / "d.csv", d, comments=["made by a test"])
    text = (tmp_path / "d.csv").read_text()
    assert text.startswith("# made by a test\n" + BOTH + "\n")
    got = read_directions(tmp_path / "d.csv")
    for k in ("theta_h", "theta_d", "phi_d"):
        np.testing.assert_array_equal(getattr(got, k), getattr(d, k))
    np.testing.assert_array_equal(got.lines, np.arange(3, 3 + len(d)))
    assert got.source == "d.csv" and not tmp_leftovers(tmp_path)


def test_angles_only_vectors_only_and_both_agree(tmp_path):
    d = _directions()
    wi, wo = d.vectors()
    angles = read_directions(_write(tmp_path / "a.csv", ",".join(ANGLE_COLUMNS),
                                    np.column_stack([d.theta_h, d.theta_d, d.phi_d])))
    # Vectors turned about the normal, wi and wo swapped in every other row, columns in
    # another order: the same measurements.
    turned_i, turned_o = _rot_z(wi, 0.7), _rot_z(wo, 0.7)
    swap = np.arange(len(d)) % 2 == 1
    turned_i[swap], turned_o[swap] = turned_o[swap].copy(), turned_i[swap].copy()
    vec = np.column_stack([turned_o, turned_i])
    vectors = read_directions(_write(tmp_path / "v.csv", "wo_x,wo_y,wo_z,wi_x,wi_y,wi_z", vec))
    both = read_directions(_write(tmp_path / "b.csv", ",".join(ANGLE_COLUMNS + VECTOR_COLUMNS),
                                  np.column_stack([d.theta_h, d.theta_d, d.phi_d, turned_i, turned_o])))
    for k in ("theta_h", "theta_d", "phi_d"):
        np.testing.assert_allclose(getattr(vectors, k), getattr(angles, k), atol=1e-9)
        np.testing.assert_array_equal(getattr(both, k), getattr(angles, k))  # given both, the angles


def test_pair_disagreement_is_a_rotation_and_swap_invariant_angle():
    d = _directions(200)
    wi, wo = d.vectors()
    assert pair_disagreement(wi, wo, _rot_z(wi, 2.0), _rot_z(wo, 2.0)).max() < 1e-12
    assert pair_disagreement(wi, wo, wo, wi).max() < 1e-12
    # A mirror image (wi at 30 degrees, wo at 60 degrees a quarter turn to the left, or to
    # the right) is another cell of the table: closest swapped, 30 degrees apart.
    def at(theta, phi):
        t, p = np.radians(theta), np.radians(phi)
        return np.array([[np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)]])

    assert pair_disagreement(at(30, 0), at(60, 90), at(30, 0), at(60, -90))[0] == pytest.approx(np.pi / 6)
    # theta_d 0.01 rad larger moves both directions by up to 0.01 rad: a disagreement
    # of that order (the measure adds the polar and the azimuthal part).
    other = DirectionSet(d.theta_h, np.clip(d.theta_d + 0.01, 0, 1.5), d.phi_d)
    assert 0.005 < np.median(pair_disagreement(wi, wo, *other.vectors())) < 0.03


BAD = {
    "empty": ("", "empty: no header and no direction rows"),
    "no header": ("0.1,0.2,0.3\n", "line 1: no header; the first line must name the columns "
                  "(theta_h,theta_d,phi_d and/or wi_x,wi_y,wi_z,wo_x,wo_y,wo_z)"),
    "sample columns": ("theta_h,theta_d,phi_d,r,g,b\n0.1,0.2,0.3,1,1,1\n",
                       "line 1: unknown column(s) 'r', 'g', 'b'; expected theta_h,theta_d,phi_d and/or "
                       "wi_x,wi_y,wi_z,wo_x,wo_y,wo_z"),
    "half a set": ("theta_h,theta_d\n0.1,0.2\n", "line 1: columns theta_h,theta_d are not a known set; "
                   "expected theta_h,theta_d,phi_d and/or wi_x,wi_y,wi_z,wo_x,wo_y,wo_z"),
    "no rows": ("theta_h,theta_d,phi_d\n# nothing\n", "no direction rows after the header"),
    "short row": ("theta_h,theta_d,phi_d\n0.1,0.2,0.3\n0.1,0.2\n", "line 3: 2 fields, the header names 3"),
    "text": ("theta_h,theta_d,phi_d\n0.1,abc,0.3\n", "line 2: 'abc' is not a number"),
    "nan": ("theta_h,theta_d,phi_d\n0.1,0.2,0.3\nnan,0.2,0.3\n", "line 3: NaN or infinite value (1 such row)"),
    "degrees": ("theta_h,theta_d,phi_d\n10,20,30\n12,20,30\n",
                "line 2: theta_h outside [0, pi/2] radians (2 such rows)"),
    "below horizon": ("theta_h,theta_d,phi_d\n1.2,1.2,0\n", "line 2: direction below the horizon (1 such row)"),
    "not unit": ("wi_x,wi_y,wi_z,wo_x,wo_y,wo_z\n0,0,2,0,0,1\n",
                 "line 2: direction is not a unit vector (|norm - 1| > 0.001) (1 such row)"),
    "vector below": ("wi_x,wi_y,wi_z,wo_x,wo_y,wo_z\n0.6,0,-0.8,0,0,1\n",
                     "line 2: direction below the horizon (z < 0) (1 such row)"),
    "opposite": ("wi_x,wi_y,wi_z,wo_x,wo_y,wo_z\n1,0,0,-1,0,0\n",
                 "line 2: wi and wo are opposite (no half vector) (1 such row)"),
    "disagree": (f"{BOTH}\n0,0,0,0,0,1,0,0,1\n0.3,0.2,0.1,0,0,1,0,0,1\n",
                 "line 3: the wi/wo vectors and theta_h,theta_d,phi_d describe different directions "
                 f"(by more than {AGREEMENT_TOLERANCE} rad) (1 such row)"),
    "binary": ("theta_h\x00", "not a CSV text file (binary content)"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_directions_refused_in_one_line(tmp_path, capsys, case):
    text, message = BAD[case]
    at = tmp_path / "at.csv"
    at.write_text(text)
    with pytest.raises(FormatError) as e:
        read_directions(at)
    assert str(e.value) == f"{at}: {message}"
    table = tmp_path / "t.binary"
    write_merl(table, material_table(1))
    out = tmp_path / "s.csv"
    code, _, err = run_cli(capsys, ["sample", table, "--at", at, "-o", out])
    assert code == 2
    assert one_error_line(err) == f"brdfkit: error: {at}: {message}"
    nothing_written(tmp_path, out)


# --- measuring a table at directions --------------------------------------------------------

def test_measure_at_cell_centres_reads_the_cells():
    table = material_table(1)
    cells = _cells(500)
    s = measure_samples(table, DirectionSet(*cell_angles(cells)), source="m")
    np.testing.assert_allclose(s.rgb, table.reshape(N_CELLS, 3)[cells], rtol=1e-12, atol=0)
    assert s.source == "m"


def test_measure_between_cells_is_the_trilinear_lookup():
    table = material_table(1)
    rng = np.random.default_rng(0)
    th, td, pd = rng.uniform(0, 0.7, 300), rng.uniform(0, 0.7, 300), rng.uniform(0, np.pi, 300)
    s = measure_samples(table, DirectionSet(th, td, pd))
    np.testing.assert_array_equal(s.rgb, lookup_trilinear(table, th, td, pd))
    np.testing.assert_array_equal(s.theta_h, th)


def test_measure_refuses_a_direction_without_measured_cells():
    table = np.full((90, 90, 180, 3), np.nan)
    table[:10] = 0.5
    d = DirectionSet(np.array([0.01, 1.0]), np.array([0.1, 0.1]), np.array([0.0, 0.0]), "d.csv", np.array([4, 7]))
    with pytest.raises(InputError, match=r"^d.csv: line 7: m has no measured cell around this direction "
                                         r"\(1 such direction\)$"):
        measure_samples(table, d, source="m")


def test_sample_at_reproduces_sample_n(tmp_path, capsys):
    """`brdfkit sample --at` at the cells `brdfkit sample -n` drew: the same sample set."""
    table = tmp_path / "t.binary"
    write_merl(table, material_table(1))
    code, _, err = run_cli(capsys, ["sample", table, "-n", "300", "--seed", "4", "-o", tmp_path / "n.csv"])
    assert code == 0, err
    drawn = read_samples(tmp_path / "n.csv")
    write_directions(tmp_path / "d.csv", DirectionSet(drawn.theta_h, drawn.theta_d, drawn.phi_d))
    code, _, err = run_cli(capsys, ["sample", table, "--at", tmp_path / "d.csv", "-o", tmp_path / "at.csv"])
    assert code == 0, err
    said = " ".join(err.split())  # the console wraps long lines
    assert f"wrote 300 samples of {table} at the directions of {tmp_path / 'd.csv'}" in said
    at = read_samples(tmp_path / "at.csv")
    np.testing.assert_array_equal(at.theta_h, drawn.theta_h)
    np.testing.assert_allclose(at.rgb, drawn.rgb, rtol=1e-12, atol=0)
    assert not tmp_leftovers(tmp_path)


@pytest.mark.slow
@pytest.mark.proxy
def test_sample_at_a_cell_centre_of_a_proxy(tmp_path_factory, tmp_path, capsys):
    path = proxy_material(tmp_path_factory, "teflon")
    table = read_merl(path)
    cells = np.array([0, 17 + 180 * (40 + 90 * 3), 5 + 180 * (10 + 90 * 60)])  # specular peak, two others
    write_directions(tmp_path / "d.csv", DirectionSet(*cell_angles(cells)))
    code, _, err = run_cli(capsys, ["sample", path, "--at", tmp_path / "d.csv", "-o", tmp_path / "s.csv"])
    assert code == 0, err
    np.testing.assert_allclose(read_samples(tmp_path / "s.csv").rgb, table.reshape(N_CELLS, 3)[cells],
                               rtol=1e-12, atol=0)
    # and the same as `draw_samples` gives for those cells
    assert np.isfinite(draw_samples(table, 5, seed=0).rgb).all()


@pytest.mark.parametrize("args, message", [
    ([], "give either -n N (random samples) or --at DIRECTIONS.csv, not neither"),
    (["-n", "3", "--at", "{d}"], "give either -n N (random samples) or --at DIRECTIONS.csv, not both"),
    (["--at", "{d}", "--seed", "3"], "--seed apply to random samples (-n), not to --at"),
    (["--at", "{d}", "--distribution", "cells"], "--distribution apply to random samples (-n), not to --at"),
    (["--at", "{missing}"], "{missing}: no such file"),
])
def test_sample_option_errors(tmp_path, capsys, args, message):
    table = tmp_path / "t.binary"
    write_merl(table, material_table(1))
    write_directions(tmp_path / "d.csv", _directions(5))
    subs = {"d": tmp_path / "d.csv", "missing": tmp_path / "missing.csv"}
    out = tmp_path / "s.csv"
    code, _, err = run_cli(capsys, ["sample", table, *[a.format(**subs) for a in args], "-o", out])
    assert code == 2
    assert one_error_line(err).startswith("brdfkit: error: " + message.format(**subs)), err
    nothing_written(tmp_path, out)


def test_sample_at_refuses_to_overwrite_its_directions(tmp_path, capsys):
    table = tmp_path / "t.binary"
    write_merl(table, material_table(1))
    write_directions(tmp_path / "d.csv", _directions(5))
    before = (tmp_path / "d.csv").read_bytes()
    code, _, err = run_cli(capsys, ["sample", table, "--at", tmp_path / "d.csv", "-o", tmp_path / "d.csv"])
    assert code == 2 and "output path is also an input" in one_error_line(err)
    assert (tmp_path / "d.csv").read_bytes() == before


def test_the_documented_example_reads(tmp_path):
    """The directions example of docs/formats.md (rounded to 6 digits) is a valid file
    whose angles and vectors agree."""
    import re
    from pathlib import Path

    text = (Path(__file__).resolve().parents[1] / "docs" / "formats.md").read_text()
    block = next(b for b in re.findall(r"```csv\n(.*?)```", text, re.S) if b.startswith("# brdfkit plan"))
    (tmp_path / "plan.csv").write_text(block)
    d = read_directions(tmp_path / "plan.csv")
    assert len(d) == 2 and d.lines.tolist() == [4, 5]
