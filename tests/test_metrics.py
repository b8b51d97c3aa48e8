"""Metrics: BRDF-space log RMSE and the image metrics (PSNR, Delta E 2000, SSIM)."""

import math

import numpy as np
import pytest

from brdfkit.evaluation import metrics
from brdfkit.errors import InputError
from brdfkit.geometry import GRID_SHAPE, cos_theta_i, grid_angles, valid_mask


def _lambert(albedo):
    t = np.empty(GRID_SHAPE + (3,))
    t[:] = np.asarray(albedo, dtype=np.float64) / math.pi
    t[~valid_mask()] = np.nan
    return t


def _image(seed=0, h=32, w=40):
    rng = np.random.default_rng(seed)
    return rng.uniform(0.0, 1.2, size=(h, w, 3)).astype(np.float32)


def test_brdf_log_rmse_identical_is_zero():
    t = _lambert([0.2, 0.5, 0.8])
    assert metrics.brdf_log_rmse(t, t.copy()) == 0.0


@pytest.mark.slow
def test_brdf_log_rmse_matches_hand_computation():
    a, b = _lambert([0.2, 0.5, 0.8]), _lambert([0.3, 0.1, 0.8])
    th, td, pd = np.meshgrid(*grid_angles(), indexing="ij")
    cos = np.clip(cos_theta_i(th, td, pd), 0, None)
    m = valid_mask()
    d = np.log1p(a * cos[..., None]) - np.log1p(b * cos[..., None])
    expected = math.sqrt(np.mean(d[m] ** 2))
    assert metrics.brdf_log_rmse(a, b) == pytest.approx(expected, rel=1e-12)
    assert metrics.brdf_log_rmse(a, b) > 0.01


def test_brdf_log_rmse_uses_cells_measured_in_both():
    a, b = _lambert([0.2, 0.2, 0.2]), _lambert([0.2, 0.2, 0.2])
    # a wildly wrong value where the reference is unmeasured is ignored
    a[0, 0, 0] = 1e6
    b[0, 0, 0] = np.nan
    assert metrics.brdf_log_rmse(a, b) == 0.0


def test_brdf_log_rmse_bad_inputs():
    t = _lambert([0.5] * 3)
    with pytest.raises(InputError, match="shape"):
        metrics.brdf_log_rmse(t[:10], t[:10])
    with pytest.raises(InputError, match="no cell"):
        metrics.brdf_log_rmse(np.full_like(t, np.nan), t)


def test_identical_images():
    img = _image()
    assert metrics.psnr(img, img.copy()) == math.inf
    assert metrics.delta_e_2000(img, img.copy()) == 0.0
    assert metrics.ssim(img, img.copy()) == pytest.approx(1.0, abs=1e-12)


def test_psnr_value_and_clipping():
    ref = np.full((16, 16, 3), 0.5)
    pred = ref.copy()
    pred[:8] = 0.6
    enc = metrics.srgb_oetf(np.array([0.5, 0.6]))
    mse = 0.5 * (enc[1] - enc[0]) ** 2
    assert metrics.psnr(pred, ref) == pytest.approx(10 * math.log10(1 / mse), rel=1e-9)
    # above the display range, differences vanish (documented clip after exposure)
    assert metrics.psnr(np.full((8, 8, 3), 2.0), np.full((8, 8, 3), 5.0)) == math.inf


def test_delta_e_known_pair():
    import colour

    a = np.zeros((8, 8, 3))
    b = np.zeros((8, 8, 3))
    a[:] = [0.2, 0.4, 0.1]
    b[:] = [0.25, 0.35, 0.1]
    xyz = colour.RGB_to_XYZ(np.array([[0.2, 0.4, 0.1], [0.25, 0.35, 0.1]]),
                            colour.RGB_COLOURSPACES["sRGB"], apply_cctf_decoding=False)
    lab = colour.XYZ_to_Lab(xyz, colour.CCS_ILLUMINANTS["CIE 1931 2 Degree Standard Observer"]["D65"])
    expected = float(colour.delta_E(lab[0], lab[1], method="CIE 2000"))
    assert metrics.delta_e_2000(a, b) == pytest.approx(expected, rel=1e-9)
    assert expected > 1.0
    # white maps to L* = 100
    white = metrics._lab(np.ones((1, 1, 3)))
    assert white[0, 0, 0] == pytest.approx(100.0, abs=1e-3)
    assert abs(white[0, 0, 1]) < 0.05 and abs(white[0, 0, 2]) < 0.05


def test_mask_restricts_metrics():
    ref = _image(1)
    pred = ref.copy()
    pred[:, :20] += 0.3  # change only the left half
    mask = np.zeros(ref.shape[:2], bool)
    mask[:, 25:] = True
    assert metrics.psnr(pred, ref, mask) == math.inf
    assert metrics.delta_e_2000(pred, ref, mask) == 0.0
    assert metrics.psnr(pred, ref) < 40
    assert metrics.delta_e_2000(pred, ref) > 0.5
    assert metrics.ssim(pred, ref) < metrics.ssim(pred, ref, mask) <= 1.0


def test_metrics_degrade_with_noise():
    ref = _image(2, 64, 64) * 0.8
    rng = np.random.default_rng(3)
    small = ref + rng.normal(0, 0.01, ref.shape)
    big = ref + rng.normal(0, 0.1, ref.shape)
    assert metrics.psnr(small, ref) > metrics.psnr(big, ref)
    assert metrics.delta_e_2000(small, ref) < metrics.delta_e_2000(big, ref)
    assert metrics.ssim(small, ref) > metrics.ssim(big, ref)


def test_image_metric_bad_inputs():
    img = _image()
    with pytest.raises(InputError, match="sizes differ"):
        metrics.psnr(img, img[:10])
    with pytest.raises(InputError, match=r"\(H, W, 3\)"):
        metrics.psnr(img[..., 0], img[..., 0])
    bad = img.copy()
    bad[0, 0, 0] = np.nan
    with pytest.raises(InputError, match="NaN"):
        metrics.delta_e_2000(bad, img)
    with pytest.raises(InputError, match="no pixel"):
        metrics.ssim(img, img, np.zeros(img.shape[:2], bool))


def test_score_is_what_bench_and_the_metrics_command_report():
    img = _image(4, 32, 32) * 0.7
    table = np.full(GRID_SHAPE + (3,), 0.2)
    table[~valid_mask()] = np.nan
    got = metrics.score(img, img, table, table)
    assert got == {"psnr": metrics.PSNR_CAP, "delta_e": 0.0, "ssim": pytest.approx(1.0), "brdf_log_rmse": 0.0}
    noisy = img + np.random.default_rng(0).normal(0, 0.05, img.shape)
    got = metrics.score(noisy, img)
    assert got["brdf_log_rmse"] is None
    assert got["psnr"] == metrics.psnr(noisy, img) < metrics.PSNR_CAP
    assert got["ssim"] == metrics.ssim(noisy, img) and got["delta_e"] == metrics.delta_e_2000(noisy, img)


@pytest.mark.parametrize("shape", [(64, 64, 3), (9, 13, 3)])
def test_delta_e_and_ssim_are_colour_sciences_and_scikit_images(shape):
    """Delta E 2000 is colour-science's on the display images; SSIM runs in NumPy (no
    scikit-image import in a metrics process): scikit-image's values to 1e-9, on random
    display images."""
    colour = pytest.importorskip("colour")
    skimage_metrics = pytest.importorskip("skimage.metrics")
    from brdfkit.evaluation import metrics

    rng = np.random.default_rng(sum(shape))
    a = rng.uniform(0, 1.2, shape)
    b = np.clip(a + rng.normal(0, 0.05, shape), 0, None)
    space, d65 = colour.RGB_COLOURSPACES["sRGB"], colour.CCS_ILLUMINANTS["CIE 1931 2 Degree Standard Observer"]["D65"]
    lab = [colour.XYZ_to_Lab(colour.RGB_to_XYZ(metrics.display_linear(x), space, apply_cctf_decoding=False), d65)
           for x in (a, b)]
    np.testing.assert_allclose(metrics.delta_e_2000_map(a, b), colour.delta_E(*lab, method="CIE 2000"),
                               rtol=0, atol=1e-9)
    want, smap = skimage_metrics.structural_similarity(metrics.display_encode(a), metrics.display_encode(b),
                                                       data_range=1.0, channel_axis=-1, full=True)
    assert metrics.ssim(a, b) == pytest.approx(want, abs=1e-9)
    mask = rng.uniform(size=shape[:2]) < 0.5
    assert metrics.ssim(a, b, mask) == pytest.approx(smap.mean(-1)[mask].mean(), abs=1e-9)
