"""MERL .binary I/O: layout, exact round trip, speed, and every malformed file."""

from __future__ import annotations

import hashlib
import time

import numpy as np
import pytest

from brdfkit.cli import main as cli_main
from brdfkit.errors import FormatError, InputError
from brdfkit.geometry import GRID_SHAPE, N_CELLS
from brdfkit.io.merl import MERL_FILE_SIZE, MERL_SCALE, is_merl_file, read_merl, write_merl
from brdfkit.io.samples import read_samples

from conftest import run_brdfkit, tmp_leftovers
from helpers_foundation import measured_mask, merl_bytes, proxy_material, random_stored, random_table


@pytest.fixture(scope="module")
def stored():
    return random_stored(seed=7)


@pytest.fixture(scope="module")
def good_file(tmp_path_factory, stored):
    path = tmp_path_factory.mktemp("merl") / "random.binary"
    path.write_bytes(merl_bytes(stored))
    return path


def test_file_size_constant():
    assert MERL_FILE_SIZE == 34_992_012 == 12 + 3 * 90 * 90 * 180 * 8


def test_layout_channel_major_and_flat_index(tmp_path):
    # Stored value = flat index + channel offset: pins the channel-major order, the index
    # phi_d + 180 * (theta_d + 90 * theta_h) and the colour scales.
    flat = np.arange(N_CELLS, dtype=np.float64)
    stored = np.stack([flat, flat + 0.25, flat + 0.5])
    path = tmp_path / "layout.binary"
    path.write_bytes(merl_bytes(stored))
    table = read_merl(path)
    i, j, k = 37, 61, 149
    idx = k + 180 * (j + 90 * i)
    assert table[i, j, k, 0] == idx * MERL_SCALE[0]
    assert table[i, j, k, 1] == (idx + 0.25) * MERL_SCALE[1]
    assert table[i, j, k, 2] == (idx + 0.5) * MERL_SCALE[2]
    np.testing.assert_array_equal(MERL_SCALE, [1 / 1500, 1.15 / 1500, 1.66 / 1500])


def test_shape_dtype_and_nan_convention(good_file, stored):
    table = read_merl(good_file)
    assert table.shape == GRID_SHAPE + (3,) and table.dtype == np.float64
    cellmajor = stored.T.reshape(GRID_SHAPE + (3,))
    np.testing.assert_array_equal(np.isnan(table), cellmajor < 0)
    ok = cellmajor >= 0
    np.testing.assert_array_equal(table[ok], (cellmajor * MERL_SCALE)[ok])
    assert np.isnan(table).any(axis=-1).sum() == (~measured_mask()).sum()


def test_round_trip_random_doubles_byte_for_byte(good_file, stored, tmp_path):
    # The case the exactness machinery exists for: a sizeable share of the stored values
    # is not recovered by dividing the physical value by the scale.
    phys = stored.T * MERL_SCALE
    lossy = ((phys / MERL_SCALE) != stored.T) & (stored.T >= 0)
    assert lossy.mean() > 0.05
    out = tmp_path / "out.binary"
    write_merl(out, read_merl(good_file))
    assert out.read_bytes() == good_file.read_bytes()


def test_round_trip_exotic_stored_values(tmp_path, stored):
    s = stored.copy()
    cells = np.flatnonzero(measured_mask().reshape(-1))[:6]
    s[0, cells] = [0.0, -0.0, 5e-324, 1e300, 1e-310, 1.0]  # zero, signed zero, subnormals, huge
    src = tmp_path / "exotic.binary"
    src.write_bytes(merl_bytes(s))
    out = tmp_path / "out.binary"
    write_merl(out, read_merl(src))
    assert out.read_bytes() == src.read_bytes()


def test_round_trip_synthetic_table(tmp_path):
    table = random_table(seed=3)
    first, second = tmp_path / "a.binary", tmp_path / "b.binary"
    write_merl(first, table)
    back = read_merl(first)
    np.testing.assert_array_equal(np.isnan(back), np.isnan(table))
    np.testing.assert_allclose(back, table, rtol=4e-16, equal_nan=True)
    write_merl(second, back)
    assert second.read_bytes() == first.read_bytes()


def test_nan_cells_written_as_minus_one(tmp_path):
    table = np.full(GRID_SHAPE + (3,), 0.5)
    table[3, 4, 5, 1] = np.nan
    path = tmp_path / "t.binary"
    write_merl(path, table)
    payload = np.frombuffer(path.read_bytes()[12:], dtype="<f8").reshape(3, N_CELLS)
    idx = 5 + 180 * (4 + 90 * 3)
    assert payload[1, idx] == -1.0
    assert (payload[1] == -1.0).sum() == 1 and (payload >= 0).sum() == 3 * N_CELLS - 1


def test_copy_is_not_byte_exact_but_within_one_ulp(good_file, tmp_path):
    # The documented caveat: exactness is remembered per array returned by read_merl.
    copy = read_merl(good_file).copy()
    out = tmp_path / "copy.binary"
    write_merl(out, copy)
    a = np.frombuffer(good_file.read_bytes()[12:], "<f8")
    b = np.frombuffer(out.read_bytes()[12:], "<f8")
    np.testing.assert_allclose(b, a, rtol=2.3e-16, atol=0)


def test_modified_cells_are_written_with_their_new_value(good_file, tmp_path):
    # The remembered exact values must not resurrect a value the caller changed.
    table = read_merl(good_file)
    measured = np.flatnonzero(measured_mask().reshape(-1))[:1000]
    flat = table.reshape(-1, 3)
    flat[measured, 0] = 2.0
    out = tmp_path / "mod.binary"
    write_merl(out, table)
    back = read_merl(out)
    np.testing.assert_allclose(back.reshape(-1, 3)[measured, 0], 2.0, rtol=3e-16)
    untouched = np.flatnonzero(measured_mask().reshape(-1))[1000:]
    np.testing.assert_array_equal(
        np.frombuffer(out.read_bytes()[12:], "<f8").reshape(3, -1)[1:, untouched],
        np.frombuffer(good_file.read_bytes()[12:], "<f8").reshape(3, -1)[1:, untouched])


def test_read_speed(good_file):
    read_merl(good_file)  # page cache warm, as in any repeated use
    start = time.perf_counter()
    read_merl(good_file)
    assert time.perf_counter() - start < 1.5


def test_is_merl_file(good_file, tmp_path):
    assert is_merl_file(good_file)
    (tmp_path / "x.txt").write_text("hello")
    assert not is_merl_file(tmp_path / "x.txt")
    assert not is_merl_file(tmp_path / "missing.binary")


@pytest.mark.parametrize("bad", [np.inf, -np.inf])
def test_write_refuses_infinite(tmp_path, bad):
    table = np.zeros(GRID_SHAPE + (3,))
    table[1, 2, 3, 0] = bad
    with pytest.raises(InputError, match="out.binary"):
        write_merl(tmp_path / "out.binary", table)
    assert not (tmp_path / "out.binary").exists() and not tmp_leftovers(tmp_path)


def test_write_refuses_negative_and_wrong_shape(tmp_path):
    table = np.zeros(GRID_SHAPE + (3,))
    table[0, 0, 0, 2] = -1e-3
    with pytest.raises(InputError, match="negative"):
        write_merl(tmp_path / "out.binary", table)
    with pytest.raises(InputError, match=r"shape \(90, 90, 180\)"):
        write_merl(tmp_path / "out.binary", np.zeros(GRID_SHAPE))
    assert not list(tmp_path.iterdir())


# --- malformed files -------------------------------------------------------------------

def _bad_files(folder, good: bytes) -> dict:
    """name -> (path, expected error class, regex the message must match)."""
    def put(name, data):
        p = folder / name
        p.write_bytes(data)
        return p

    nan = bytearray(good)
    nan[12 + 8 * 100:12 + 8 * 101] = np.array([np.nan]).tobytes()
    inf = bytearray(good)
    off = 12 + 8 * (2 * N_CELLS + 7)
    inf[off:off + 8] = np.array([np.inf]).tobytes()
    (folder / "a_directory.binary").mkdir()
    return {
        "missing": (folder / "missing.binary", InputError, "no such file"),
        "directory": (folder / "a_directory.binary", InputError, "is a directory"),
        "empty": (put("empty.binary", b""), FormatError, "0 bytes, too short"),
        "header5": (put("header5.binary", good[:5]), FormatError, "5 bytes, too short"),
        "header12": (put("header12.binary", good[:12]), FormatError, "truncated: 12 bytes"),
        "payload13": (put("payload13.binary", good[:13]), FormatError, "truncated: 13 bytes"),
        "red_only": (put("red_only.binary", good[:12 + 8 * N_CELLS]), FormatError,
                     f"truncated: {12 + 8 * N_CELLS} bytes"),
        "half": (put("half.binary", good[:len(good) // 2]), FormatError, "truncated"),
        "one_short": (put("one_short.binary", good[:-1]), FormatError,
                      f"truncated: {MERL_FILE_SIZE - 1} bytes"),
        "too_long": (put("too_long.binary", good + b"\0" * 8), FormatError,
                     f"too long: {MERL_FILE_SIZE + 8} bytes"),
        "wrong_dims": (put("wrong_dims.binary", np.array([90, 90, 360], "<i4").tobytes() + good[12:]),
                       FormatError, r"dimensions are \(90, 90, 360\)"),
        "garbage_dims": (put("garbage_dims.binary", np.array([-1, 2**31 - 1, 5], "<i4").tobytes()
                             + good[12:]), FormatError, "not plausible"),
        "nan": (put("nan.binary", bytes(nan)), FormatError, r"NaN value in the payload \(channel R, cell 100\)"),
        "inf": (put("inf.binary", bytes(inf)), FormatError, r"infinite value in the payload \(channel B, cell 7\)"),
        "text": (put("text.binary", b"theta_h,theta_d,phi_d,r,g,b\n0.1,0.2,0.3,1,1,1\n"),
                 FormatError, "not a MERL table"),
    }


@pytest.fixture(scope="module")
def bad_files(tmp_path_factory, good_file):
    return _bad_files(tmp_path_factory.mktemp("bad"), good_file.read_bytes())


BAD_NAMES = ["missing", "directory", "empty", "header5", "header12", "payload13", "red_only",
             "half", "one_short", "too_long", "wrong_dims", "garbage_dims", "nan", "inf", "text"]


@pytest.mark.parametrize("name", BAD_NAMES)
def test_bad_file_raises_clear_error(bad_files, name):
    path, kind, pattern = bad_files[name]
    with pytest.raises(kind, match=pattern) as info:
        read_merl(path)
    message = str(info.value)
    assert str(path) in message and "\n" not in message
    assert isinstance(info.value, InputError)  # FormatError is an InputError too


@pytest.mark.parametrize("name", BAD_NAMES)
def test_cli_sample_on_bad_file(bad_files, name, tmp_path, capsys):
    path, _, pattern = bad_files[name]
    out = tmp_path / "x.csv"
    with pytest.raises(SystemExit) as info:
        cli_main(["sample", str(path), "-n", "3", "-o", str(out)])
    assert info.value.code == 2
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("brdfkit: error: ") and str(path) in lines[0]
    assert "Traceback" not in err
    assert not out.exists() and not tmp_leftovers(tmp_path)


@pytest.mark.parametrize("name", ["header5", "nan"])
def test_cli_sample_on_bad_file_subprocess(bad_files, name, tmp_path):
    path, _, _ = bad_files[name]
    res = run_brdfkit(["sample", path, "-n", "3", "-o", "x.csv"], cwd=tmp_path)
    assert res.returncode == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and str(path) in lines[0] and "Traceback" not in res.stderr
    assert res.stdout == ""
    assert not list(tmp_path.iterdir())


# --- real data (proxy) -----------------------------------------------------------------

@pytest.mark.slow
@pytest.mark.proxy
def test_proxy_round_trip_and_sample(tmp_path_factory, tmp_path):
    src = proxy_material(tmp_path_factory, "teflon")
    digest = hashlib.sha256(src.read_bytes()).hexdigest()
    table = read_merl(src)
    assert table.shape == GRID_SHAPE + (3,)
    np.testing.assert_array_equal(np.isnan(table).any(-1), ~measured_mask())
    assert np.nanmin(table) >= 0
    out = tmp_path / "teflon-copy.binary"
    write_merl(out, table)
    assert out.read_bytes() == src.read_bytes()

    csv = tmp_path / "teflon.csv"
    res = run_brdfkit(["sample", src, "-n", "500", "--seed", "3", "-o", csv])
    assert res.returncode == 0, res.stderr
    samples = read_samples(csv)
    assert len(samples) == 500 and np.isfinite(samples.rgb).all() and (samples.rgb >= 0).all()
    assert hashlib.sha256(src.read_bytes()).hexdigest() == digest  # input untouched
