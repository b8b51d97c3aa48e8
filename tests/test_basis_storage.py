"""Compact storage of a PCA basis (:mod:`brdfkit.basis.storage`) and the
version-2 basis file that uses it (float16, every other ``phi_d`` cell), with version-1
files still read."""

from __future__ import annotations

import json

import numpy as np
import pytest

from brdfkit.errors import FormatError, InputError
from brdfkit.geometry import N_CELLS, N_PHI_D, grid_cosine_weight
from brdfkit.basis.storage import GRAZING_FULL, check_half, compact, expand
from brdfkit.basis import BASIS_VERSION, PcaBasis, basis_tensors, load_basis, save_basis

_TENSORS = ("cells", "reference", "mean", "components", "sigma")


def _rows_cells(rows, phis):
    """Flat MERL indices of the given ``phi_d`` indices on each ``(theta_h, theta_d)`` row."""
    return np.sort(np.concatenate([r * N_PHI_D + np.asarray(phis, np.int64) for r in rows]))


def _neighbour_mean(even_cells, values, odd_cells):
    """Per cell of ``odd_cells``: the mean of ``values`` (over ``even_cells``) at its
    stored even neighbours on the same row (179's are 178 and 0), looked up on a dense
    grid, independently of ``expand``."""
    values = np.asarray(values, np.float64)
    dense = np.full(values.shape[:-1] + (N_CELLS,), np.nan)
    dense[..., even_cells] = values
    odd = np.asarray(odd_cells, np.int64)
    row, phi = odd // N_PHI_D, odd % N_PHI_D
    near = np.stack([dense[..., row * N_PHI_D + phi - 1], dense[..., row * N_PHI_D + (phi + 1) % N_PHI_D]])
    assert np.isfinite(near).any(axis=0).all()
    return np.nanmean(near, axis=0)


def _above_horizon():
    """bool ``(8100, 180)``: the cells with a positive cosine weight, per row."""
    return (grid_cosine_weight() > 0).reshape(-1, N_PHI_D)


@pytest.fixture(scope="module")
def basis():
    """A 3-component basis on every cell above the horizon, smooth in ``phi_d`` with
    values over six decades in the reference (as the real one has), float32."""
    cells = np.flatnonzero(grid_cosine_weight() > 0).astype(np.int64)
    rng = np.random.default_rng(3)
    phi = (cells % N_PHI_D) * (np.pi / N_PHI_D)
    row = cells // N_PHI_D
    reference = (10.0 ** (-4 + 6 * (row % 97) / 96) * (1 + 0.2 * np.cos(2 * phi))).astype(np.float32)
    mean = (0.3 * np.sin(row / 500.0) + 0.05 * np.cos(2 * phi)).astype(np.float32)
    comp = (rng.normal(size=(3, 1)) * np.cos(row / 300.0 + np.arange(3)[:, None])
            + 0.01 * rng.normal(size=(3, cells.size))).astype(np.float32) / np.sqrt(cells.size)
    sigma = np.array([30.0, 8.0, 2.0], np.float32)
    return PcaBasis(cells, reference, mean, comp.astype(np.float32), sigma, ["a", "b"])


# --- compact / expand ------------------------------------------------------------------------

def test_compact_keeps_even_and_grazing_cells_and_expand_restores_the_neighbour_mean():
    rows = (0, 7, 7921)  # rows above the horizon at every phi_d; 7921 near the horizon
    assert _above_horizon()[list(rows)].all()
    cells = _rows_cells(rows, np.arange(N_PHI_D))
    rng = np.random.default_rng(0)
    vec = rng.normal(size=cells.size).astype(np.float32)
    mat = rng.normal(size=(2, cells.size)).astype(np.float32)
    kept, (kv, km) = compact(cells, [vec, mat], 2)
    grazing = grid_cosine_weight()[cells] < GRAZING_FULL
    assert grazing.any() and not grazing[cells < 8 * N_PHI_D].any()
    even = ((cells % 2) == 0) | grazing  # the cells stored
    np.testing.assert_array_equal(kept, cells[even])
    np.testing.assert_array_equal(kv, vec[even])
    np.testing.assert_array_equal(km, mat[:, even])

    out_cells, (ev, em) = expand(kept, [kv, km])
    np.testing.assert_array_equal(out_cells, cells)
    assert ev.dtype == em.dtype == np.float32 and em.shape == mat.shape
    np.testing.assert_array_equal(ev[even], vec[even])  # stored cells: exactly
    np.testing.assert_array_equal(em[:, even], mat[:, even])
    np.testing.assert_allclose(ev[~even], _neighbour_mean(kept, kv, cells[~even]), rtol=0, atol=1e-6)
    np.testing.assert_allclose(em[:, ~even], _neighbour_mean(kept, km, cells[~even]), rtol=0, atol=1e-6)
    # The wrap: phi_d index 179 lies between 178 and 0 (phi_d is periodic with period pi).
    for r in rows[:2]:
        i179, i178, i0 = (np.searchsorted(cells, r * N_PHI_D + p) for p in (179, 178, 0))
        assert ev[i179] == np.float32(0.5) * (vec[i178] + vec[i0])

    # stride 1 keeps everything; other strides and odd cells are programming errors.
    same, (sv,) = compact(cells, [vec], 1)
    np.testing.assert_array_equal(same, cells)
    np.testing.assert_array_equal(sv, vec)
    with pytest.raises(ValueError, match="stride"):
        compact(cells, [vec], 3)
    every, (xv,) = expand(cells, [vec])  # every cell stored: every cell as stored
    np.testing.assert_array_equal(every, cells)
    np.testing.assert_array_equal(xv, vec)


def test_expand_next_to_missing_cells_and_the_horizon():
    """An odd cell with one stored neighbour takes its value, one with none is dropped,
    and no cell below the horizon (cosine weight 0) is restored."""
    above = _above_horizon()
    # Row 5: evens 0..10 only (11 has 10 alone; 179 has 0 alone; 13..177 have none).
    # Row 1349: above the horizon at 63..117 only, its evens stored (63 has 64 alone, 117
    # 116 alone, 61 and 119 lie below the horizon). Row 9: one even cell.
    assert above[[5, 9]].all() and np.array_equal(np.flatnonzero(above[1349]), np.arange(63, 118))
    kept = np.concatenate([_rows_cells([5], np.arange(0, 12, 2)), _rows_cells([9], [40]),
                           _rows_cells([1349], np.arange(64, 118, 2))])
    vals = np.random.default_rng(1).normal(size=(2, kept.size)).astype(np.float32)
    out, (ev,) = expand(kept, [vals])
    want = np.concatenate([_rows_cells([5], np.r_[0:12, 179]), _rows_cells([9], [39, 40, 41]),
                           _rows_cells([1349], np.arange(63, 118))])
    np.testing.assert_array_equal(out, want)
    even = (out % 2) == 0
    np.testing.assert_array_equal(ev[:, even], vals)
    np.testing.assert_allclose(ev[:, ~even], _neighbour_mean(kept, vals, out[~even]), rtol=0, atol=1e-6)
    at = dict(zip(out.tolist(), ev.T))
    for odd, near in ((5 * 180 + 11, 5 * 180 + 10), (5 * 180 + 179, 5 * 180), (1349 * 180 + 63, 1349 * 180 + 64),
                      (1349 * 180 + 117, 1349 * 180 + 116), (9 * 180 + 39, 9 * 180 + 40)):
        np.testing.assert_array_equal(at[odd], at[near])
    # A row below the horizon at its stored cell restores nothing there.
    below = int(np.flatnonzero(~above[1349])[0])
    assert below % 2 == 0
    out2, _ = expand(np.array([1349 * 180 + below], np.int64), [np.ones(1, np.float32)])
    assert out2.size == 0 or (grid_cosine_weight()[out2] > 0).all()


def test_check_half_refuses_values_float16_cannot_hold(tmp_path):
    check_half("b.safetensors", [np.array([65504.0, -65504.0]), np.zeros((2, 0))])
    with pytest.raises(InputError, match=r"b.safetensors: .*float16's range \(65504\)"):
        check_half("b.safetensors", [np.zeros(3), np.array([[1.0, -70000.0]])])
    big = PcaBasis(np.array([0, 2], np.int64), np.array([1.0, 1e5], np.float32), np.zeros(2, np.float32),
                    np.ones((1, 2), np.float32), np.ones(1, np.float32), [])
    with pytest.raises(InputError, match="float16"):
        save_basis(tmp_path / "big.safetensors", big, half=True)
    assert not (tmp_path / "big.safetensors").exists()
    save_basis(tmp_path / "big.safetensors", big)  # float32 holds it


# --- the basis file ---------------------------------------------------------------------------

def _raw(path):
    from safetensors.numpy import load_file
    from safetensors import safe_open

    with safe_open(str(path), "numpy") as f:
        meta = f.metadata()
    return load_file(str(path)), meta


def test_half_stride_two_file_round_trip(basis, tmp_path):
    full, packed = tmp_path / "full.safetensors", tmp_path / "packed.safetensors"
    save_basis(full, basis)
    save_basis(packed, basis, half=True, phi_stride=2)
    tensors, meta = _raw(packed)
    assert meta["version"] == BASIS_VERSION == "2"
    assert meta["phi_d_stride"] == "2" and meta["dtype"] == "float16"
    assert tensors["components"].dtype == np.float16 and tensors["sigma"].dtype == np.float32
    assert "cells" not in tensors and tensors["cell_mask"].dtype == np.uint8
    stored = ((basis.cells % 2) == 0) | (grid_cosine_weight()[basis.cells] < GRAZING_FULL)
    np.testing.assert_array_equal(_stored_cells(tensors), basis.cells[stored])
    assert packed.stat().st_size < 0.3 * full.stat().st_size

    a, b = load_basis(full), load_basis(packed)
    # The same cells as stride 1, less the odd cells with no stored even neighbour (none
    # is added).
    idx = np.searchsorted(a.cells, b.cells)
    assert (idx < a.cells.size).all() and (a.cells[idx] == b.cells).all()
    kept = np.zeros(a.cells.size, bool)
    kept[idx] = True
    lost = a.cells[~kept]
    assert ((lost % N_PHI_D) % 2 == 1).all()
    on_grid = np.zeros(N_CELLS, bool)
    on_grid[a.cells] = True
    row, phi = lost // N_PHI_D, lost % N_PHI_D
    assert not on_grid[row * N_PHI_D + phi - 1].any() and not on_grid[row * N_PHI_D + (phi + 1) % N_PHI_D].any()
    np.testing.assert_array_equal(b.sigma, basis.sigma)
    assert b.materials == basis.materials

    even = ((b.cells % 2) == 0) | (grid_cosine_weight()[b.cells] < GRAZING_FULL)  # the stored cells
    for name in ("reference", "mean", "components"):
        orig, got = getattr(basis, name)[..., idx], getattr(b, name)
        assert got.dtype == np.float32
        # Stored cells: float16 rounding (half an ulp, 2^-11 relative; subnormals absolute).
        tol = np.abs(orig) * 2.0 ** -11 + 2.0 ** -25
        assert (np.abs(got[..., even] - orig[..., even]) <= tol[..., even]).all(), name
        # Restored cells: the mean of the rounded neighbours, close to the true value of a
        # basis smooth in phi_d.
        pairs = (b.cells % 2) == 0
        np.testing.assert_allclose(got[..., ~even], _neighbour_mean(b.cells[pairs], got[..., pairs], b.cells[~even]),
                                   rtol=1e-6, atol=1e-9)
        scale = np.abs(orig).max()
        assert np.abs(got[..., ~even] - orig[..., ~even]).max() < 0.05 * scale, name


def test_int8_storage(basis, tmp_path):
    """int8 components with a scale per block of cells: each value within half a step
    (1/254) of the largest in its block, in half the bytes of float16; the
    reference and mean as in float16 storage."""
    from brdfkit.basis.storage import INT8_BLOCK, dequantize, quantize

    q, scale = quantize(basis.components)
    assert q.dtype == np.int8 and scale.shape == (3, -(-basis.cells.size // INT8_BLOCK))
    back = dequantize(q, scale)
    step = np.repeat(scale, INT8_BLOCK, axis=1)[:, :basis.cells.size]
    assert (np.abs(back - basis.components) <= 0.5 * step * (1 + 1e-4)).all()  # float32 rounding of q * scale
    assert np.array_equal(quantize(np.zeros((2, 10)))[0], np.zeros((2, 10), np.int8))  # no 0 / 0

    f16, i8 = tmp_path / "f16.safetensors", tmp_path / "i8.safetensors"
    save_basis(f16, basis, half=True, phi_stride=2)
    save_basis(i8, basis, half=True, phi_stride=2, int8=True)
    # the components take half the bytes (the scales 1/128 of that again)
    assert f16.stat().st_size - i8.stat().st_size > 0.49 * _raw(f16)[0]["components"].nbytes
    tensors, meta = _raw(i8)
    assert meta["dtype"] == "int8" and tensors["components"].dtype == np.int8
    a, b = load_basis(f16), load_basis(i8)
    np.testing.assert_array_equal(a.cells, b.cells)
    np.testing.assert_array_equal(a.reference, b.reference)
    np.testing.assert_array_equal(a.mean, b.mean)
    assert np.abs(a.components - b.components).max() < 0.01 * np.abs(a.components).max()
    with pytest.raises(ValueError, match="int8 storage of a basis goes with half"):
        save_basis(tmp_path / "x.safetensors", basis, int8=True)
    for broken in ({k: v for k, v in tensors.items() if k != "component_scales"},
                   {**tensors, "component_scales": tensors["component_scales"][:, :-1]},
                   {**tensors, "component_scales": np.full_like(tensors["component_scales"], np.nan)}):
        _save_raw(tmp_path / "bad.safetensors", broken, meta)
        with pytest.raises(FormatError, match="bad.safetensors: .*(component_scales|scales)"):
            load_basis(tmp_path / "bad.safetensors")


@pytest.mark.parametrize("half,stride,int8", [(True, 2, False), (True, 1, False), (False, 2, False),
                                              (True, 2, True)])
def test_resaving_a_stored_basis_gives_the_identical_tensors(basis, tmp_path, half, stride, int8):
    """What ``brdfkit.prior.fit`` relies on: a basis read back from compact storage and stored the
    same way again is bit-identical, so a model trained on it sees what it ships with."""
    first, second = tmp_path / "a.safetensors", tmp_path / "b.safetensors"
    save_basis(first, basis, half=half, phi_stride=stride, int8=int8)
    back = load_basis(first)
    save_basis(second, back, half=half, phi_stride=stride, int8=int8)
    t1, m1 = _raw(first)
    t2, m2 = _raw(second)
    assert m1 == m2 and sorted(t1) == sorted(t2)
    for k in t1:
        assert t1[k].dtype == t2[k].dtype
        np.testing.assert_array_equal(t1[k], t2[k])
    again = load_basis(second)
    for k in _TENSORS:
        np.testing.assert_array_equal(getattr(again, k), getattr(back, k))
    # The same through the prefixed tensors a learnt-prior file stores inside itself.
    pt, pm = basis_tensors(back, half=half, phi_stride=stride, int8=int8, prefix="basis.")
    assert sorted(pt) == sorted("basis." + k for k in t1)
    for k in t1:
        np.testing.assert_array_equal(pt["basis." + k], t1[k])
    assert {k[len("basis."):]: v for k, v in pm.items()} == m1


def _stored_cells(tensors):
    """The cells a basis file names: its ``cells`` tensor, or its ``cell_mask`` (bits
    over the grid, compact files)."""
    if "cells" in tensors:
        return tensors["cells"]
    return np.flatnonzero(np.unpackbits(tensors["cell_mask"])[:N_CELLS])


def _save_raw(path, tensors, meta):
    from safetensors.numpy import save_file

    save_file({k: np.ascontiguousarray(v) for k, v in tensors.items()}, str(path), metadata=meta)


def _v1_meta(basis):
    return {"format": "brdfkit-ipca", "version": "1", "n_components": str(basis.n_components), "eps": "0.001",
            "weight": "cos_i*cos_o", "channels": "separate observations, shared basis",
            "materials": json.dumps(basis.materials)}


def test_version_1_files_still_load(basis, tmp_path):
    path = tmp_path / "v1.safetensors"
    _save_raw(path, {"cells": basis.cells, "reference": basis.reference, "mean": basis.mean,
                     "components": basis.components, "sigma": basis.sigma}, _v1_meta(basis))
    back = load_basis(path)
    for k in _TENSORS:
        np.testing.assert_array_equal(getattr(back, k), getattr(basis, k))
    assert back.materials == basis.materials
    meta = _v1_meta(basis)
    meta["version"] = "3"
    _save_raw(path, {k: getattr(basis, k) for k in _TENSORS}, meta)
    with pytest.raises(FormatError, match="version '3' is not supported"):
        load_basis(path)


def test_bad_storage_metadata_and_odd_cells_are_format_errors(basis, tmp_path):
    good = tmp_path / "good.safetensors"
    save_basis(good, basis, half=True, phi_stride=2)
    tensors, meta = _raw(good)
    for bad in ("3", "0", "", "two", "2.0"):
        path = tmp_path / "stride.safetensors"
        _save_raw(path, tensors, {**meta, "phi_d_stride": bad})
        with pytest.raises(FormatError, match="stride.safetensors: .*phi_d_stride"):
            load_basis(path)
    # An odd phi_d cell in a stride-2 file, named by the mask or by index.
    cells = _stored_cells(tensors).copy()
    cells[5] += 1  # still sorted and in range
    mask = np.zeros(N_CELLS, bool)
    mask[cells] = True
    path = tmp_path / "odd.safetensors"
    for where in ({"cell_mask": np.packbits(mask)}, {"cells": cells}):
        odd = {k: v for k, v in tensors.items() if k != "cell_mask"}
        odd.update(where)
        _save_raw(path, odd, meta)
        with pytest.raises(FormatError, match="odd.safetensors: .*odd phi_d cells only near the horizon"):
            load_basis(path)
    bad = {k: v for k, v in tensors.items() if k != "cell_mask"}
    bad["cell_mask"] = np.packbits(mask)[:-1]
    _save_raw(path, bad, meta)
    with pytest.raises(FormatError, match="odd.safetensors: .*cell mask"):
        load_basis(path)
    # The same tensors declared stride 1 are a valid (if odd) basis.
    _save_raw(path, odd, {**meta, "phi_d_stride": "1"})
    assert load_basis(path).cells.size == cells.size
