"""``brdfkit plot`` and :mod:`brdfkit.figures.brdf_plot`: lobes and slices of tables and embeddings."""

from __future__ import annotations

import functools
import math
import os
import subprocess
import sys

import numpy as np
import pytest

from brdfkit.materials import synthetic
from brdfkit.geometry import GRID_SHAPE, valid_mask
from brdfkit.io.merl import write_merl
from brdfkit.figures.brdf_plot import inplane_lobe, plot_figure

from conftest import run_here

MIRROR = synthetic.Material("mirror-0.01", "conductor", 0.01, ior=synthetic.METALS["silver"][0],
                            k=synthetic.METALS["silver"][1])


@functools.lru_cache(maxsize=1)
def _mirror():
    """``synthetic.table(MIRROR)``, read-only, computed once a module (half a second or
    more a table; ten tests and cases use it)."""
    t = synthetic.table(MIRROR)
    t.setflags(write=False)
    return t


def _lambert(albedo=(0.6, 0.5, 0.4)):
    t = np.empty(GRID_SHAPE + (3,))
    t[:] = np.asarray(albedo) / math.pi
    t[~valid_mask()] = np.nan
    return t


@pytest.fixture(scope="module")
def tables(tmp_path_factory):
    """A Lambertian table and a sharp silver mirror, as MERL files."""
    folder = tmp_path_factory.mktemp("plot")
    write_merl(folder / "lambert.binary", _lambert())
    write_merl(folder / "mirror.binary", _mirror())
    return folder


def _png_ok(path):
    from PIL import Image

    with Image.open(path) as im:
        assert im.format == "PNG"
        arr = np.asarray(im.convert("RGB"), dtype=np.float64)
    assert arr.shape[0] > 300 and arr.shape[1] > 600
    assert arr.std() > 10  # not a blank page
    return arr


def test_lambertian_lobe_is_flat_and_cosine_weighted_lobe_is_a_cosine():
    t = _lambert()
    for theta_i in (0.0, 45.0, 80.0):
        to, v = inplane_lobe(t, theta_i)
        y = 0.2126 * 0.6 + 0.7152 * 0.5 + 0.0722 * 0.4
        assert np.allclose(v, y / math.pi, rtol=1e-9)
        _, vc = inplane_lobe(t, theta_i, channel="red", cosine=True)
        assert np.allclose(vc, 0.6 / math.pi * np.cos(np.radians(to)), rtol=1e-9)


@pytest.mark.parametrize("theta_i", [0.0, 30.0, 60.0])
def test_mirror_lobe_peaks_in_the_mirror_direction(theta_i):
    to, v = inplane_lobe(_mirror(), theta_i)
    assert abs(to[np.nanargmax(v)] - theta_i) <= 1.0
    assert np.nanmax(v) > 100 * np.nanmedian(v)


@pytest.mark.slow
def test_plot_of_tables_writes_a_png_and_imports_no_torch(tables, tmp_path):
    """Tables only: matplotlib and NumPy, no torch (checked in a fresh process)."""
    out = tmp_path / "p.png"
    code = ("import sys\n"
            "from brdfkit.cli import main\n"
            "try:\n"
            f"    main(['plot', {str(tables / 'lambert.binary')!r}, {str(tables / 'mirror.binary')!r},"
            f" '-o', {str(out)!r}, '--phi-d', '90,45', '--cosine'])\n"
            "except SystemExit as e:\n"
            "    assert not e.code, e.code\n"
            "assert 'torch' not in sys.modules, 'torch imported'\n"
            "assert 'matplotlib' in sys.modules\n")
    r = subprocess.run([sys.executable, "-c", code], env={**os.environ, "OMP_NUM_THREADS": "1"},
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert "lambert, mirror" in r.stderr
    _png_ok(out)


@pytest.mark.slow
@pytest.mark.parametrize("n, options", [
    (1, {}), (4, {}), (3, {"view": "slices"}), (1, {"theta_i": (0.0, 45.0)}),
    (2, {"view": "slices", "phi_d": (0.0, 90.0)}), (5, {"theta_i": (20.0,), "phi_d": (0.0, 45.0, 90.0)}),
    (1, {"view": "lobes", "theta_i": (10.0,)}),
])
def test_layout_cuts_and_overlaps_nothing(n, options):
    """Regression: the slices' x label fell off the figure's bottom and the panels'
    titles ran into their view's title (fixed-aspect axes the layout had placed before
    they shrank); a view's title wider than the figure was cut at both edges; long
    labels ran into each other."""
    import matplotlib.pyplot as plt

    labels = ["lambert", "mirror-silver-reconstructed-from-40-samples", "c", "d", "e-with-a-long-name-too"][:n]
    tabs = {lab: (_lambert() if i % 2 == 0 else _mirror()) for i, lab in enumerate(labels)}
    fig = plot_figure(tabs, **options)
    try:
        fig.canvas.draw()
        r = fig.canvas.get_renderer()
        page = fig.bbox
        views = [sub for sub in fig.subfigs]
        assert views
        for sub in views:
            title = sub._suptitle.get_window_extent(r)
            assert page.x0 <= title.x0 and title.x1 <= page.x1
            for ax in sub.axes:
                box = ax.get_tightbbox(r)
                assert page.x0 - 0.5 <= box.x0 and box.x1 <= page.x1 + 0.5
                assert page.y0 - 0.5 <= box.y0 and box.y1 <= page.y1 + 0.5
                assert box.y1 <= title.y0, "a panel runs into its view's title"
            heads = [ax.title.get_window_extent(r) for ax in sub.axes if ax.get_title()]
            for i, a in enumerate(heads):
                assert not any(a.overlaps(b) for b in heads[i + 1:]), "two panel titles overlap"
    finally:
        plt.close(fig)


@pytest.mark.parametrize("view", ["lobes", "slices"])
def test_each_view_alone(tables, tmp_path, view, capsys):
    r = run_here(capsys, ["plot", tables / "mirror.binary", "-o", tmp_path / "p.png", "--view", view,
                     "--channel", "green", "--linear"])
    assert r.returncode == 0, r.stderr
    from PIL import Image

    with Image.open(tmp_path / "p.png") as im:
        assert im.format == "PNG" and im.size[1] > 150


@pytest.mark.slow
def test_table_and_embedding_side_by_side(tables, tmp_path, capsys):
    pytest.importorskip("torch")
    from brdfkit import api
    from brdfkit.io.embedding import write_embedding

    from helpers_model import make_model

    model_path = tmp_path / "model.safetensors"
    make_model(model_path)
    emb = api.encode(tables / "lambert.binary", api.load_model(model_path))
    write_embedding(tmp_path / "lambert.emb", emb)
    r = run_here(capsys, ["plot", tables / "lambert.binary", tmp_path / "lambert.emb", "-m", model_path,
                     "-o", tmp_path / "p.png"])
    assert r.returncode == 0, r.stderr
    assert "lambert.binary, lambert.emb" in r.stderr  # same stem: named with the extension
    _png_ok(tmp_path / "p.png")


@pytest.mark.parametrize("args, message", [
    (["{t}/lambert.binary", "{t}/x.emb"], "x.emb: no such file"),
    (["{t}/lambert.binary", "--theta-i", "95"], "--theta-i 95"),
    (["{t}/lambert.binary", "--phi-d", "abc"], "--phi-d"),
    (["{t}/lambert.binary", "--decades", "0"], "--decades"),
    (["{t}/lambert.csv"], "not a MERL table"),
])
def test_bad_plot_input_is_one_line(tables, tmp_path, args, message, capsys):
    r = run_here(capsys, ["plot", *[a.format(t=tables) for a in args], "-o", tmp_path / "p.png"])
    assert r.returncode == 2 and message in r.stderr, r.stderr
    assert r.stderr.count("\n") == 1
    assert not (tmp_path / "p.png").exists()


def test_bad_options_fail_before_reading_inputs(tmp_path, capsys):
    r = run_here(capsys, ["plot", tmp_path / "missing.binary", "--theta-i", "95", "-o", tmp_path / "p.png"])
    assert r.returncode == 2 and "--theta-i" in r.stderr, r.stderr
    r = run_here(capsys, ["plot", tmp_path / "missing.binary", "-o", tmp_path / "p.jpg"])
    assert r.returncode == 2 and ".png" in r.stderr, r.stderr


def _slices_title(tables, phi_d):
    import matplotlib.pyplot as plt

    fig = plot_figure(tables, view="slices", phi_d=phi_d)
    try:
        return " ".join(sf.get_suptitle() for sf in fig.subfigs).replace("\n", " ")
    finally:
        plt.close(fig)


def test_slice_legend_says_what_the_images_show():
    """The slices' title names black (the scale's bottom and below, a decoder's 0 included)
    and grey (not measured) only where the images hold them: at phi_d = 90 degrees every
    cell is measured, so the demo's plot has no grey."""
    lam = _lambert()
    assert _slices_title({"lambert": lam}, (90.0,)).endswith("log colour scale shared by all; darker: smaller)")
    holed = lam.copy()
    holed[60:, :, :, :] = 0.0  # a band decoded to zero at grazing theta_h
    title = _slices_title({"lambert": lam, "holed": holed}, (90.0,))
    assert "black: $10^{-6}$ or less, 0 included" in title and "grey" not in title
    title = _slices_title({"lambert": lam}, (0.0,))
    assert "grey: not measured" in title and "black" not in title
