"""The basis's mapping at grazing cells (``brdfkit.basis.mapping.LogMapping``), its file
record, the deflated storage of a basis, and the same arithmetic whatever a process did
before (a compact basis's leading components)."""

from __future__ import annotations

import numpy as np
import pytest

from brdfkit.basis.mapping import EPS, NIELSEN, SHARE_FLOOR, LogMapping, from_mapped, lower_bound, to_mapped


def test_nielsen_is_the_module_functions_and_a_share_leaves_bright_references_alone():
    rng = np.random.default_rng(0)
    rho, w = rng.uniform(0, 3, 500), rng.uniform(0.01, 1, 500)
    ref = rng.uniform(0, 0.05, 500)
    np.testing.assert_array_equal(NIELSEN.to_mapped(rho, w, ref), to_mapped(rho, w, ref))
    y = to_mapped(rho, w, ref)
    np.testing.assert_array_equal(NIELSEN.from_mapped(y, w, ref), from_mapped(y, w, ref))
    np.testing.assert_array_equal(NIELSEN.lower_bound(ref, w), lower_bound(ref, w))
    bright = ref >= EPS  # where x_ref >= eps a share changes nothing
    m = LogMapping(0.03)
    np.testing.assert_allclose(m.to_mapped(rho, w, ref)[bright], y[bright], rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("share", [0.03, 0.1])
def test_a_share_resolves_dark_grazing_values_keeps_the_slope_and_inverts(share):
    m = LogMapping(share)
    x_ref = np.array([2e-5, 1e-4, 5e-4, 2e-3])
    for f in (0.01, 0.1, 0.5, 1.0, 3.0):
        rho = f * x_ref
        y = m.to_mapped(rho, 1.0, x_ref)
        np.testing.assert_allclose(m.from_mapped(y, 1.0, x_ref), np.maximum(rho, SHARE_FLOOR * x_ref), rtol=1e-9)
    # Nielsen's mapping hardly tells 10x from 100x darker at x_ref = 2e-5; the share does.
    a, b = (m.to_mapped(np.array([f * 2e-5]), 1.0, 2e-5)[0] for f in (0.1, 0.01))
    na, nb = (NIELSEN.to_mapped(np.array([f * 2e-5]), 1.0, 2e-5)[0] for f in (0.1, 0.01))
    assert (a - b) > 5 * (na - nb) > 0
    # The same slope d x' / d x at the reference as Nielsen's: the fit's budget there is kept.
    h = 1e-9
    for r in x_ref:
        slope = (m.to_mapped(np.array([r + h]), 1.0, r)[0] - m.to_mapped(np.array([r - h]), 1.0, r)[0]) / (2 * h)
        assert slope == pytest.approx(1.0 / (r + EPS), rel=1e-4)
    np.testing.assert_allclose(m.rho_slope(x_ref, 1.0, x_ref), x_ref + EPS, rtol=1e-12)


def test_torch_and_numpy_agree_and_nothing_overflows():
    torch = pytest.importorskip("torch")
    m = LogMapping(0.03)
    rng = np.random.default_rng(1)
    rho, w, ref = rng.uniform(0, 1e-2, 64), rng.uniform(0.005, 1, 64), rng.uniform(1e-6, 3e-3, 64)
    y = m.to_mapped(rho, w, ref)
    t = m.to_mapped(torch.as_tensor(rho), torch.as_tensor(w), torch.as_tensor(ref)).numpy()
    np.testing.assert_allclose(t, y, rtol=1e-12)
    back = m.from_mapped(torch.as_tensor(y), torch.as_tensor(w), torch.as_tensor(ref)).numpy()
    np.testing.assert_allclose(back, m.from_mapped(y, w, ref), rtol=1e-12)
    huge = m.from_mapped(np.full(64, 1e3), w, ref)  # a decoder's wild error: large, finite
    assert np.isfinite(huge).all()


def test_records_and_refusals():
    assert NIELSEN.record() == {} and LogMapping(0.03).record() == {"eps_share": "0.03"}
    assert LogMapping.from_record({}) is NIELSEN and LogMapping.from_record({"eps_share": "0.03"}) == LogMapping(0.03)
    for bad in (-0.1, 1.0, True, "x"):
        with pytest.raises(ValueError):
            LogMapping(bad)
    with pytest.raises(ValueError):
        LogMapping.from_record({"eps_share": "lots"})


@pytest.fixture(scope="module")
def shared_basis():
    """A basis of 5 components fitted with a share, on six synthetic tables."""
    from brdfkit.basis import fit_basis
    from brdfkit.materials.synthetic import library, table

    tables = [table(m) for m in library(6, seed=3, stiff=False)]
    return fit_basis(tables, 5, w_floor=0.005, mapping=LogMapping(0.03)), tables


def test_the_basis_file_records_its_mapping_and_deflated_storage_decodes_the_same_bytes(shared_basis, tmp_path):
    from brdfkit.basis import load_basis, save_basis, storage_of
    from brdfkit.errors import FormatError
    from brdfkit.io.tensorfile import open_safetensors

    basis, tables = shared_basis
    plain, deflated = tmp_path / "i8.safetensors", tmp_path / "z.safetensors"
    save_basis(plain, basis, half=True, phi_stride=2, int8=True)
    save_basis(deflated, basis, half=True, phi_stride=2, int8=True, deflate=True)
    with open_safetensors(deflated) as f:
        meta = f.metadata()
    assert meta["eps_share"] == "0.03" and storage_of(meta)["deflate"] and storage_of(meta)["int8"]
    a, b = load_basis(plain), load_basis(deflated)
    assert a.mapping == b.mapping == LogMapping(0.03)
    c = a.leading(3).project(tables[0])
    np.testing.assert_array_equal(a.leading(3).decode(c), b.leading(3).decode(c))
    np.testing.assert_array_equal(a.components, b.components)
    # A deflated stream that lies is refused as a format error naming the file.
    data = bytearray(deflated.read_bytes())
    i = data.rfind(b"\x78\xda")  # the last component's zlib header
    data[i + 10:i + 40] = bytes(30)
    bad = tmp_path / "bad.safetensors"
    bad.write_bytes(bytes(data))
    with pytest.raises(FormatError, match="bad.safetensors"):
        load_basis(bad).components


def test_a_compact_basis_computes_alike_whatever_was_restored_before(shared_basis, tmp_path):
    """Issue 51: a compact basis's full components, once restored by one use, changed the
    arithmetic of every later encode in the process (other last bits in a batch)."""
    from brdfkit.basis import load_basis, save_basis

    basis, tables = shared_basis
    path = tmp_path / "c.safetensors"
    save_basis(path, basis, half=True, phi_stride=2, int8=True, deflate=True)
    fresh = load_basis(path)
    c = np.full((3, 3), 0.2, np.float32)
    first = fresh.leading(3).mapped_values(c), fresh.leading(3).project(tables[1])
    used = load_basis(path)
    _ = used.components  # what a residual's fit through its correction reads
    again = used.leading(3).mapped_values(c), used.leading(3).project(tables[1])
    for x, y in zip(first, again):
        np.testing.assert_array_equal(x, y)
