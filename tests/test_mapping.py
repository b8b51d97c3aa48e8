"""The log-relative mapping, its inverse, and reference tables."""

from __future__ import annotations

import json
import pickle
import warnings

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from brdfkit.errors import InputError
from brdfkit.geometry import GRID_SHAPE
from brdfkit.hypernet.mapping import (CAP, EPS, FLOOR, from_mapped, load_reference, median_reference, save_reference,
                                      to_mapped)
from brdfkit.io.merl import write_merl

from conftest import format_error, tmp_leftovers
from helpers_foundation import measured_mask

# BRDF values from 0 through 1e-8 (black) to 1e5 (beyond the brightest mirror peak).
brdf = st.one_of(st.just(0.0), st.floats(1e-8, 1e5), st.floats(0, 1e-6))


@settings(max_examples=300, deadline=None)
@given(brdf, brdf)
def test_round_trip(rho, ref):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        mapped = to_mapped(np.array([rho]), ref)
        back = from_mapped(mapped, ref, floor=0)  # the exact inverse (the paper's)
    assert np.isfinite(mapped).all() and np.isfinite(back).all() and back[0] >= 0
    if rho > 1e-6:
        assert abs(back[0] - rho) <= 1e-6 * rho
    else:
        assert abs(back[0] - rho) <= 1e-12


@pytest.mark.parametrize("ref", [0.0, 1e-3, 1.0, 1e3, 1e5])
def test_stable_at_extremes(ref):
    rho = np.array([0.0, 1e-8, 1e-6, 1e5])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        mapped = to_mapped(rho, ref)
        back = from_mapped(mapped, ref, floor=0)
    assert np.isfinite(mapped).all() and (mapped > 0).all()
    assert back[0] == 0.0  # exactly: clamped at 0, never a tiny negative
    np.testing.assert_allclose(back[1:], rho[1:], rtol=1e-6, atol=1e-14)
    # the case that needs log1p: a dark cell under a bright reference
    assert abs(back[2] - 1e-6) < 1e-12


def test_formula_and_range():
    rho = np.array([0.0, 0.1, 1.0, 1e3])
    ref = 0.5
    np.testing.assert_allclose(to_mapped(rho, ref), np.log((rho + EPS) / (ref + EPS) + 1), rtol=1e-14)
    assert EPS == 0.002
    # monotone in rho; mapped 1e-3 ... 1e4 over a 1e-3 reference stays within ~0 ... 16
    grid = np.logspace(-3, 4, 50)
    m = to_mapped(grid, 1e-3)
    assert (np.diff(m) > 0).all() and m.max() < 16


def test_nan_propagates_without_warnings():
    rho = np.array([np.nan, 1.0, 0.0])
    ref = np.array([1.0, np.nan, 0.0])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        mapped = to_mapped(rho, ref)
        back = from_mapped(mapped, ref)
        from_mapped(mapped, ref, floor=0)
    np.testing.assert_array_equal(np.isnan(mapped), [True, True, False])
    np.testing.assert_array_equal(np.isnan(back), [True, True, False])
    assert not np.isinf(mapped).any() and not np.isinf(back).any()


def test_negative_input_clamped():
    # impossible for a BRDF, but a network may predict one: the log stays defined
    assert np.isfinite(to_mapped(np.array([-1.0]), 0.1)).all()
    assert from_mapped(np.array([-5.0]), 0.1, floor=0)[0] == 0.0
    assert from_mapped(np.array([-5.0]), 0.1)[0] == min(FLOOR * 0.1, CAP) + 1e-6 * EPS


@pytest.mark.parametrize("ref", [0.0, 1e-3, 1.0, 1e3])
def test_the_decoded_value_is_bounded_below_where_the_mapping_resolves_nothing(ref):
    """The default inverse never crosses zero: a network's "below eps" decodes to
    min(FLOOR * ref, CAP), never to 0 (black bands); every value above that bound comes
    back as it went in."""
    bound = min(FLOOR * ref, CAP) + 1e-6 * EPS
    rho = np.array([0.0, 1.5 * bound, 100 * bound, 1e4 * bound, 1e3])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        back = from_mapped(to_mapped(rho, ref), ref)
        low = from_mapped(np.array([-30.0, -1.0, 0.0]), ref)
    assert back[0] == bound and (low >= bound).all() and (np.diff(low) >= 0).all()
    np.testing.assert_allclose(back[1:], rho[1:], rtol=1e-6)


def test_torch_matches_numpy():
    rng = np.random.default_rng(1)
    rho = 10.0 ** rng.uniform(-8, 5, 200)
    ref = 10.0 ** rng.uniform(-4, 4, 200)
    rho[3] = np.nan
    t_m = to_mapped(torch.from_numpy(rho), torch.from_numpy(ref))
    assert isinstance(t_m, torch.Tensor) and t_m.dtype == torch.float64
    np.testing.assert_allclose(t_m.numpy(), to_mapped(rho, ref), rtol=1e-13, equal_nan=True)
    t_b = from_mapped(t_m, torch.from_numpy(ref))
    np.testing.assert_allclose(t_b.numpy(), from_mapped(to_mapped(rho, ref), ref), rtol=1e-12, atol=1e-15,
                               equal_nan=True)
    assert to_mapped(torch.ones(3, dtype=torch.float32), torch.ones(3)).dtype == torch.float32


# --- reference tables ------------------------------------------------------------------

def _constant(value, nan_cells=()):
    t = np.full(GRID_SHAPE + (3,), float(value))
    for c in nan_cells:
        t[c] = np.nan
    return t


@pytest.mark.slow
def test_median_reference_known_tables(tmp_path):
    a = _constant(1.0, [(0, 0, 0), (5, 5, 5)])
    b = _constant(2.0, [(0, 0, 0)])
    c = _constant(10.0, [(0, 0, 0), (5, 5, 5)])
    c[1, 2, 3] = [4.0, 5.0, 6.0]
    ref = median_reference([a, b, c])
    assert ref.shape == GRID_SHAPE + (3,) and ref.dtype == np.float32
    assert np.isnan(ref[0, 0, 0]).all()                     # nobody measured it
    np.testing.assert_array_equal(ref[5, 5, 5], 2.0)        # only b measured it
    np.testing.assert_array_equal(ref[1, 2, 3], [2.0, 2.0, 2.0])  # median of 1, 2, 4..6
    assert ref[7, 8, 9, 0] == 2.0
    # even count: mean of the middle two; paths of MERL files work like arrays
    even = median_reference([a, c])
    np.testing.assert_array_equal(even[7, 8, 9], 5.5)
    write_merl(tmp_path / "a.binary", a)
    write_merl(tmp_path / "c.binary", c)
    from_files = median_reference([str(tmp_path / "a.binary"), tmp_path / "c.binary"])
    np.testing.assert_allclose(from_files, even, rtol=1e-6, equal_nan=True)
    with pytest.raises(ValueError):
        median_reference([])


def test_save_load_reference_round_trip(tmp_path):
    rng = np.random.default_rng(0)
    ref = rng.random(GRID_SHAPE + (3,)).astype(np.float32)
    ref[~measured_mask()] = np.nan
    path = tmp_path / "ref.safetensors"
    save_reference(path, ref, materials=["a", "b"])
    back = load_reference(path)
    assert back.dtype == np.float32 and back.shape == GRID_SHAPE + (3,)
    np.testing.assert_array_equal(back, ref)
    from safetensors import safe_open
    with safe_open(str(path), framework="numpy") as f:
        assert json.loads(f.metadata()["materials"]) == ["a", "b"]
    assert not tmp_leftovers(tmp_path)


def _bad_reference(tmp_path, kind):
    from safetensors.numpy import save_file

    p = tmp_path / f"{kind}.safetensors"
    if kind == "text":
        p.write_text("not a safetensors file\n")
    elif kind == "pickle":
        p.write_bytes(pickle.dumps({"rho_ref": np.zeros(3)}))
    elif kind == "short":
        p.write_bytes(b"\x01")
    elif kind == "empty":
        p.write_bytes(b"")
    elif kind == "no_format":
        save_file({"rho_ref": np.zeros(GRID_SHAPE + (3,), np.float32)}, str(p))
    elif kind == "wrong_shape":
        save_file({"rho_ref": np.zeros((2, 2), np.float32)}, str(p), metadata={"format": "brdfkit-reference"})
    elif kind == "missing_tensor":
        save_file({"other": np.zeros((2, 2), np.float32)}, str(p), metadata={"format": "brdfkit-reference"})
    elif kind == "truncated":
        save_reference(p, np.zeros(GRID_SHAPE + (3,), np.float32))
        p.write_bytes(p.read_bytes()[:-100])
    return p


@pytest.mark.parametrize("kind, pattern", [
    *[(kind, "not a valid safetensors file") for kind in ("text", "pickle", "short", "empty", "truncated")],
    ("no_format", "not a brdfkit reference table"),
    ("wrong_shape", r"shape \(2, 2\)"),
    ("missing_tensor", "rho_ref"),
])
def test_load_reference_refuses(tmp_path, kind, pattern):
    format_error(load_reference, _bad_reference(tmp_path, kind), pattern)


def test_load_reference_missing_and_directory(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        load_reference(tmp_path / "nope.safetensors")
    with pytest.raises(InputError, match="is a directory"):
        load_reference(tmp_path)
