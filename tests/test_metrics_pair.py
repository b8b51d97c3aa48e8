"""``brdfkit metrics`` of two BRDFs renders the pair in one quadrature pass, and a
reference scored against several predictions is rendered once (issue 14 item 2).

The one-pass images must be the separate renders to the bit: the pass shares the nodes,
shares and weights, and only the BRDF evaluations differ.
"""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from brdfkit.evaluation.comparison import FileLoader, compare_files
from brdfkit.io.merl import write_merl
from brdfkit.evaluation.metrics import score
from brdfkit.render import quadrature
from brdfkit.render.renderable import TableBRDF
from brdfkit.render.scene import Scene

from helpers_model import make_model, material_table

RES = 16


def _same(a, b):
    assert a.dtype == b.dtype and a.shape == b.shape
    np.testing.assert_array_equal(a, b)


def test_one_pass_equals_separate_renders_table_and_neural(tmp_path):
    from brdfkit import api
    from brdfkit.io.embedding import write_embedding
    from brdfkit.files.brdf_file import load_brdf
    from brdfkit.acquisition.sampling import draw_samples

    make_model(tmp_path / "m.safetensors", seed=0)
    model = api.load_model(tmp_path / "m.safetensors", "cpu")
    write_embedding(tmp_path / "w.emb", api.encode(draw_samples(material_table(1), 200, seed=0), model, source="w"))
    neural = load_brdf(tmp_path / "w.emb", model=model)
    brdfs = [TableBRDF(material_table(1), "ggx", device="cpu"), TableBRDF(material_table(0), "white", device="cpu"),
             neural]
    scene = Scene(resolution=RES)
    stats = quadrature.RenderStats()
    together = quadrature.render_many(brdfs, scene, stats=stats)
    assert len(together) == 3
    for brdf, (img, mask) in zip(brdfs, together):
        alone_stats = quadrature.RenderStats()
        alone, alone_mask = quadrature.render(brdf, scene, stats=alone_stats)
        _same(img, alone)
        _same(mask, alone_mask)
        assert alone_stats.evaluations == stats.evaluations > 0
    assert not np.array_equal(together[0][0], together[1][0])


def _reference_and_two(folder, names):
    """MERL files ``folder/NAME.binary`` of the reference (material 0), a prediction
    (material 1) and that prediction at half its value."""
    paths = [folder / f"{n}.binary" for n in names]
    for path, table in zip(paths, (material_table(0), material_table(1), np.asarray(material_table(1)) * 0.5)):
        write_merl(path, table)
    return paths


@pytest.mark.slow
def test_metrics_of_two_tables_one_pass_and_the_reference_cached(tmp_path):
    ref, pred, pred2 = _reference_and_two(tmp_path, ("ref", "pred", "pred2"))
    loader = FileLoader(resolution=RES, progress=False)
    got = compare_files(loader, str(pred), str(ref))
    assert (loader.counts.passes, loader.counts.renders, loader.counts.cached) == (1, 2, 0)

    # what rendering each alone and scoring gives
    scene = Scene(resolution=RES)
    img_p, _ = quadrature.render(TableBRDF(material_table(1), device="cpu"), scene)
    img_r, _ = quadrature.render(TableBRDF(material_table(0), device="cpu"), scene)
    want = score(img_p, img_r, material_table(1), material_table(0))
    assert got == want

    # the same reference again, under another name: only the new prediction is rendered
    shutil.copy(ref, tmp_path / "ref-copy.binary")
    got2 = compare_files(loader, str(pred2), str(tmp_path / "ref-copy.binary"))
    assert (loader.counts.passes, loader.counts.renders, loader.counts.cached) == (2, 3, 1)
    assert got2["psnr"] != got["psnr"]
    # a cached render is handed out as a copy: changing it does not change the cache
    img = loader.image(str(ref))
    img[:] = 0
    assert loader.image(str(ref)).any()
    assert loader.counts.renders == 3


def test_a_changed_file_or_resolution_is_rendered_again(tmp_path):
    path = tmp_path / "a.binary"
    write_merl(path, material_table(0))
    loader = FileLoader(resolution=RES, progress=False)
    a = loader.image(str(path))
    loader.image(str(path), RES + 4)
    assert loader.counts.renders == 2
    write_merl(path, material_table(1))
    b = loader.image(str(path))
    assert loader.counts.renders == 3 and not np.array_equal(a, b)


def test_the_same_file_twice_is_rendered_once(tmp_path):
    path = tmp_path / "a.binary"
    write_merl(path, material_table(1))
    loader = FileLoader(resolution=RES, progress=False)
    r = compare_files(loader, str(path), str(path))
    assert r["psnr"] == 100.0 and r["delta_e"] == 0.0  # identical images (PSNR capped)
    assert (loader.counts.passes, loader.counts.renders, loader.counts.cached) == (1, 1, 1)


@pytest.mark.slow
def test_sheet_renders_all_brdfs_in_one_pass_with_the_same_scores(tmp_path):
    """``brdfkit compare`` of a table against two tables: the scores of ``metrics``."""
    from brdfkit.figures.comparison_sheet import comparison_sheet

    ref, a, b = _reference_and_two(tmp_path, ("ref", "a", "b"))
    rows = comparison_sheet(ref, [a, b], tmp_path / "sheet.png", resolution=RES, progress=False)
    loader = FileLoader(resolution=RES, progress=False)
    assert rows["a"] == compare_files(loader, str(a), str(ref))
    assert rows["b"] == compare_files(loader, str(b), str(ref))
    assert (tmp_path / "sheet.png").is_file()


def test_each_table_is_read_once_for_a_pair(tmp_path, monkeypatch):
    """The check, the render and the BRDF-space error of ``metrics a b`` share one read
    of each table (it was three: 1 s of the command for two MERL files)."""
    import brdfkit.io.merl

    a, b = tmp_path / "a.binary", tmp_path / "b.binary"
    write_merl(a, material_table(0))
    write_merl(b, material_table(1))
    reads = []
    real = brdfkit.io.merl.read_merl
    monkeypatch.setattr(brdfkit.io.merl, "read_merl", lambda p, *k, **kw: reads.append(str(p)) or real(p, *k, **kw))
    r = compare_files(FileLoader(resolution=RES, progress=False), str(a), str(b))
    assert sorted(reads) == sorted([str(a), str(b)])
    assert np.isfinite(r["brdf_log_rmse"]) and r["brdf_log_rmse"] > 0


def test_two_tables_stacked_in_one_pass_equal_separate_renders(monkeypatch):
    """Tables rendered together are looked up together (``TableStackBRDF``: the corners
    once), a neural BRDF between them apart; each image is its separate render to the bit,
    NaN semantics included (one table unmeasured outside MERL's region and in holes, where
    its corners are skipped or 0)."""
    from brdfkit.render import renderable as brdf_mod
    from brdfkit.render.renderable import TableStackBRDF, stack_tables

    from helpers_foundation import measured_mask

    holes = np.array(material_table(1), dtype=np.float64)
    holes[~measured_mask()] = np.nan
    holes[np.random.default_rng(0).random(holes.shape[:3]) < 0.2] = np.nan
    holes[30:40, 10:20] = np.nan
    made = []
    real = brdf_mod.TableStackBRDF
    monkeypatch.setattr(brdf_mod, "TableStackBRDF", lambda b: made.append(real(b)) or made[-1])
    scene = Scene(resolution=32)
    brdfs = [TableBRDF(material_table(0), "white", device="cpu"), _Scaled(0.5, material_table(1)),
             TableBRDF(holes, "holes", device="cpu")]
    passes = stack_tables(brdfs)
    assert [idx for _, idx in passes] == [[0, 2], [1]] and isinstance(passes[0][0], TableStackBRDF)
    made.clear()
    together = quadrature.render_many(brdfs, scene)
    assert len(made) == 1 and all(b._rows is not None for b in made[0].brdfs)
    for brdf, (img, _) in zip(brdfs, together):
        alone, _ = quadrature.render(brdf, scene)
        _same(img, alone)
    assert not np.array_equal(together[0][0], together[2][0])


class _Scaled:
    """A BRDF that is not a table (renders alone in a pass)."""

    def __init__(self, k, table):
        self.inner, self.k, self.name, self.device = TableBRDF(table, device="cpu"), k, "scaled", "cpu"

    def eval_dirs(self, wi, wo):
        return self.inner.eval_dirs(wi, wo) * self.k
