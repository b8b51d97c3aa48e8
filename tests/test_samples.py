"""Sample sets: drawing from tables, CSV round trips, every malformed CSV, fuzzing."""

from __future__ import annotations

import math
import os

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from brdfkit.io import samples as samples_mod
from brdfkit.errors import FormatError, InputError
from brdfkit.geometry import GRID_SHAPE, N_CELLS, cell_index
from brdfkit.io.merl import read_merl
from brdfkit.io.samples import ANGLE_COLUMNS, VECTOR_COLUMNS, SampleSet, read_samples, write_samples
from brdfkit.acquisition.sampling import draw_samples

from conftest import tmp_leftovers
from helpers_foundation import measured_mask, merl_bytes, random_stored, random_table

ANGLE_HEADER = ",".join(ANGLE_COLUMNS)
VECTOR_HEADER = ",".join(VECTOR_COLUMNS)
GOOD_ANGLE_ROW = "0.3,0.4,1.0,0.1,0.2,0.3"


@pytest.fixture(scope="module")
def table():
    return random_table(seed=11)


# --- drawing ---------------------------------------------------------------------------

@pytest.mark.parametrize("distribution", ["angles", "cells"])
def test_draw_deterministic_and_measured_only(table, distribution):
    a = draw_samples(table, 3000, seed=4, distribution=distribution)
    b = draw_samples(table, 3000, seed=4, distribution=distribution)
    c = draw_samples(table, 3000, seed=5, distribution=distribution)
    assert len(a) == 3000
    for name in ("theta_h", "theta_d", "phi_d", "rgb"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    assert not np.array_equal(a.rgb, c.rgb)
    idx = cell_index(a.theta_h, a.theta_d, a.phi_d)
    assert measured_mask().reshape(-1)[idx].all()
    np.testing.assert_array_equal(a.rgb, table.reshape(N_CELLS, 3)[idx])
    assert np.isfinite(a.rgb).all() and a.rgb.dtype == np.float64


def test_distributions_differ_as_documented():
    # On a fully measured table, "angles" is uniform in theta_h (mean ~ pi/4, less half a
    # cell), "cells" uniform over cells whose theta_h are packed towards 0 (mean ~ pi/6).
    full = np.ones(GRID_SHAPE + (3,))
    by_angle = draw_samples(full, 20000, seed=0, distribution="angles").theta_h.mean()
    by_cell = draw_samples(full, 20000, seed=0, distribution="cells").theta_h.mean()
    assert abs(by_angle - (math.pi / 4 - 0.009)) < 0.03
    assert abs(by_cell - np.mean((np.arange(90) / 90) ** 2 * math.pi / 2)) < 0.03


def test_draw_from_few_measured_cells():
    t = np.full(GRID_SHAPE + (3,), np.nan)
    cells = [12345, 400000, 999999]
    t.reshape(N_CELLS, 3)[cells] = [[1, 2, 3], [4, 5, 6], [7, 8, 9]]
    s = draw_samples(t, 300, seed=0, distribution="cells")
    assert set(cell_index(s.theta_h, s.theta_d, s.phi_d).tolist()) == set(cells)


def test_draw_refuses_bad_arguments(table):
    with pytest.raises(InputError, match="at least 1"):
        draw_samples(table, 0)
    with pytest.raises(InputError, match="unknown distribution"):
        draw_samples(table, 5, distribution="stratified")
    with pytest.raises(InputError, match="no measured cells"):
        draw_samples(np.full(GRID_SHAPE + (3,), np.nan), 5)


def test_sampleset_helpers(table):
    s = draw_samples(table, 50, seed=1)
    assert s.hd().shape == (50, 6)
    assert (s.cos_i() >= 0).all()
    wi, wo = s.directions()
    np.testing.assert_allclose(wi[:, 2], s.cos_i(), atol=1e-12)
    assert (wi[:, 2] > 0).all() and (wo[:, 2] > 0).all()


# --- CSV -------------------------------------------------------------------------------

def test_csv_round_trip(table, tmp_path):
    s = draw_samples(table, 2000, seed=2)
    path = tmp_path / "s.csv"
    write_samples(path, s)
    assert path.read_text().splitlines()[0] == ANGLE_HEADER
    back = read_samples(path)
    for name in ("theta_h", "theta_d", "phi_d", "rgb"):
        np.testing.assert_array_equal(getattr(back, name), getattr(s, name))
    assert back.source == "s.csv" and not tmp_leftovers(tmp_path)


def test_vector_columns_equal_angle_form(table, tmp_path):
    s = draw_samples(table, 2000, seed=3)
    write_samples(tmp_path / "angles.csv", s)
    # any rotation about the normal (phi_h) names the same isotropic configuration
    phi_h = np.random.default_rng(0).uniform(-math.pi, math.pi, len(s))
    from brdfkit.geometry import io_from_half_diff
    wi, wo = io_from_half_diff(s.theta_h, s.theta_d, s.phi_d, phi_h)
    data = np.column_stack([wi, wo, s.rgb])
    # columns in another order: the header decides
    order = [VECTOR_COLUMNS.index(c) for c in ("r", "wo_x", "wo_y", "wo_z", "g", "wi_x", "wi_y", "wi_z", "b")]
    header = ",".join(VECTOR_COLUMNS[i] for i in order)
    lines = [header] + [",".join(f"{x:.17g}" for x in row[order]) for row in data]
    (tmp_path / "vectors.csv").write_text("\n".join(lines) + "\n")
    a, v = read_samples(tmp_path / "angles.csv"), read_samples(tmp_path / "vectors.csv")
    np.testing.assert_allclose(v.theta_h, a.theta_h, atol=1e-9)
    np.testing.assert_allclose(v.theta_d, a.theta_d, atol=1e-9)
    defined = np.sin(a.theta_d) > 1e-6  # phi_d is undefined at theta_d = 0
    d = (v.phi_d - a.phi_d)[defined] % math.pi
    assert np.minimum(d, math.pi - d).max() < 1e-9
    np.testing.assert_array_equal(v.rgb, a.rgb)
    assert ((v.phi_d >= 0) & (v.phi_d < math.pi)).all()


def test_comments_blank_lines_whitespace_crlf(tmp_path):
    p = tmp_path / "c.csv"
    p.write_bytes(("\ufeff# measured 2024\r\n\r\n THETA_H , theta_d,phi_d,r,g,b\r\n"
                   "# a comment\r\n 0.3 , 0.4,1.0,0.1,0.2,0.3\r\n\r\n").encode())
    s = read_samples(p)
    assert len(s) == 1 and s.theta_h[0] == 0.3 and s.rgb[0, 2] == 0.3


def test_phi_d_is_folded(tmp_path):
    p = tmp_path / "f.csv"
    p.write_text(f"{ANGLE_HEADER}\n0.3,0.4,{1.0 + math.pi},1,1,1\n0.3,0.4,-2.0,1,1,1\n")
    s = read_samples(p)
    np.testing.assert_allclose(s.phi_d, [1.0, math.pi - 2.0], atol=1e-12)


# every malformed CSV: (content, expected line number or None, message pattern)
H = ANGLE_HEADER + "\n"
V = VECTOR_HEADER + "\n"
BAD = {
    "no_header": ("0.3,0.4,1.0,0.1,0.2,0.3\n", 1, "no header"),
    "unknown_column": ("theta_h,theta_d,phi,r,g,b\n" + GOOD_ANGLE_ROW + "\n", 1, "unknown column.*'phi'"),
    "mixed_columns": ("theta_h,theta_d,phi_d,wi_x,g,b\n" + GOOD_ANGLE_ROW + "\n", 1, "not a known set"),
    "duplicate_column": ("theta_h,theta_h,phi_d,r,g,b\n" + GOOD_ANGLE_ROW + "\n", 1, "not a known set"),
    "text_in_number": (H + GOOD_ANGLE_ROW + "\n" + GOOD_ANGLE_ROW + "\n0.3,abc,1.0,0.1,0.2,0.3\n", 4,
                       "'abc' is not a number"),
    "text_first_row": (H + "0.3,0.4,1.0,red,0.2,0.3\n", 2, "'red' is not a number"),
    "empty_field": (H + GOOD_ANGLE_ROW + "\n0.3,,1.0,0.1,0.2,0.3\n", 3, "'' is not a number"),
    "too_few_fields": (H + GOOD_ANGLE_ROW + "\n0.3,0.4,1.0,0.1,0.2\n", 3, "5 fields, the header names 6"),
    "too_many_first": (H + "0.3,0.4,1.0,0.1,0.2,0.3,9\n" + GOOD_ANGLE_ROW + "\n", 2, "7 fields"),
    "all_rows_short": (H + "0.3,0.4,1.0,0.1,0.2\n0.3,0.4,1.0,0.1,0.2\n", 2, "5 fields"),
    "nan": (H + GOOD_ANGLE_ROW + "\n0.3,0.4,1.0,nan,0.2,0.3\n", 3, "NaN or infinite"),
    "inf": (H + "0.3,0.4,1.0,0.1,inf,0.3\n", 2, "NaN or infinite"),
    "huge_is_inf": (H + "0.3,0.4,1.0,0.1,1e999,0.3\n", 2, "NaN or infinite"),
    "negative_brdf": (H + GOOD_ANGLE_ROW + "\n" + "0.3,0.4,1.0,0.1,-0.2,0.3\n", 3, "negative BRDF"),
    "theta_h_range": (H + "2.0,0.4,1.0,0.1,0.2,0.3\n", 2, r"theta_h outside \[0, pi/2\]"),
    "theta_d_negative": (H + "0.3,-0.1,1.0,0.1,0.2,0.3\n", 2, r"theta_d outside \[0, pi/2\]"),
    "angles_below_horizon": (H + GOOD_ANGLE_ROW + "\n1.2,1.2,0.0,0.1,0.2,0.3\n", 3, "below the horizon"),
    "vector_below_horizon": (V + "0,0,1,0.6,0,0.8,1,1,1\n0,0.6,-0.8,0,0,1,1,1,1\n", 3, "below the horizon"),
    "vector_wo_below": (V + "0,0,1,0.6,0,-0.8,1,1,1\n", 2, "below the horizon"),
    "vector_not_unit": (V + "0,0,1,0.6,0,0.8,1,1,1\n0,0,2,0,0,1,1,1,1\n", 3, "not a unit vector"),
    "vector_zero": (V + "0,0,0,0,0,1,1,1,1\n", 2, "not a unit vector"),
    "vector_opposite": (V + "1,0,0,-1,0,0,1,1,1\n", 2, "opposite"),
    "comment_shifts_lines": (H + "# note\n\n" + GOOD_ANGLE_ROW + "\n0.3,0.4,1.0,0.1,0.2,x\n", 5, "'x' is not a number"),
    "form_feed_not_a_line_break": (H + GOOD_ANGLE_ROW + "\f" + GOOD_ANGLE_ROW + "\n", 2, "11 fields"),
    "header_only": (H, None, "no sample rows"),
    "comments_only": ("# nothing\n\n#\n", None, "empty"),
    "empty": ("", None, "empty"),
}


@pytest.mark.parametrize("name", sorted(BAD))
def test_bad_csv(tmp_path, name):
    content, line, pattern = BAD[name]
    path = tmp_path / f"{name}.csv"
    path.write_text(content)
    with pytest.raises(FormatError, match=pattern) as info:
        read_samples(path)
    message = str(info.value)
    assert message.startswith(f"{path}: ") and "\n" not in message
    if line is not None:
        assert f": line {line}: " in message


@pytest.mark.parametrize("data, pattern", [
    (b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR", "binary content"),
    (b"theta_h,theta_d,phi_d,r,g,b\n\xff\xfe\x80,1,2\n", "not UTF-8"),
    (merl_bytes(random_stored(0))[:4096], "binary content"),
])
def test_binary_junk(tmp_path, data, pattern):
    path = tmp_path / "junk.csv"
    path.write_bytes(data)
    with pytest.raises(FormatError, match=pattern):
        read_samples(path)


def test_too_many_rows(tmp_path, monkeypatch):
    monkeypatch.setattr(samples_mod, "MAX_ROWS", 3)
    path = tmp_path / "many.csv"
    path.write_text(H + "\n".join([GOOD_ANGLE_ROW] * 3) + "\n")
    assert len(read_samples(path)) == 3
    path.write_text(H + "\n".join([GOOD_ANGLE_ROW] * 4) + "\n")
    with pytest.raises(FormatError, match="4 sample rows, more than the limit of 3"):
        read_samples(path)


def test_missing_and_directory(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        read_samples(tmp_path / "nope.csv")
    with pytest.raises(InputError, match="is a directory"):
        read_samples(tmp_path)


def test_reports_count_of_bad_rows(tmp_path):
    path = tmp_path / "neg.csv"
    path.write_text(H + "0.3,0.4,1.0,-1,0.2,0.3\n" * 3)
    with pytest.raises(FormatError, match=r"line 2: negative BRDF value \(3 such rows\)"):
        read_samples(path)


# --- fuzzing: only our own errors escape -----------------------------------------------

csv_like = st.text(alphabet="0123456789.,-+eEnaif# \n\r\t", max_size=300)
fuzz_bytes = st.one_of(
    st.binary(max_size=400),
    csv_like.map(lambda s: (ANGLE_HEADER + "\n" + s).encode()),
    csv_like.map(lambda s: (VECTOR_HEADER + "\n" + s).encode()),
    st.text(max_size=200).map(lambda s: (ANGLE_HEADER + "\n" + s).encode("utf-8", "surrogatepass")),
)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=fuzz_bytes)
def test_fuzz_read_samples(tmp_path, data):
    path = tmp_path / "fuzz.csv"
    path.write_bytes(data)
    try:
        s = read_samples(path)
    except InputError as e:  # FormatError included
        assert str(path) in str(e) and "\n" not in str(e)
        return
    assert isinstance(s, SampleSet) and len(s) >= 1
    assert np.isfinite(s.rgb).all() and (s.rgb >= 0).all()


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.one_of(st.binary(max_size=200),
                      st.binary(max_size=200).map(lambda b: np.array([90, 90, 180], "<i4").tobytes() + b)))
def test_fuzz_read_merl(tmp_path, data):
    path = tmp_path / "fuzz.binary"
    path.write_bytes(data)
    with pytest.raises(InputError) as info:
        read_merl(path)
    assert str(path) in str(info.value)


@settings(max_examples=4, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(seed=st.integers(0, 2**32 - 1))
def test_fuzz_read_merl_full_size(tmp_path, seed):
    # right size and header, random payload bytes: a table (NaN where negative) or a
    # FormatError for the NaN/Inf bit patterns, nothing else
    payload = np.random.default_rng(seed).bytes(3 * N_CELLS * 8)
    path = tmp_path / "fuzz.binary"
    path.write_bytes(np.array([90, 90, 180], "<i4").tobytes() + payload)
    try:
        t = read_merl(path)
    except FormatError as e:
        assert "value in the payload" in str(e)
    else:
        assert t.shape == GRID_SHAPE + (3,) and not np.isinf(t).any()


# --- through a command that reads CSV --------------------------------------------------

@pytest.mark.parametrize("name", ["text_in_number", "negative_brdf", "vector_not_unit"])
def test_bad_csv_through_cli(tmp_path, name):
    from brdfkit.cli import cli
    from conftest import run_brdfkit

    if "sparse" not in cli.list_commands(None):
        pytest.skip("no CLI command reading CSV yet")
    content, line, _ = BAD[name]
    path = tmp_path / f"{name}.csv"
    path.write_text(content)
    env = {k: v for k, v in os.environ.items() if k != "BRDFKIT_MODEL"}
    # nbrdf needs no model, so the samples are the first thing read (no built-in is
    # installed in the tests, and the other methods ask for a model first).
    res = run_brdfkit(["sparse", path, "--method", "nbrdf", "-o", tmp_path / "out.binary"], env=env)
    assert res.returncode == 2 and "Traceback" not in res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and f"{path}: line {line}: " in lines[0]
    assert not (tmp_path / "out.binary").exists() and not tmp_leftovers(tmp_path)
