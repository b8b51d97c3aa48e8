"""Synthetic GGX materials: determinism, the stiff cases, reciprocity, energy."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from brdfkit.materials import synthetic as syn
from brdfkit.geometry import GRID_SHAPE

from helpers_foundation import measured_mask


@pytest.fixture(scope="module")
def stiff_tables():
    return {m.name: syn.table(m) for m in syn.STIFF}


def test_library_deterministic():
    a, b = syn.library(12, seed=3), syn.library(12, seed=3)
    assert a == b
    assert syn.library(12, seed=4)[4:] != a[4:]
    assert [m.name for m in a[:4]] == ["stiff-mirror", "stiff-black", "stiff-white", "stiff-grazing"]
    assert [m.name for m in a[4:6]] == ["synth-000", "synth-001"]
    assert [m.name for m in syn.library(2, seed=0, stiff=False)] == ["synth-000", "synth-001"]
    with pytest.raises(ValueError):
        syn.library(0)


def test_library_parameters_in_documented_ranges():
    lib = syn.library(200, seed=1, stiff=False)
    kinds = [m.kind for m in lib]
    assert 0.45 < kinds.count("dielectric") / len(lib) < 0.75
    for m in lib:
        assert 0.01 <= m.alpha <= 0.6 and m.ks == 1.0
        if m.kind == "dielectric":
            assert all(0.005 <= a <= 0.85 for a in m.albedo)
            assert 1.3 <= m.ior[0] <= 1.8 and len(set(m.ior)) == 1
        else:
            assert m.albedo == (0.0, 0.0, 0.0)
            metal = next(n for n, (nn, _) in syn.METALS.items() if tuple(nn) == m.ior)
            kk = np.array(m.k) / np.array(syn.METALS[metal][1])
            assert ((kk >= 0.8 - 1e-12) & (kk <= 1.2 + 1e-12)).all()


def test_table_deterministic(stiff_tables):
    again = syn.table(syn.STIFF[1])
    assert again.tobytes() == stiff_tables["stiff-black"].tobytes()


@pytest.mark.parametrize("name", [m.name for m in syn.STIFF])
def test_nan_exactly_below_horizon_finite_elsewhere(stiff_tables, name):
    t = stiff_tables[name]
    assert t.shape == GRID_SHAPE + (3,) and t.dtype == np.float64
    np.testing.assert_array_equal(np.isnan(t), np.broadcast_to(~measured_mask()[..., None], t.shape))
    v = t[measured_mask()]
    assert np.isfinite(v).all() and (v >= 0).all()


def test_stiff_properties(stiff_tables):
    mirror = stiff_tables["stiff-mirror"]
    assert mirror[0, 0, 0].min() > 1e3  # normal incidence, specular peak
    assert np.nanmax(mirror) > 1e6    # towards grazing
    black = stiff_tables["stiff-black"]
    assert np.nanmax(black) < 0.5 and np.nanmedian(black) < 1e-3
    white = stiff_tables["stiff-white"]
    assert np.nanmin(white) >= 0.95 / math.pi
    grazing = stiff_tables["stiff-grazing"]
    # Fresnel from 4% at normal incidence to 100% at grazing, seen in the table along the
    # specular peak (theta_h = 0): theta_d 0 -> 87 degrees
    normal, near_grazing = grazing[0, 0, 0, 0], grazing[0, 87, 0, 0]
    assert near_grazing > 20 * normal
    assert syn._fresnel_dielectric(np.array(1.0), 1.5) == pytest.approx(0.04)
    assert syn._fresnel_dielectric(np.array(0.0), 1.5) == pytest.approx(1.0)


def _dirs(t, p):
    return np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1)


@settings(max_examples=100, deadline=None)
@given(st.integers(0, 9), st.lists(st.floats(0, math.pi / 2), min_size=2, max_size=2),
       st.lists(st.floats(0, 2 * math.pi), min_size=2, max_size=2))
def test_reciprocity(which, thetas, phis):
    m = syn.library(10, seed=2)[which]
    wi, wo = _dirs(thetas[0], phis[0]), _dirs(thetas[1], phis[1])
    a, b = syn.evaluate(m, wi, wo), syn.evaluate(m, wo, wi)
    np.testing.assert_allclose(a, b, rtol=1e-12, atol=0)
    assert np.isfinite(a).all() and (a >= 0).all()


def test_zero_below_horizon():
    m = syn.STIFF[2]
    up, down = np.array([0, 0.6, 0.8]), np.array([0, 0.6, -0.8])
    np.testing.assert_array_equal(syn.evaluate(m, up, down), 0)
    np.testing.assert_array_equal(syn.evaluate(m, down, up), 0)


def directional_albedo(m, theta_i, n=300):
    """Integral of f cos(theta_o) over the hemisphere, midpoint rule in (cos theta_o, phi_o)
    (exact for a Lambertian BRDF)."""
    mu = (np.arange(n) + 0.5) / n
    ph = (np.arange(2 * n) + 0.5) / (2 * n) * 2 * np.pi
    MU, PH = np.meshgrid(mu, ph, indexing="ij")
    s = np.sqrt(1 - MU ** 2)
    wo = np.stack([s * np.cos(PH), s * np.sin(PH), MU], -1)
    wi = np.broadcast_to([math.sin(theta_i), 0.0, math.cos(theta_i)], wo.shape)
    f = syn.evaluate(m, wi, wo)
    return (f * MU[..., None]).sum((0, 1)) * (1 / n) * (np.pi / n)


@pytest.mark.parametrize("theta_i", [0.0, 0.6, 1.2, 1.5])
def test_energy_white_lambertian(theta_i):
    white = syn.Material("white", "dielectric", 0.3, albedo=(1.0, 1.0, 1.0), ks=0.0)
    np.testing.assert_allclose(directional_albedo(white, theta_i), 1.0, rtol=1e-9)
    grey = syn.Material("grey", "dielectric", 0.3, albedo=(0.5, 0.25, 0.1), ks=0.0)
    np.testing.assert_allclose(directional_albedo(grey, theta_i), [0.5, 0.25, 0.1], rtol=1e-9)


@pytest.mark.parametrize("theta_i", [0.0, 0.5, 1.0])
def test_energy_stiff_white_up_to_60_degrees(theta_i):
    # Lambert 0.95 plus an uncoupled GGX lobe: at most 1 up to ~60 degrees incidence (the
    # excess towards grazing is documented in docs/synthetic.md).
    a = directional_albedo(syn.STIFF[2], theta_i)
    assert (a <= 1.0).all() and (a > 0.95).all()
