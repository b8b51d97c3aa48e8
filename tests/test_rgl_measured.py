"""Measured .bsdf files as Mitsuba 3 renders them: rounding residues, non-reciprocity,
the view-conditioned evaluation of render and metrics, the reciprocity rules of a table.

The files here are written by the tests (RGL's own are in ``test_real_data.py``, which
skips without them): a small brdfkit file, and the same file made non-reciprocal by
scaling its values per incident elevation (what a measurement's conditioned
parameterization can hold and a MERL table cannot). The judge of the evaluation is
Mitsuba's ``measured`` plugin in a child process (``brdfkit.testing.mitsuba_measured``).
"""

from __future__ import annotations

import numpy as np
import pytest

from conftest import one_error_line, run_cli

from brdfkit.io.rgl.container import read_tensor_file, write_tensor_file
from brdfkit.io.rgl.fit import FitSettings
from brdfkit.io.rgl_bsdf import RULES, read_bsdf, write_bsdf
from brdfkit.materials import synthetic
from brdfkit.testing.mitsuba_measured import measured_eval, measured_render, mitsuba_available

needs_mitsuba = pytest.mark.skipif(not mitsuba_available(), reason="mitsuba is not installed")
SMALL = FitSettings(resolution=8, theta_i=4, ndf=16, vndf=(4, 8))


def _pairs(n, seed):
    rng = np.random.default_rng(seed)

    def dirs():
        z, phi = rng.uniform(0.05, 1.0, n), rng.random(n) * 2 * np.pi
        r = np.sqrt(1 - z * z)
        return np.stack([r * np.cos(phi), r * np.sin(phi), z], -1)

    return dirs(), dirs()


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """``{"reciprocal": path, "skewed": path}``: a GGX material written by brdfkit, and
    the same file with its values scaled by ``1 + 3 theta_i / (pi/2)``, so that the value
    conditioned on a grazing direction is up to 4 times the other."""
    folder = tmp_path_factory.mktemp("measured")
    material = next(m for m in synthetic.library(16, seed=0) if m.name == "synth-001")
    write_bsdf(folder / "reciprocal.bsdf", synthetic.table(material), SMALL, description="reciprocal")
    fields = read_tensor_file(folder / "reciprocal.bsdf")
    scale = 1.0 + 3.0 * fields["theta_i"].astype(np.float64) / (np.pi / 2)
    fields["rgb"] = (fields["rgb"] * scale[None, :, None, None, None]).astype(np.float32)
    write_tensor_file(folder / "skewed.bsdf", fields)
    return {"reciprocal": folder / "reciprocal.bsdf", "skewed": folder / "skewed.bsdf"}


def test_rounding_residues_read_as_zero_and_clear_negatives_refused(files, tmp_path):
    """RGL's ilm_solo_m_68_rgb.bsdf holds -3.98e-10 in its luminance: within float32
    rounding of zero (1e-6 of the field's largest), so read as 0; -1e-3 of it is data."""
    from brdfkit.errors import FormatError

    fields = read_tensor_file(files["reciprocal"])
    top = float(fields["luminance"].max())
    for value, ok in ((-4e-10 * top, True), (-1e-7 * top, True), (-1e-3 * top, False)):
        f = dict(fields)
        f["luminance"] = fields["luminance"].copy()
        f["luminance"][0, 2, 3, 4] = value
        write_tensor_file(tmp_path / "x.bsdf", f)
        if ok:
            read_bsdf(tmp_path / "x.bsdf").eval(*_pairs(10, 0))
        else:
            with pytest.raises(FormatError, match="field 'luminance' holds negative values"):
                read_bsdf(tmp_path / "x.bsdf")


@needs_mitsuba
def test_render_evaluation_is_mitsubas_conditioned_on_the_view(files):
    """``load_brdf`` of a .bsdf evaluates it as Mitsuba's ``measured`` does with ``si.wi``
    toward the camera: ``eval_dirs(light, view) cos(light)`` is Mitsuba's ``eval(view,
    light)``, and on the skewed file far from the other conditioning."""
    from brdfkit.files.brdf_file import load_brdf
    from brdfkit.render.measured import MeasuredBRDF

    light, view = _pairs(400, 3)
    theirs = measured_eval(files["skewed"], view, light)
    brdf = load_brdf(files["skewed"])
    assert isinstance(brdf, MeasuredBRDF)
    ours = brdf.eval_dirs(light.astype(np.float32), view.astype(np.float32)).astype(np.float64) * light[:, 2:3]
    scale = np.abs(theirs).max()
    assert np.abs(ours - theirs).max() < 1e-4 * scale
    swapped = brdf.bsdf.eval(light, view)
    assert np.abs(swapped - theirs).max() > 0.1 * scale


def test_reciprocity_rules_and_non_reciprocity(files):
    bsdf = read_bsdf(files["skewed"])
    wi, wo = _pairs(300, 4)
    a, b = bsdf.conditioned(wi, wo)
    ci, co = wi[:, 2:3], wo[:, 2:3]
    expected = {"least-squares": (a * co ** 2 + b * ci ** 2) / (co ** 2 + ci ** 2), "mean": (a + b) / 2,
                "grazing": np.where(ci < co, a, b), "steep": np.where(ci < co, b, a)}
    for rule in RULES:
        f = bsdf.brdf(wi, wo, rule)
        np.testing.assert_allclose(f, np.maximum(expected[rule], 0), rtol=1e-12, atol=0, err_msg=rule)
        np.testing.assert_allclose(f, bsdf.brdf(wo, wi, rule), rtol=1e-12, atol=0, err_msg=rule)  # reciprocal
    from brdfkit.errors import InputError

    with pytest.raises(InputError, match="unknown reciprocity rule"):
        bsdf.brdf(wi, wo, "median")



@pytest.fixture(scope="module")
def skewed_grazing(files):
    """The skewed file's table by the grazing rule and its non-reciprocity (a second of
    evaluation on an idle core: computed once)."""
    return read_bsdf(files["skewed"]).reciprocal_table("grazing")


@pytest.mark.slow
def test_non_reciprocity_of_the_skewed_file(skewed_grazing):
    # brdfkit's own small file, fitted per incident elevation, is 0.03 from reciprocal
    # (8 x 8 x 4 grid); the skewed one more.
    assert skewed_grazing[1] > 0.05


@pytest.mark.slow
def test_convert_prints_the_non_reciprocity_and_applies_the_rule(files, skewed_grazing, tmp_path, capsys):
    from brdfkit.cli import convert
    from brdfkit.io.merl import read_merl

    assert convert.RULES == RULES
    table, asym = skewed_grazing
    code, out, err = run_cli(capsys, ["convert", files["skewed"], "-o", tmp_path / "g.binary",
                                      "--reciprocity", "grazing"])
    assert code == 0, err
    assert f"non-reciprocity {asym:.4f}" in out + err and "grazing rule" in out + err
    back = read_merl(tmp_path / "g.binary")
    np.testing.assert_allclose(back, table, rtol=1e-6, atol=1e-12)  # the MERL colour scales' rounding
    code, _, err = run_cli(capsys, ["convert", files["skewed"], "-o", tmp_path / "x.binary", "--reciprocity", "x"])
    assert code == 2 and "Invalid value for '--reciprocity'" in one_error_line(err)


@pytest.mark.slow
@needs_mitsuba
def test_render_of_a_non_reciprocal_file_is_mitsubas(files):
    """brdfkit's render of the skewed file agrees with Mitsuba's render of it better than
    the render of any reciprocal table of it can (a small version of
    ``benchmarks/studies/rgl_real.py --mitsuba``)."""
    import dataclasses

    from brdfkit.files.brdf_file import load_brdf
    from brdfkit.evaluation.metrics import psnr
    from brdfkit.render.quadrature import render
    from brdfkit.render.renderable import TableBRDF
    from brdfkit.render.scene import REFERENCE

    scene = dataclasses.replace(REFERENCE, resolution=16, supersample=3)
    theirs = measured_render(files["skewed"], resolution=16, spp=512, seed=2)
    inner = scene.pixel_normals()[1].all(2)
    direct = psnr(render(load_brdf(files["skewed"]), scene)[0], theirs, inner)
    table = psnr(render(TableBRDF(read_bsdf(files["skewed"]).to_table(), device="cpu"), scene)[0], theirs, inner)
    assert direct > 30.0 and direct > table + 3.0, (direct, table)
