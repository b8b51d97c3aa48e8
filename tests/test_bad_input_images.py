"""Bad OpenEXR images, and bad inputs in general, through ``brdfkit metrics`` (issue 6,
docs/errors.md): exit code 2, one line on stderr naming the file, a clean stdout, and
every input checked before any rendering.
"""

from __future__ import annotations

import pytest

from conftest import one_error_line, run_cli


@pytest.fixture(scope="module")
def bad_exr(tmp_path_factory):
    import numpy as np

    from brdfkit.render.image import write_exr

    d = tmp_path_factory.mktemp("bad-exr")
    img = np.linspace(0, 1, 16 * 16 * 3, dtype=np.float32).reshape(16, 16, 3)
    write_exr(d / "good.exr", img)
    good_bytes = (d / "good.exr").read_bytes()
    (d / "empty.exr").write_bytes(b"")
    (d / "text.exr").write_text("not an image\n")
    (d / "truncated.exr").write_bytes(good_bytes[:len(good_bytes) // 2])
    (d / "header-only.exr").write_bytes(good_bytes[:40])
    nan = img.copy()
    nan[3, 4, 1] = np.nan
    import OpenEXR  # write_exr refuses NaN; a file made elsewhere may hold it

    OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage},
                 {"RGB": nan}).write(str(d / "nan.exr"))
    return d


@pytest.mark.parametrize("name, message", [
    ("missing", "no such file"),
    ("empty", "not an OpenEXR image (bad magic number)"),
    ("text", "not an OpenEXR image (bad magic number)"),
    ("truncated", "cannot read OpenEXR image ("),
    ("header-only", "cannot read OpenEXR image ("),
    ("nan", "OpenEXR image holds NaN or infinite pixels"),
])
@pytest.mark.parametrize("position", ["pred", "ref"])
def test_bad_exr_through_metrics(bad_exr, capsys, name, message, position):
    bad, good_img = bad_exr / f"{name}.exr", bad_exr / "good.exr"
    args = ["--ref", good_img, bad] if position == "pred" else ["--ref", bad, good_img]
    code, _, err = run_cli(capsys, ["metrics", *args, "--json"])
    assert code == 2
    line = one_error_line(err)
    assert line.startswith(f"brdfkit: error: {bad}: {message}"), line


def test_damaged_exr_gives_one_line_and_a_clean_stdout(tmp_path):
    # Regression, found by benchmarks/fuzz_parsers.py: the OpenEXR library printed
    # "x.exr: (EXR_ERR_BAD_CHUNK_LEADER) ..." on stderr and "Warning: Exception raised
    # reading pixel data ..." on stdout (breaking --json) besides brdfkit's own line.
    # A real process: C-level output bypasses pytest's capture.
    import numpy as np

    from brdfkit.render.image import write_exr

    from conftest import run_brdfkit

    write_exr(tmp_path / "good.exr", np.ones((16, 16, 3), np.float32))
    raw = bytearray((tmp_path / "good.exr").read_bytes())
    # one chunk: the offset table is 8 bytes holding the offset just after it
    table = next(i for i in range(len(raw) - 8) if int.from_bytes(raw[i:i + 8], "little") == i + 8)
    raw[table + 8:table + 16] = b"\xff" * 8  # the chunk's scanline number
    (tmp_path / "bad.exr").write_bytes(bytes(raw))
    r = run_brdfkit(["metrics", "--ref", tmp_path / "good.exr", tmp_path / "bad.exr", "--json"])
    assert r.returncode == 2 and r.stdout == ""
    assert r.stderr.splitlines() == [
        f"brdfkit: error: {tmp_path / 'bad.exr'}: cannot read OpenEXR image (EXR_ERR_BAD_CHUNK_LEADER: "
        f"Preparing to read scanline 0 (chunk 0), found corrupt leader: scanline says -1, expected 0)"]


def test_metrics_checks_both_inputs_before_rendering(good, bad_merl, capsys, monkeypatch):
    # Regression: `brdfkit metrics --ref BAD.binary GOOD.binary` rendered GOOD (256 px: 2.5 min
    # on the busy 2-core machine) before it read BAD and refused it.
    import brdfkit.files.render_file as cli_render

    def no_render(*a, **k):
        raise AssertionError("rendered before checking the inputs")

    monkeypatch.setattr(cli_render, "render_brdf_file", no_render)
    for args, bad in ((["--ref", bad_merl["nan"], good / "mat.binary"], bad_merl["nan"]),
                      ([good / "a.emb", bad_merl["red_half"], "-m", good / "model.safetensors"], bad_merl["red_half"]),
                      ([good / "mat.binary", good / "other.emb", "-m", good / "model.safetensors"], None)):
        code, _, err = run_cli(capsys, ["metrics", *args, "--json"])
        assert code == 2
        line = one_error_line(err)
        assert (str(bad) in line) if bad else ("other.emb was made with hypernet decoder" in line), line
