"""Rusinkiewicz coordinates, the MERL grid and table lookups (property tests)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from brdfkit import geometry as g
from brdfkit.io.merl import read_merl
from brdfkit.geometry.trilinear import lookup_trilinear

from helpers_foundation import measured_mask, proxy_material

PI = math.pi
FEW = settings(max_examples=150, deadline=None)

# Angles with the edge values hypothesis should always try: exact 0, grazing pi/2, and
# the phi wrap points 0, pi, 2 pi.
theta = st.one_of(st.sampled_from([0.0, PI / 2, 1e-12, PI / 2 - 1e-12]),
                  st.floats(0.0, PI / 2, allow_nan=False))
phi = st.one_of(st.sampled_from([0.0, PI, 2 * PI, -PI, PI - 1e-12, 2 * PI - 1e-12]),
                st.floats(-2 * PI, 2 * PI, allow_nan=False))


def direction(t, p):
    return np.array([math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t)])


def circ(a, b, period=2 * PI):
    """Distance of two angles on a circle of the given period."""
    d = (np.asarray(a) - np.asarray(b)) % period
    return np.minimum(d, period - d)


# --- directions <-> angles -------------------------------------------------------------

@FEW
@given(theta, phi, theta, phi)
def test_directions_angles_directions(ti, pi_, to, po):
    wi, wo = direction(ti, pi_), direction(to, po)
    assume(np.linalg.norm(wi + wo) > 1e-6)  # opposite grazing pair: no half vector
    th, ph, td, pd = g.half_diff_from_io(wi, wo)
    assert 0 <= th <= PI / 2 + 1e-12 and 0 <= td <= PI / 2 + 1e-12
    assert -PI <= ph <= PI and -PI <= pd <= PI
    wi2, wo2 = g.io_from_half_diff(th, td, pd, ph)
    np.testing.assert_allclose(wi2, wi, atol=1e-6)
    np.testing.assert_allclose(wo2, wo, atol=1e-6)


@FEW
@given(theta, theta, phi, phi)
def test_angles_directions_angles(th, td, pd, ph):
    assume(math.cos(td) > 1e-6)  # theta_d = 90 degrees: wo = -wi, no half vector
    wi, wo = g.io_from_half_diff(th, td, pd, ph)
    np.testing.assert_allclose(np.linalg.norm(wi), 1, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(wo), 1, atol=1e-12)
    th2, ph2, td2, pd2 = g.half_diff_from_io(wi, wo)
    assert abs(th2 - th) < 1e-6 and abs(td2 - td) < 1e-6
    # phi_h is undefined at theta_h = 0 and phi_d at theta_d = 0 (any value names the
    # same pair); elsewhere the angles come back, modulo 2 pi.
    if math.sin(th) > 1e-3:
        assert circ(ph2, ph) < 1e-6
        if math.sin(td) > 1e-3:
            assert circ(pd2, pd) < 1e-6


def test_normal_incidence_exact():
    z = np.array([0.0, 0.0, 1.0])
    assert g.half_diff_from_io(z, z) == (0.0, 0.0, 0.0, 0.0)
    wi, wo = g.io_from_half_diff(0.0, 0.0, 0.0)
    np.testing.assert_array_equal(wi, z)
    np.testing.assert_array_equal(wo, z)


def test_grazing_pair():
    # Both directions on the horizon, 90 degrees apart: theta_h = 90, theta_d = 45.
    th, _, td, _ = g.half_diff_from_io(np.array([1.0, 0, 0]), np.array([0.0, 1, 0]))
    assert abs(th - PI / 2) < 1e-12 and abs(td - PI / 4) < 1e-12


# --- reciprocity -----------------------------------------------------------------------

@FEW
@given(theta, phi, theta, phi)
def test_reciprocity(ti, pi_, to, po):
    wi, wo = direction(ti, pi_), direction(to, po)
    assume(np.linalg.norm(wi + wo) > 1e-6)
    th, _, td, pd = g.half_diff_from_io(wi, wo)
    th2, _, td2, pd2 = g.half_diff_from_io(wo, wi)
    assert abs(th - th2) < 1e-9 and abs(td - td2) < 1e-9
    if math.sin(td) > 1e-6:
        assert circ(pd2, pd + PI) < 1e-6
    # Same MERL cell, unless rounding straddles a cell boundary (then an adjacent one);
    # at theta_d ~ 0 phi_d is undefined, so only the theta cells must agree.
    a, b = g.cell_index(th, td, pd), g.cell_index(th2, td2, pd2)
    if math.sin(td) <= 1e-6:
        a, b = a // 180, b // 180
    if a != b:
        u, v = g.fractional_indices(th, td, pd), g.fractional_indices(th2, td2, pd2)
        assert min(float(circ(x, np.round(x), 1.0)) for x in u + v) < 1e-6


def test_reciprocity_on_whole_grid():
    th, td, pd = np.meshgrid(*g.grid_angles(), indexing="ij")
    wi, wo = g.io_from_half_diff(th, td, pd)
    fwd = g.half_diff_from_io(wi, wo)
    rev = g.half_diff_from_io(wo, wi)
    np.testing.assert_array_equal(g.cell_index(fwd[0], fwd[2], fwd[3]),
                                  g.cell_index(rev[0], rev[2], rev[3]))


# --- the MERL grid ---------------------------------------------------------------------

def test_grid_angles():
    th, td, pd = g.grid_angles()
    assert th.shape == (90,) and td.shape == (90,) and pd.shape == (180,)
    assert th[0] == 0 and td[0] == 0 and pd[0] == 0
    np.testing.assert_allclose(th[45], (45 / 90) ** 2 * PI / 2)
    np.testing.assert_allclose(td[45], PI / 4)
    np.testing.assert_allclose(pd[90], PI / 2)


def test_cell_index_identity_on_grid_angles():
    th, td, pd = np.meshgrid(*g.grid_angles(), indexing="ij")
    np.testing.assert_array_equal(g.cell_index(th, td, pd).reshape(-1), np.arange(g.N_CELLS))
    back = g.cell_angles(np.arange(g.N_CELLS))
    for a, b in zip(back, (th, td, pd)):
        np.testing.assert_array_equal(a, b.reshape(-1))


def test_cell_index_identity_through_directions():
    # Every cell -> (wi, wo) -> angles -> the same cell, except the theta_d = 0 row where
    # phi_d is undefined (all 180 phi_d cells name one direction pair).
    th, td, pd = np.meshgrid(*g.grid_angles(), indexing="ij")
    wi, wo = g.io_from_half_diff(th, td, pd)
    th2, _, td2, pd2 = g.half_diff_from_io(wi, wo)
    idx = g.cell_index(th2, td2, pd2)
    expected = np.arange(g.N_CELLS).reshape(g.GRID_SHAPE)
    np.testing.assert_array_equal(idx[:, 1:], expected[:, 1:])
    np.testing.assert_array_equal(idx[:, 0] // 180, expected[:, 0] // 180)


@FEW
@given(st.floats(0, PI / 2), st.floats(0, PI / 2), st.floats(-4 * PI, 4 * PI))
def test_cell_index_contains_angles(th, td, pd):
    # The cell of (theta_h, theta_d, phi_d), from MERL's spacing written out again here.
    idx = int(g.cell_index(th, td, pd))
    assert 0 <= idx < g.N_CELLS
    i, j, k = idx // (90 * 180), (idx // 180) % 90, idx % 180
    u_h = 90 * math.sqrt(th / (PI / 2))
    u_d = td / (PI / 2) * 90
    u_p = (pd % PI) / PI * 180
    assert i <= u_h + 1e-6 and (u_h < i + 1 + 1e-6 or i == 89)
    assert j <= u_d + 1e-6 and (u_d < j + 1 + 1e-6 or j == 89)
    assert (k <= u_p + 1e-6 and u_p < k + 1 + 1e-6) or (k == 0 and u_p > 180 - 1e-6)


def test_phi_d_folding():
    # phi_d and phi_d + pi (the reciprocal configuration) share a cell; so do +-2 pi.
    pd = np.array([0.3, 0.3 + PI, 0.3 - PI, 0.3 + 2 * PI, 0.3 - 2 * PI])
    idx = g.cell_index(np.full(5, 0.4), np.full(5, 0.5), pd)
    assert len(set(idx.tolist())) == 1
    # just below pi folds to the last cell or wraps to the first, never out of range
    assert int(g.cell_index(0.4, 0.5, PI - 1e-15)) % 180 in (0, 179)
    assert int(g.cell_index(0.4, 0.5, np.nextafter(PI, 0))) % 180 in (0, 179)


def test_valid_mask():
    mask = g.valid_mask()
    assert mask.shape == g.GRID_SHAPE and mask.dtype == bool
    th, td, pd = np.meshgrid(*g.grid_angles(), indexing="ij")
    ci = g.cos_theta_i(th, td, pd)
    wi, wo = g.io_from_half_diff(th, td, pd)
    np.testing.assert_allclose(ci, wi[..., 2], atol=1e-15)
    np.testing.assert_array_equal(mask, (wi[..., 2] > 0) & (wo[..., 2] > 0))
    assert mask[0, :89].all()  # at theta_h = 0 both directions are above up to grazing
    assert mask.sum() == 1_111_432  # measured cells of a MERL table


@pytest.mark.slow
@pytest.mark.proxy
def test_valid_mask_matches_proxy_files(tmp_path_factory):
    table = read_merl(proxy_material(tmp_path_factory, "teflon"))
    np.testing.assert_array_equal(~np.isnan(table[..., 0]), g.valid_mask())
    np.testing.assert_array_equal(np.isnan(table).any(-1), np.isnan(table).all(-1))


def test_hd_vectors():
    th, td, pd = np.array([0.0, 0.7, PI / 2]), np.array([0.2, 1.0, 0.0]), np.array([0.3, 2.0, 1.0])
    hd = g.hd_vectors(th, td, pd)
    assert hd.shape == (3, 6)
    np.testing.assert_allclose(np.linalg.norm(hd[:, :3], axis=1), 1)
    np.testing.assert_allclose(np.linalg.norm(hd[:, 3:], axis=1), 1)
    assert (hd[:, 1] == 0).all()
    # h is the half vector of the pair with phi_h = 0
    wi, wo = g.io_from_half_diff(th, td, pd)
    h = (wi + wo) / np.linalg.norm(wi + wo, axis=1, keepdims=True)
    np.testing.assert_allclose(hd[:, :3], h, atol=1e-12)


# --- lookups ---------------------------------------------------------------------------

@pytest.fixture(scope="module")
def linear_table():
    # Linear in the grid coordinates: trilinear interpolation must reproduce it exactly.
    i, j, k = np.meshgrid(np.arange(90.0), np.arange(90.0), np.arange(180.0), indexing="ij")
    return np.stack([i, 2 * j + 1, 0.5 * k + 3], -1)


def test_trilinear_equals_table_at_grid_points(linear_table):
    rng = np.random.default_rng(0)
    table = rng.random(g.GRID_SHAPE + (3,))
    idx = rng.integers(0, g.N_CELLS, 2000)
    angles = g.cell_angles(idx)
    np.testing.assert_allclose(lookup_trilinear(table, *angles), table.reshape(-1, 3)[idx],
                               rtol=1e-9)
    np.testing.assert_array_equal(g.lookup_nearest(table, *angles), table.reshape(-1, 3)[idx])


@FEW
@given(st.floats(0, 89), st.floats(0, 89), st.floats(0, 179))
def test_trilinear_is_linear_between_cells(linear_table, u_h, u_d, u_p):
    th = (u_h / 90) ** 2 * PI / 2
    td = u_d / 90 * PI / 2
    pd = u_p / 180 * PI
    got = lookup_trilinear(linear_table, th, td, pd)
    np.testing.assert_allclose(got, [u_h, 2 * u_d + 1, 0.5 * u_p + 3], atol=1e-7)


def test_trilinear_wraps_phi_d(linear_table):
    table = linear_table
    # half-way between cell 179 and cell 0 (= 180): the mean of the two
    pd = 179.5 / 180 * PI
    got = lookup_trilinear(table, 0.2, 0.3, pd)[2]
    assert abs(got - (0.5 * (0.5 * 179 + 3) + 0.5 * 3)) < 1e-9
    for shift in (PI, -PI, 2 * PI):
        np.testing.assert_allclose(lookup_trilinear(table, 0.2, 0.3, 0.4 + shift),
                                   lookup_trilinear(table, 0.2, 0.3, 0.4), rtol=1e-9)


def test_trilinear_nan_corners():
    table = np.ones(g.GRID_SHAPE + (1,))
    table[10, 20, 30] = 5.0
    table[11, 20, 30] = np.nan
    th = (10.5 / 90) ** 2 * PI / 2
    td, pd = 20 / 90 * PI / 2, 30 / 180 * PI
    # corners (10,20,30)=5 and (11,20,30)=NaN with equal weight: NaN left out
    assert lookup_trilinear(table, th, td, pd)[0] == pytest.approx(5.0)
    table[10, 20, 30] = np.nan
    assert np.isnan(lookup_trilinear(table, th, td, pd)[0])
    assert lookup_trilinear(table, th, td, pd, fill=-7.0)[0] == -7.0
    # next to the horizon a real table stays defined
    real = np.where(measured_mask()[..., None], 2.0, np.nan)
    th, td, pd = np.meshgrid(*g.grid_angles(), indexing="ij")
    v = lookup_trilinear(real, th[measured_mask()] + 1e-3, td[measured_mask()] + 1e-3,
                           pd[measured_mask()])
    np.testing.assert_array_equal(v, 2.0)


# --- torch and numpy agree -------------------------------------------------------------

def test_torch_matches_numpy():
    rng = np.random.default_rng(5)
    n = 500
    th, td = rng.uniform(0, PI / 2, n), rng.uniform(0, PI / 2, n)
    pd, ph = rng.uniform(-PI, PI, n), rng.uniform(-PI, PI, n)
    T = lambda a: torch.from_numpy(np.ascontiguousarray(a))  # noqa: E731

    def same(a, b, exact=False):
        assert isinstance(b, torch.Tensor) and b.dtype in (torch.float64, torch.int64)
        if exact:
            np.testing.assert_array_equal(b.numpy(), a)
        else:
            np.testing.assert_allclose(b.numpy(), a, rtol=1e-12, atol=1e-12)

    wi, wo = g.io_from_half_diff(th, td, pd, ph)
    twi, two = g.io_from_half_diff(T(th), T(td), T(pd), T(ph))
    same(wi, twi), same(wo, two)
    for a, b in zip(g.half_diff_from_io(wi, wo), g.half_diff_from_io(T(wi), T(wo))):
        same(a, b)
    same(g.hd_vectors(th, td, pd), g.hd_vectors(T(th), T(td), T(pd)))
    same(g.cos_theta_i(th, td, pd), g.cos_theta_i(T(th), T(td), T(pd)))
    for a, b in zip(g.fractional_indices(th, td, pd), g.fractional_indices(T(th), T(td), T(pd))):
        same(a, b)
    same(g.cell_index(th, td, pd), g.cell_index(T(th), T(td), T(pd)), exact=True)
    table = rng.random(g.GRID_SHAPE + (3,))
    table[~measured_mask()] = np.nan
    same(lookup_trilinear(table, th, td, pd), lookup_trilinear(T(table), T(th), T(td), T(pd)))
    same(g.lookup_nearest(table, th, td, pd), g.lookup_nearest(T(table), T(th), T(td), T(pd)),
         exact=True)
    # cell_angles of integer tensors follow torch's default dtype
    for a, b in zip(g.cell_angles(np.arange(0, g.N_CELLS, 997)), g.cell_angles(torch.arange(0, g.N_CELLS, 997))):
        assert b.dtype == torch.get_default_dtype()
        np.testing.assert_allclose(b.numpy(), a, rtol=1e-6)


def test_float32_tensors_stay_float32():
    th = torch.tensor([0.1, 0.5], dtype=torch.float32)
    assert g.hd_vectors(th, th, th).dtype == torch.float32
    table = torch.rand(g.GRID_SHAPE + (3,), dtype=torch.float32)
    assert lookup_trilinear(table, th, th, th).dtype == torch.float32


# --- the grid caches (computed once per process, shared by every module) -----------------

def test_grid_caches_are_the_per_cell_definitions():
    cells = np.arange(0, g.N_CELLS, 613)
    th, td, pd = g.cell_angles(cells)
    wi, wo = g.grid_directions()
    assert wi.shape == wo.shape == g.GRID_SHAPE + (3,) and g.TABLE_SHAPE == g.GRID_SHAPE + (3,)
    ewi, ewo = g.io_from_half_diff(th, td, pd)
    np.testing.assert_array_equal(wi.reshape(-1, 3)[cells], ewi)
    np.testing.assert_array_equal(wo.reshape(-1, 3)[cells], ewo)
    want = np.clip(ewi[:, 2], 0, None) * np.clip(ewo[:, 2], 0, None)
    # In closed form: equal to the definition to rounding, and zero exactly where it is.
    np.testing.assert_allclose(g.grid_cosine_weight()[cells], want, rtol=1e-12, atol=0)
    np.testing.assert_array_equal(g.grid_cosine_weight()[cells] == 0, want == 0)
    np.testing.assert_array_equal(g.valid_cells(), np.flatnonzero(g.valid_mask().reshape(-1)))
    # one copy per process, which nobody may change
    for arr in (wi, wo, g.grid_cosine_weight(), g.valid_cells(), g.grid_hd()):
        assert not arr.flags.writeable
    assert g.grid_directions()[0] is wi and g.grid_hd() is g.grid_hd()


def test_merl_table_shape_is_the_geometry_constant():
    from brdfkit.io import merl

    assert merl.TABLE_SHAPE is g.TABLE_SHAPE == (90, 90, 180, 3)
