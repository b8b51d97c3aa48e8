"""Real instrument data in: spectra to linear sRGB, the pbrt-v2 / Cornell ``.brdf``
reader, measurement CSVs in every angle convention, and the commands that take them
(sparse, validate, metrics, plan --within) with the held-out error.

The files are written by the tests (``helpers_measurements``); the five Cornell files
themselves are ``test_real_data.py``'s. Bad files: ``test_bad_input_measurements.py``.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import run_cli
from helpers_measurements import WAVELENGTHS, csv_text, directions, spectra, write_brdf, write_csv

from brdfkit.io.sample_files import read_sample_file


def test_spectra_to_rgb_is_colour_sciences_conversion():
    """The matrix is colour-science's ``sd_to_XYZ`` (ASTM E308, CIE 1931 2 degree, D65)
    and sRGB's matrix, applied to any spectrum; a flat spectrum is grey."""
    import warnings

    import colour

    from brdfkit.io.spectral import spectra_to_rgb, spectral_to_rgb_matrix

    m = spectral_to_rgb_matrix(WAVELENGTHS)
    np.testing.assert_allclose(np.ones(31) @ m, 1.0, atol=3e-4)
    v = np.random.default_rng(0).random(31)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        xyz = colour.sd_to_XYZ(colour.SpectralDistribution(dict(zip(WAVELENGTHS, v))),
                               colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"], colour.SDS_ILLUMINANTS["D65"])
    direct = np.asarray(colour.RGB_COLOURSPACES["sRGB"].matrix_XYZ_to_RGB) @ (xyz / 100)
    np.testing.assert_allclose(v @ m, direct, rtol=1e-10)
    for uneven in ([400.0, 550.0, 700.0], [395.0, 420.0, 455.0, 500.0, 560.0, 600.0, 650.0, 705.5]):
        np.testing.assert_allclose(np.ones(len(uneven)) @ spectral_to_rgb_matrix(uneven), 1.0, atol=3e-4)
    blue = np.where(WAVELENGTHS < 470, 1.0, 0.0)  # outside the sRGB gamut: red goes negative
    rgb, clipped = spectra_to_rgb(blue[None], WAVELENGTHS)
    assert clipped >= 1 and rgb.min() == 0.0 and rgb[0, 2] > rgb[0, 1]


def test_brdf_file_and_every_csv_convention_read_the_same(tmp_path):
    n = 40
    brdf = read_sample_file(write_brdf(tmp_path / "m.brdf", n))
    ti, pi_, to, po = directions(n)
    values = spectra(n)
    assert len(brdf) == n and "CIE 1931 2 degree observer, illuminant D65" in brdf.note
    np.testing.assert_allclose(brdf.rgb, np.repeat(values[:, :1], 3, 1), rtol=5e-4)  # flat spectra: grey
    rad = read_sample_file(write_csv(tmp_path / "rad.csv", n))
    deg = read_sample_file(write_csv(tmp_path / "deg.csv", n, degrees=True))
    wi = np.stack([np.sin(ti) * np.cos(pi_), np.sin(ti) * np.sin(pi_), np.cos(ti)], -1)
    wo = np.stack([np.sin(to) * np.cos(po), np.sin(to) * np.sin(po), np.cos(to)], -1)
    vectors = ("wi_x", "wi_y", "wi_z", "wo_x", "wo_y", "wo_z")
    (tmp_path / "vec.csv").write_text(csv_text((*wi.T, *wo.T), values, vectors))
    rgb = brdf.rgb  # the same colours as r,g,b columns
    (tmp_path / "rgb.csv").write_text(csv_text((ti, pi_, to, po), rgb, value_names=("b", "r", "g")))
    nm = read_sample_file(tmp_path / "vec.csv")
    for other in (rad, deg, nm):
        for a, b in zip((brdf.theta_h, brdf.theta_d, brdf.phi_d), (other.theta_h, other.theta_d, other.phi_d)):
            np.testing.assert_allclose(a, b, atol=1e-5)
        np.testing.assert_allclose(other.rgb, brdf.rgb, rtol=1e-5)  # the .brdf holds 6 decimals
    mixed = read_sample_file(tmp_path / "rgb.csv")  # columns b,r,g: taken by name
    np.testing.assert_allclose(mixed.rgb[:, [2, 0, 1]], rgb, rtol=1e-6)


def test_sample_csv_of_brdfkit_is_read_as_before(good):
    from brdfkit.io.samples import read_samples

    a, b = read_samples(good / "samples.csv"), read_sample_file(good / "samples.csv")
    assert a.digest() == b.digest() and b.note == ""


def test_split_and_sample_errors():
    from brdfkit.evaluation.holdout import sample_errors, split
    from brdfkit.io.samples import SampleSet
    from brdfkit.testing.examples import lambertian_table

    rest, held = split(100, 0.3, seed=4)
    assert held.size == 30 and rest.size == 70 and not set(rest) & set(held)
    again, _ = split(100, 0.3, seed=4)
    assert np.array_equal(rest, again) and not np.array_equal(rest, split(100, 0.3, seed=5)[0])
    rng = np.random.default_rng(1)
    th, td, pd = rng.uniform(0.05, 0.7, 50), rng.uniform(0.05, 0.7, 50), rng.uniform(0, np.pi, 50)  # all lit
    s = SampleSet(th, td, pd, np.full((50, 3), 0.4 / np.pi))
    e = sample_errors(lambertian_table((0.4, 0.4, 0.4)), s)
    assert e["covered"] == 50 and e["log_rmse"] < 1e-6 and e["luminance_error"] < 1e-6
    e = sample_errors(lambertian_table((0.8, 0.8, 0.8)), s)  # twice as bright
    assert e["luminance_error"] == pytest.approx(1.0, rel=1e-6)
    assert e["luminance_error_median"] == pytest.approx(1.0, rel=1e-6)
    cos = s.cos_i()
    want = np.sqrt(np.mean((np.log1p(0.8 / np.pi * cos) - np.log1p(0.4 / np.pi * cos)) ** 2))
    assert e["log_rmse"] == pytest.approx(want, rel=1e-6)


@pytest.mark.slow
def test_sparse_validate_metrics_and_plan_take_measurement_files(good, tmp_path, capsys):
    brdf = write_brdf(tmp_path / "m.brdf", 80)
    csv = write_csv(tmp_path / "m.csv", 80, degrees=True)
    model = good / "model.safetensors"
    # the CSV reads as the .brdf does (the test above); one reconstruction through the command
    assert len(read_sample_file(csv)) == 80
    code, out, err = run_cli(capsys, ["sparse", brdf, "-m", model, "--no-refine", "-o", tmp_path / "r.binary"])
    assert code == 0, err
    assert "converted to RGB: CIE 1931 2 degree observer, illuminant D65, linear sRGB" in err
    code, out, err = run_cli(capsys, ["validate", brdf, "-n", "20", "--seed", "0", "--seed", "1",
                                      "--method", f"hypernet={model}", "--json", "-o", tmp_path / "v.json"])
    assert code == 0, err
    report = json.loads(out)
    assert report == json.loads((tmp_path / "v.json").read_text())
    assert len(report["rows"]) == 2 and {r["n"] for r in report["rows"]} == {20}
    assert all(r["held_out"] == 24 and r["covered"] == 24 for r in report["rows"])
    assert all(np.isfinite(r["log_rmse"]) for r in report["rows"])
    assert [(r["n"], r["seeds"]) for r in report["summary"]] == [(20, [0, 1])]
    code, _, err = run_cli(capsys, ["validate", brdf, "-n", "57", "--method", f"hypernet={model}"])
    assert code == 2 and "-n 57: 56 samples are left after holding out 24 (0.3 of 80)" in err
    code, out, err = run_cli(capsys, ["metrics", "--ref", brdf, tmp_path / "r.binary", "--json"])
    assert code == 0, err
    scores = json.loads(out)
    assert scores["samples"] == 80 and scores["covered"] == 80 and scores["log_rmse"] >= 0
    # a sample file is only ever the reference: without --ref, in either order, the same scores
    for args in ([tmp_path / "r.binary", brdf], [brdf, tmp_path / "r.binary"]):
        code, out, err = run_cli(capsys, ["metrics", *args, "--json"])
        assert code == 0 and json.loads(out) == scores, err
    code, out, err = run_cli(capsys, ["plan", "-n", "12", "--design", "uniform", "--within", brdf, "-o",
                                      tmp_path / "p.csv"])
    assert code == 0, err
    from brdfkit.io.directions import read_directions

    chosen = read_directions(tmp_path / "p.csv")
    own = read_sample_file(brdf)
    assert len(chosen) == 12
    for i in range(12):  # each is one of the file's own directions, at its own angles
        d = np.abs(own.theta_h - chosen.theta_h[i]) + np.abs(own.theta_d - chosen.theta_d[i]) + \
            np.abs(own.phi_d - chosen.phi_d[i])
        assert d.min() < 1e-12
