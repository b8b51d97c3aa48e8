"""The trilinear lookup (:func:`brdfkit.geometry.trilinear.lookup_trilinear`) against an
independent oracle, and the prepared tables of the lookups (torch's
:class:`brdfkit.geometry.trilinear.TrilinearTable`, the renderer's NumPy
:class:`brdfkit.render.lookup.TableRows`) against the plain one, bit for bit, NaN
semantics included (issue 14 item 1).

The oracle (:func:`oracle_lookup`) computes the interpolation another way: the grid's
continuous coordinates from their documented definitions (``DEVELOPERS.md``), each
cell's weight a tent ``max(0, 1 - |u - i|)`` along each axis (a circular distance along
``phi_d``), over the cells around the nearest one, without the library's floors,
fractions and clamped corner indices (issue 27 item 7). It agrees with the library to
rounding (``test_plain_lookup_agrees_with_the_oracle``); the prepared table must then
give the plain lookup's very bits (``reference_lookup``).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from brdfkit import geometry as g
from brdfkit.geometry.trilinear import TrilinearTable, lookup_prepared_many, lookup_trilinear

from helpers_foundation import measured_mask


def reference_lookup(table, theta_h, theta_d, phi_d, fill=float("nan")):
    """The plain-table lookup, whose bits the prepared table must give."""
    return lookup_trilinear(table, theta_h, theta_d, phi_d, fill=fill)


def oracle_lookup(table, theta_h, theta_d, phi_d, fill=float("nan"), weights=False):
    """Trilinear interpolation by tent weights (module docstring), float64 NumPy; with
    ``weights``, also the summed weight of the measured corners ``(..., C)`` and whether
    the point lies on a grid plane ``(...)`` (within 1e-7 of a cell along some axis)."""
    table = np.asarray(table, np.float64)
    th, td, pd = np.broadcast_arrays(*(np.asarray(a, np.float64) for a in (theta_h, theta_d, phi_d)))
    # The documented grid: theta_h cell i at (i / 90)^2 pi/2, theta_d cell j at j/90 pi/2,
    # phi_d cell k at k/180 pi, phi_d folded into [0, pi); beyond the last cell, the last.
    u_h = np.minimum(90 * np.sqrt(np.clip(th, 0, math.pi / 2) / (math.pi / 2)), 89.0)
    u_d = np.minimum(90 * np.clip(td, 0, math.pi / 2) / (math.pi / 2), 89.0)
    u_p = 180 * np.mod(pd, math.pi) / math.pi
    num = np.zeros(th.shape + (table.shape[-1],))
    den = np.zeros(th.shape + (table.shape[-1],))
    nh, nd, n_p = np.rint(u_h).astype(int), np.rint(u_d).astype(int), np.rint(u_p).astype(int)
    for oh in (-1, 0, 1):
        i = np.clip(nh + oh, 0, 89)
        wh = np.maximum(0.0, 1.0 - np.abs(u_h - i)) * (nh + oh == i)  # a clipped index is no cell
        for od in (-1, 0, 1):
            j = np.clip(nd + od, 0, 89)
            wd = np.maximum(0.0, 1.0 - np.abs(u_d - j)) * (nd + od == j)
            for op in (-1, 0, 1):
                k = np.mod(n_p + op, 180)
                dist = np.abs(u_p - k)
                wp = np.maximum(0.0, 1.0 - np.minimum(dist, 180 - dist))
                w = (wh * wd * wp)[..., None]
                v = table[i, j, k]
                ok = ~np.isnan(v)
                num += np.where(ok, w * np.where(ok, v, 0.0), 0.0)
                den += np.where(ok, w, 0.0)
    out = np.where(den > 0, num / np.where(den > 0, den, 1.0), fill)
    on_plane = np.min([np.abs(u - np.rint(u)) for u in (u_h, u_d, u_p)], axis=0) < 1e-7
    return (out, den, on_plane) if weights else out


def _angles(n, seed):
    """Random angles with the hard cases mixed in: cell boundaries and centres, phi_d at
    and around multiples of pi (the wrap), theta_h near 0 and pi/2, theta beyond the
    clamps, negative phi_d."""
    rng = np.random.default_rng(seed)
    th = rng.uniform(0, math.pi / 2, n)
    td = rng.uniform(0, math.pi / 2, n)
    pd = rng.uniform(-2 * math.pi, 2 * math.pi, n)
    q = n // 8
    cells = rng.integers(0, g.N_CELLS, q)
    ch, cd, cp = g.cell_angles(cells)
    th[:q], td[:q], pd[:q] = ch, cd, cp                      # on the grid's own angles
    pd[q:2 * q] = rng.choice([0.0, math.pi, -math.pi, 2 * math.pi, math.pi - 1e-12,
                              math.pi * (179.5 / 180), 1e-12], q)
    th[2 * q:3 * q] = rng.choice([0.0, 1e-9, 1e-5, (1 / 90) ** 2 * math.pi / 2, math.pi / 2,
                                  math.pi / 2 - 1e-9, math.pi / 2 + 0.1, -0.1], q)
    td[3 * q:4 * q] = rng.choice([0.0, math.pi / 2, math.pi / 2 - 1e-7, 89.5 / 90 * math.pi / 2,
                                  math.pi / 2 + 1, -1.0], q)
    return th, td, pd


def _tables(seed):
    rng = np.random.default_rng(seed)
    measured = rng.random(g.GRID_SHAPE + (3,))
    measured[~measured_mask()] = np.nan                     # MERL's own unmeasured region
    holes = measured.copy()
    holes[rng.random(g.GRID_SHAPE) < 0.3] = np.nan          # scattered NaN cells
    holes[10:14, 20:30] = np.nan                            # and a NaN block
    per_channel = holes.copy()
    per_channel[..., 1][rng.random(g.GRID_SHAPE) < 0.2] = np.nan   # channels differ
    none = np.full(g.GRID_SHAPE + (1,), np.nan)
    return {"merl": measured, "holes": holes, "per_channel": per_channel, "all_nan": none}


def _same(a, b):
    """Bit-identical, NaN where the other is NaN."""
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape and a.dtype == b.dtype
    np.testing.assert_array_equal(np.isnan(a), np.isnan(b))
    np.testing.assert_array_equal(a[~np.isnan(a)], b[~np.isnan(b)])
    np.testing.assert_array_equal(np.signbit(a), np.signbit(b))  # -0.0 is not +0.0


@pytest.mark.parametrize("kind", ["merl", "holes", "per_channel", "all_nan"])
def test_plain_lookup_agrees_with_the_oracle(kind):
    """The library's trilinear lookup is the oracle's interpolation, to rounding: the
    same NaN pattern (``fill`` where no corner is measured), the same values, on the grid's
    own angles, at the ``phi_d`` wrap, beyond the clamps and between cells."""
    table = _tables(4)[kind]
    th, td, pd = _angles(6000, 5)
    for fill in (float("nan"), -7.0):
        got = lookup_trilinear(table, th, td, pd, fill=fill)
        want, weight, on_plane = oracle_lookup(table, th, td, pd, fill=fill, weights=True)
        # Where every measured corner's weight is a rounding error (a point on a plane of
        # cells, next to unmeasured ones), whether it counts depends on the last bit of
        # the coordinates.
        clear = ((weight == 0) & ~on_plane[:, None]) | (weight > 1e-9)
        assert clear.mean() > 0.5  # a third of the points are on grid planes on purpose (_angles)
        np.testing.assert_array_equal(np.isnan(got)[clear], np.isnan(want)[clear])
        ok = clear & ~np.isnan(got)
        np.testing.assert_allclose(got[ok], want[ok], rtol=1e-8, atol=1e-10)
        np.testing.assert_array_equal(got[clear & (weight == 0)], want[clear & (weight == 0)])


def test_oracle_interpolates_a_linear_function_exactly():
    """The oracle itself, on a table linear in the grid's coordinates away from the
    edges: trilinear interpolation reproduces it, so the oracle is no copy of a bug."""
    i, j, k = np.meshgrid(np.arange(90.0), np.arange(90.0), np.arange(180.0), indexing="ij")
    table = (2.0 * i - 3.0 * j + 0.5 * k)[..., None]
    rng = np.random.default_rng(0)
    u_h, u_d, u_p = rng.uniform(1, 88, 500), rng.uniform(1, 88, 500), rng.uniform(1, 178, 500)
    th = (u_h / 90) ** 2 * (math.pi / 2)
    td = u_d / 90 * (math.pi / 2)
    pd = u_p / 180 * math.pi
    np.testing.assert_allclose(oracle_lookup(table, th, td, pd)[:, 0], 2 * u_h - 3 * u_d + 0.5 * u_p, atol=1e-9)


@pytest.mark.parametrize("kind", ["merl", "holes", "per_channel", "all_nan"])
def test_prepared_numpy_table_is_bit_identical(kind):
    table = _tables(0)[kind]
    lut = TrilinearTable(table)
    th, td, pd = _angles(20000, 1)
    for fill in (float("nan"), 0.0, -7.0):
        want = reference_lookup(table, th, td, pd, fill=fill)
        _same(lookup_trilinear(lut, th, td, pd, fill=fill), want)
        _same(lookup_trilinear(table, th, td, pd, fill=fill), want)


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
@pytest.mark.parametrize("kind", ["merl", "holes", "per_channel"])
def test_prepared_torch_table_is_bit_identical(kind, dtype):
    """Float32, as the renderer's ``TableBRDF`` holds it, and float64."""
    table = torch.as_tensor(_tables(2)[kind], dtype=dtype)
    lut = TrilinearTable(table)
    th, td, pd = (torch.as_tensor(a, dtype=dtype) for a in _angles(20000, 3))
    for fill in (float("nan"), 0.0):
        want = reference_lookup(table, th, td, pd, fill=fill)
        got = lookup_trilinear(lut, th, td, pd, fill=fill)
        assert got.dtype == dtype
        _same(got.numpy(), want.numpy())


def test_nan_corner_semantics_on_the_prepared_table():
    """What the reference does, spelled out: an unmeasured corner is left out; a point on
    an unmeasured cell, whose measured neighbours all have weight 0, gets ``fill``; a
    point between measured cells interpolates them."""
    table = np.ones(g.GRID_SHAPE + (1,))
    table[40, 40, 90] = np.nan
    table[40, 40, 91] = 5.0
    lut = TrilinearTable(table)
    th, td, pd = g.cell_angles(np.array([90 + 180 * (40 + 90 * 40)]))
    assert np.isnan(lookup_trilinear(lut, th, td, pd)[0, 0])
    assert lookup_trilinear(lut, th, td, pd, fill=0.0)[0, 0] == 0.0
    half = math.pi / 180 / 2
    # halfway between the NaN cell and the 5.0 cell: the NaN corner left out, 5.0 remains
    assert lookup_trilinear(lut, th, td, pd + half)[0, 0] == pytest.approx(5.0)


def test_shapes_broadcast_like_the_plain_table():
    table = _tables(4)["merl"]
    lut = TrilinearTable(table)
    th = np.full((4, 5), 0.3)
    pd = np.linspace(0, 3, 5)
    assert lookup_trilinear(lut, th, 0.2, pd).shape == (4, 5, 3)
    assert lookup_trilinear(lut, 0.3, 0.2, 0.1).shape == (3,)
    _same(lookup_trilinear(lut, th, 0.2, pd), reference_lookup(table, th, 0.2, pd))


def _dirs(n, seed):
    rng = np.random.default_rng(seed)
    wi, wo = rng.normal(size=(n, 3)), rng.normal(size=(n, 3))
    return ((wi / np.linalg.norm(wi, axis=1, keepdims=True)).astype(np.float32),
            (wo / np.linalg.norm(wo, axis=1, keepdims=True)).astype(np.float32))


@pytest.mark.parametrize("kind", ["merl", "holes", "per_channel", "all_nan"])
def test_render_rows_give_the_plain_lookup(kind):
    """The renderer's prepared rows (:class:`brdfkit.render.lookup.TableRows`, NumPy) give
    the plain float32 lookup's bits at the same grid coordinates, NaN semantics included
    (0 where no corner is measured: the renderer's fill)."""
    from brdfkit.render.lookup import TableRows

    table = np.asarray(_tables(5)[kind], np.float32)
    th, td, pd = (torch.as_tensor(a.astype(np.float32)) for a in _angles(20000, 6))
    u = torch.stack(g.fractional_indices(th, td, pd)).numpy()
    with np.errstate(invalid="ignore"):
        want = reference_lookup(torch.as_tensor(table), th, td, pd, fill=0.0).numpy()
    _same(TableRows(table).lookup(u).T, want)


def test_table_brdf_and_stack_at_directions():
    """A table BRDF at local directions is the plain lookup at their angles (to float32
    rounding of the angles, computed another way), 0 below the horizon; a stack of tables
    gives each table's own values, to the bit."""
    from brdfkit.render.renderable import TableBRDF, TableStackBRDF, coords_of_dirs

    ts = _tables(5)
    wi, wo = _dirs(5000, 6)
    th, _, td, pd = g.half_diff_from_io(wi.astype(np.float64), wo.astype(np.float64))
    want = reference_lookup(ts["merl"], th, td, pd, fill=0.0)
    want[(wi[:, 2] <= 0) | (wo[:, 2] <= 0)] = 0.0
    got = TableBRDF(ts["merl"]).eval_dirs(wi, wo)
    assert got.dtype == np.float32 and got.shape == (5000, 3)
    np.testing.assert_allclose(got, want, rtol=2e-4, atol=1e-6)
    alone = [TableBRDF(ts[k], name=k) for k in ("merl", "holes")]
    stack = TableStackBRDF([TableBRDF(ts[k], name=k) for k in ("merl", "holes")])
    assert stack.members == 2 and stack.name == "merl + holes"
    coords, _ = coords_of_dirs(wi, wo)
    block = type("Block", (), {"coords": coords})()
    both = stack.eval_pairs(block)
    _same(both[:3], alone[0].eval_pairs(block))
    _same(both[3:], alone[1].eval_pairs(block))


def test_neural_brdf_reference_through_the_prepared_table(tmp_path):
    """A neural BRDF's ``rho_ref`` at its directions is the plain lookup's."""
    from brdfkit import api
    from brdfkit.hypernet.loaded import interp_reference

    from helpers_model import make_model

    make_model(tmp_path / "m.safetensors", seed=0)
    model = api.load_model(tmp_path / "m.safetensors", "cpu")
    table, fallback = model.reference_torch()
    th, td, pd = (torch.as_tensor(a, dtype=torch.float32) for a in _angles(4000, 7))
    want = interp_reference(table, fallback, th, td, pd)
    got = interp_reference(model.reference_trilinear(), fallback, th, td, pd)
    _same(got.numpy(), want.numpy())
    assert model.reference_trilinear() is model.reference_trilinear()


@pytest.mark.slow
@pytest.mark.parametrize("block", [1, 977, 1 << 14])
def test_prepared_table_blocks_and_edges(block):
    """Points split over blocks (a ragged last one, one point a block), no points, NaN
    angles (NaN whatever ``fill``, as in the reference), and float64 angles on a float32
    table (a neural BRDF's ``rho_ref``: the lookup is done in float64)."""
    table32 = torch.as_tensor(_tables(8)["holes"], dtype=torch.float32)
    lut = TrilinearTable(table32)
    lut.block = block
    n = 3000 if block == 1 else 20000
    for dtype in (torch.float32, torch.float64):
        th, td, pd = (torch.as_tensor(a[:n], dtype=dtype) for a in _angles(20000, 9))
        th[:7] = float("nan")
        pd[7:9] = float("nan")
        for fill in (float("nan"), 0.0):
            got = lookup_trilinear(lut, th, td, pd, fill=fill)
            want = reference_lookup(table32, th, td, pd, fill=fill)
            assert got.dtype == want.dtype == dtype
            assert torch.isnan(got[:9]).all()
            _same(got.numpy(), want.numpy())
    empty = torch.zeros(0)
    assert lookup_trilinear(lut, empty, empty, empty).shape == (0, 3)


@pytest.mark.filterwarnings("ignore:invalid value:RuntimeWarning")
def test_prepared_table_with_infinite_values():
    """A table holding infinities (not a MERL table, but a table): ``fill + 0 * value``
    where no corner is measured, as the reference computes it."""
    table = _tables(10)["holes"]
    table[table > 0.9] = np.inf
    lut = TrilinearTable(table)
    assert not lut.finite
    th, td, pd = _angles(20000, 11)
    for fill in (float("nan"), 0.0):
        _same(lookup_trilinear(lut, th, td, pd, fill=fill), reference_lookup(table, th, td, pd, fill=fill))


@pytest.mark.slow
@pytest.mark.parametrize("block", [977, 1 << 14])
def test_tables_looked_up_together_are_each_alone(block):
    """``trilinear.lookup_prepared_many`` (a pass rendering two tables): each table's
    result is its own lookup's, NaN semantics included, whatever the other tables hold
    (MERL's unmeasured region, holes, per-channel NaN, one channel all NaN, infinities)."""
    ts = _tables(12)
    inf = ts["holes"].copy()
    inf[inf > 0.9] = np.inf
    tables = [ts["merl"], ts["holes"], ts["per_channel"], ts["all_nan"], inf]
    th, td, pd = _angles(20000, 13)
    for kind in ("numpy", "torch"):
        tabs = tables if kind == "numpy" else [torch.as_tensor(t, dtype=torch.float32) for t in tables]
        angles = (th, td, pd) if kind == "numpy" else tuple(torch.as_tensor(a, dtype=torch.float32)
                                                            for a in (th, td, pd))
        luts = [TrilinearTable(t) for t in tabs]
        for lut in luts:
            lut.block = block
        with np.errstate(invalid="ignore"):
            for fill in (float("nan"), 0.0):
                got = lookup_prepared_many(luts, *g.fractional_indices(*angles), fill)
                assert len(got) == len(tabs)
                for t, lut, x in zip(tabs, luts, got):
                    _same(np.asarray(x), np.asarray(lookup_trilinear(lut, *angles, fill=fill)))
                    _same(np.asarray(x), np.asarray(reference_lookup(t, *angles, fill=fill)))
    with pytest.raises(ValueError, match="share"):
        lookup_prepared_many([TrilinearTable(tables[0]), TrilinearTable(torch.as_tensor(tables[1]))],
                             *g.fractional_indices(th, td, pd), 0.0)


def test_finite_flag_sees_either_infinity_and_not_nan():
    """``TrilinearTable.finite`` (which fill path it takes): False with +inf or -inf
    anywhere, True for a table whose only non-finite values are NaN (not measured)."""
    table = _tables(16)["holes"]
    assert np.isnan(table).any() and TrilinearTable(table).finite
    for bad in (np.inf, -np.inf):
        t = table.copy()
        t[3, 4, 5, 2] = bad
        assert not TrilinearTable(t).finite
        assert not TrilinearTable(torch.as_tensor(t, dtype=torch.float32)).finite
