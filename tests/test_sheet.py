"""``brdfkit compare`` and :mod:`brdfkit.figures.comparison_sheet`: the comparison sheet."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest

from brdfkit.materials import synthetic
from brdfkit.io.merl import write_merl

from conftest import run_here


@pytest.fixture(scope="module")
def materials(tmp_path_factory):
    """Three synthetic materials as MERL files: the reference and two predictions."""
    folder = tmp_path_factory.mktemp("sheet")
    for m in synthetic.library(3, seed=3, stiff=False):
        write_merl(folder / f"{m.name}.binary", synthetic.table(m))
    return sorted(folder.glob("*.binary"))


def test_delta_e_map_is_what_the_mean_delta_e_averages():
    from brdfkit.evaluation.metrics import delta_e_2000, delta_e_2000_map

    rng = np.random.default_rng(0)
    a, b = rng.random((8, 9, 3)) * 1.3, rng.random((8, 9, 3))
    m = delta_e_2000_map(a, b)
    assert m.shape == (8, 9) and (m >= 0).all()
    assert m.mean() == pytest.approx(delta_e_2000(a, b), rel=1e-12)


@pytest.mark.slow
def test_sheet_scores_are_those_of_brdfkit_metrics(materials, tmp_path):
    """The same numbers as ``brdfkit metrics --ref REF PRED`` (the same render and score
    functions), and a PNG with one column per input."""
    pytest.importorskip("torch")
    from PIL import Image

    from brdfkit.evaluation.comparison import FileLoader, compare_files
    from brdfkit.figures.comparison_sheet import comparison_sheet

    ref, *preds = [str(p) for p in materials]
    rows = comparison_sheet(ref, preds + [ref], tmp_path / "s.png", resolution=16, progress=False)
    names = [os.path.splitext(os.path.basename(p))[0] for p in preds]
    assert list(rows)[:2] == names
    loader = FileLoader(None, 16, progress=False)
    for name, pred in zip(names, preds):
        expected = compare_files(loader, pred, ref)
        assert rows[name] == pytest.approx(expected, rel=1e-12)
        assert rows[name]["psnr"] < 60 and rows[name]["delta_e"] > 0.1
    same = rows[list(rows)[-1]]  # the reference against itself: the label gets its extension
    assert same["psnr"] == 100.0 and same["delta_e"] == 0.0 and same["brdf_log_rmse"] == 0.0
    with Image.open(tmp_path / "s.png") as im:
        assert im.format == "PNG" and im.size[0] > 4 * 200
        assert np.asarray(im.convert("L"), dtype=float).std() > 10


@pytest.mark.slow
def test_compare_command_json_and_sheet(materials, tmp_path, capsys):
    ref, a, b = materials
    r = run_here(capsys, ["compare", ref, a, b, "--sheet", tmp_path / "s.png", "--resolution", "16", "--json"])
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert set(out["predictions"]) == {a.stem, b.stem}
    assert all(v["brdf_log_rmse"] > 0 for v in out["predictions"].values())
    assert (tmp_path / "s.png").stat().st_size > 10_000
    assert not [p for p in os.listdir(tmp_path) if p.startswith(".brdfkit-tmp")]


@pytest.mark.parametrize("args, message", [
    (["{ref}", "{a}", "--sheet", "{tmp}/s.jpg"], "name it .png"),
    (["{ref}", "{a}", "--sheet", "/nonexistent/s.png"], "does not exist"),
    (["{ref}", "{tmp}/x.emb", "--sheet", "{tmp}/s.png"], "x.emb"),
    (["{ref}", "{a}", "--sheet", "{ref}"], "also an input"),
])
def test_bad_compare_input_is_one_line_before_any_render(materials, tmp_path, args, message, capsys):
    ref, a, _ = materials
    argv = [x.format(ref=ref, a=a, tmp=tmp_path) for x in args]
    r = run_here(capsys, ["compare", *argv, "--resolution", "16"])
    assert r.returncode == 2 and message in r.stderr, r.stderr
    assert r.stderr.count("\n") == 1


def _disc(size=128, value=0.8):
    y, x = np.mgrid[:size, :size]
    img = np.zeros((size, size, 3), np.float32)
    img[(x - size / 2) ** 2 + (y - size / 2) ** 2 < (0.4 * size) ** 2] = value
    return img


def test_renders_are_resampled_smoothly_and_the_same_every_time(tmp_path):
    """A 128 px render in a sheet's tile (about 237 px: 1.85 times) drawn nearest-pixel has
    jagged edges, some pixels drawn twice and some once; the sheets resample it by Lanczos
    (``canvas.SMOOTH``), which puts intermediate shades along the edge, and give the same
    PNG for the same image. The interpolation strip, one PNG pixel per render pixel, keeps
    ``nearest``."""
    from PIL import Image

    from brdfkit.figures.canvas import SMOOTH, pyplot, save_png, show_render

    def draw(name, interpolation):
        fig, ax = pyplot().subplots(1, 1, figsize=(2.6, 2.6), dpi=110)
        show_render(ax, _disc(), interpolation=interpolation)
        save_png(fig, tmp_path / name)
        return np.asarray(Image.open(tmp_path / name).convert("L"))

    smooth, nearest = draw("s.png", SMOOTH), draw("n.png", "nearest")
    edge = lambda a: int(((a > 20) & (a < 200)).sum())  # noqa: E731 - shades between black and the disc's
    assert SMOOTH == "lanczos" and edge(nearest) == 0 and edge(smooth) > 300
    draw("s2.png", SMOOTH)
    assert (tmp_path / "s.png").read_bytes() == (tmp_path / "s2.png").read_bytes()


def test_comparison_sheet_is_the_same_png_for_the_same_inputs(tmp_path):
    from brdfkit.figures.comparison_sheet import comparison_sheet
    from brdfkit.render.image import write_exr

    write_exr(tmp_path / "ref.exr", _disc())
    write_exr(tmp_path / "pred.exr", _disc(value=0.7))
    for out in ("a.png", "b.png"):
        comparison_sheet(tmp_path / "ref.exr", [tmp_path / "pred.exr"], tmp_path / out, progress=False)
    assert (tmp_path / "a.png").read_bytes() == (tmp_path / "b.png").read_bytes()


@pytest.mark.slow
def test_a_sheet_reads_each_table_once_and_takes_renders_made_elsewhere(materials, tmp_path, monkeypatch):
    """Four inputs, more than ``TABLES_KEPT``: each file is read once over the sheet's
    check, renders, scores and antialiasing; a render the loader is given
    (``FileLoader.remember``, the demo's) is shown and scored without a render of its own."""
    import brdfkit.evaluation.comparison as comparison
    from brdfkit.figures.comparison_sheet import comparison_sheet

    four = [str(p) for p in (*materials, tmp_path / "again.binary")]
    (tmp_path / "again.binary").write_bytes(materials[1].read_bytes())
    assert len(four) > comparison.TABLES_KEPT
    reads = []
    read_table = comparison.read_table
    monkeypatch.setattr(comparison, "read_table", lambda path, *a: reads.append(path) or read_table(path, *a))
    comparison_sheet(four[0], four[1:], tmp_path / "s.png", resolution=8, progress=False)
    assert sorted(map(str, reads)) == sorted(four)

    loader = comparison.FileLoader(None, 8, False, keep=len(four))
    made = loader.renders(four[:2])
    again = comparison.FileLoader(None, 8, False, keep=len(four))
    for path, image in zip(four[:2], made):
        again.remember(path, image)
    rows = comparison_sheet(four[0], [four[1]], tmp_path / "t.png", loader=again)
    assert again.counts.renders == 0 and again.counts.cached >= 2
    assert rows == comparison_sheet(four[0], [four[1]], tmp_path / "u.png", loader=loader)
