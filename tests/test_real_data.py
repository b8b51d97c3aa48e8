"""RGL's and Cornell's own files, as their labs wrote them (skipped without them).

Their licences keep them out of the repository: ``$BRDFKIT_REAL_DATA`` names a folder
holding ``rgl/*_rgb.bsdf`` (isotropic RGB files of RGL's material database) and
``cornell/*.brdf`` (pbrt-v2's ``scenes/brdfs``: acryl_blue, cayman, garnet_red,
krylon_blue, mystique); ``docs/data.md`` says where they were found. Every test here
skips when the variable is unset or a file is missing.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from conftest import run_cli

pytestmark = pytest.mark.realdata
ROOT = os.environ.get("BRDFKIT_REAL_DATA")
CORNELL = ("acryl_blue", "cayman", "garnet_red", "krylon_blue", "mystique")


def _folder(name) -> Path:
    if not ROOT or not (Path(ROOT) / name).is_dir():
        pytest.skip(f"$BRDFKIT_REAL_DATA/{name} is absent")
    return Path(ROOT) / name


def _rgl_files():
    files = sorted(_folder("rgl").glob("*_rgb.bsdf"))
    if not files:
        pytest.skip("no *_rgb.bsdf in $BRDFKIT_REAL_DATA/rgl")
    return files


def _cornell(name) -> Path:
    path = _folder("cornell") / f"{name}.brdf"
    if not path.exists():
        pytest.skip(f"{path} is absent")
    return path


def test_every_real_rgl_file_loads():
    """Including ilm_solo_m_68_rgb.bsdf, whose luminance holds a rounding residue of
    -3.98e-10 (refused before brdfkit read such residues as 0)."""
    from brdfkit.io.rgl_bsdf import read_bsdf

    for path in _rgl_files():
        bsdf = read_bsdf(path)
        assert bsdf.phi_i.size <= 2 and bsdf.resolution >= 2, path.name


@pytest.mark.skipif(not __import__("brdfkit.testing.mitsuba_measured", fromlist=["x"]).mitsuba_available(),
                    reason="mitsuba is not installed")
def test_real_files_render_as_mitsuba_evaluates_them():
    """``load_brdf`` of real files against Mitsuba's ``measured`` ``eval`` with ``si.wi``
    toward the camera, at 500 random pairs each."""
    from brdfkit.files.brdf_file import load_brdf
    from brdfkit.testing.mitsuba_measured import measured_eval

    files = [p for p in _rgl_files() if p.stem in ("paper_white_rgb", "ilm_solo_m_68_rgb", "cardboard_rgb")]
    files = files or _rgl_files()[:3]
    rng = np.random.default_rng(9)

    def dirs(n):
        z, phi = rng.uniform(0.02, 1.0, n), rng.random(n) * 2 * np.pi
        return np.stack([np.sqrt(1 - z * z) * np.cos(phi), np.sqrt(1 - z * z) * np.sin(phi), z], -1)

    light, view = dirs(500), dirs(500)
    for path, theirs in zip(files, measured_eval(files, view, light)):
        ours = load_brdf(path).eval_dirs(light.astype(np.float32), view.astype(np.float32)).astype(np.float64) \
            * light[:, 2:3]
        assert np.abs(ours - theirs).max() < 1e-4 * np.abs(theirs).max(), path.name


def test_convert_of_a_real_file_prints_its_non_reciprocity(tmp_path, capsys):
    path = next((p for p in _rgl_files() if p.stem == "ilm_solo_m_68_rgb"), _rgl_files()[0])
    code, out, err = run_cli(capsys, ["convert", path, "-o", tmp_path / "m.binary"])
    assert code == 0, err
    assert f"{path}: non-reciprocity 0." in out + err and "least-squares rule" in out + err


def test_the_five_cornell_files_read():
    from brdfkit.io.sample_files import read_sample_file

    for name in CORNELL:
        s = read_sample_file(_cornell(name))
        assert len(s) == 1439 and np.isfinite(s.rgb).all() and s.rgb.min() >= 0, name
        assert "31 wavelengths, 400-700 nm" in s.note


def test_sparse_takes_a_cornell_file_as_published_and_as_a_wavelength_csv(tmp_path, monkeypatch, capsys):
    """``brdfkit sparse acryl_blue.brdf -o out.binary`` with the default built-in, and the
    same measurements as a CSV with one column per wavelength."""
    from brdfkit.io.merl import read_merl
    from brdfkit.io.pbrt_brdf import _numbers

    monkeypatch.delenv("BRDFKIT_BUILTIN_MODELS")  # the shipped models, as a user has them
    src = _cornell("acryl_blue")
    code, _, err = run_cli(capsys, ["sparse", src, "-o", tmp_path / "out.binary"])
    assert code == 0, err
    assert "from 1439 samples (method prior" in err
    table = read_merl(tmp_path / "out.binary")
    assert np.nanmax(table) > 0
    values, _ = _numbers(str(src))
    w = int(values[0])
    rows = values[1 + w:].reshape(-1, 4 + w)
    header = "theta_i,phi_i,theta_o,phi_o," + ",".join(f"{x:g}nm" for x in values[1:1 + w])
    (tmp_path / "acryl.csv").write_text(header + "\n" + "\n".join(",".join(f"{x:.6f}" for x in r) for r in rows) + "\n")
    code, _, err = run_cli(capsys, ["sparse", tmp_path / "acryl.csv", "-o", tmp_path / "csv.binary"])
    assert code == 0, err
    np.testing.assert_allclose(read_merl(tmp_path / "csv.binary"), table, rtol=1e-6, atol=1e-9)
