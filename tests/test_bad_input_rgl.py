"""Bad RGL .bsdf files through every command that reads BRDF files: convert, render,
metrics, plot, compare, sample, encode (issue 30, docs/errors.md).

Each case: exit code 2, exactly one line on stderr that names the file and the problem,
no traceback, no output file and no temporary file left behind. The bad files:
``helpers_bad_input.rgl_variants`` (truncated, another magic or version, missing or
misshapen fields, NaN, infinite or negative data, spectral, anisotropic).
"""

from __future__ import annotations

import os

import pytest

from conftest import one_error_line, run_cli
from helpers_bad_input import check_line, good_bsdf, nothing_written, rgl_variants


@pytest.fixture(scope="module")
def bad_rgl(tmp_path_factory):
    folder = tmp_path_factory.mktemp("bad-rgl")
    return rgl_variants(folder, good_bsdf(folder / "good.bsdf"))


NAMES = ["empty", "header_10", "table_cut", "data_cut", "one_short", "magic", "version", "merl", "no_vndf",
         "no_fields", "rank", "dtype", "shape", "theta_count", "nan", "inf", "negative", "zero_sigma",
         "theta_order", "spectral", "anisotropic", "missing", "directory"]


def test_every_case_is_built(bad_rgl):
    assert sorted(bad_rgl) == sorted(NAMES)


@pytest.mark.parametrize("output", ["x.binary", "x.bsdf"])
@pytest.mark.parametrize("name", NAMES)
def test_bad_bsdf_through_convert(bad_rgl, tmp_path, capsys, name, output):
    path, message = bad_rgl[name]
    code, _, err = run_cli(capsys, ["convert", path, "-o", tmp_path / output])
    assert code == 2
    check_line(one_error_line(err), path, message)
    nothing_written(tmp_path, tmp_path / output)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["data_cut", "version", "shape", "nan", "spectral", "anisotropic"])
def test_bad_bsdf_through_the_other_commands(bad_rgl, good, tmp_path, capsys, name):
    path, message = bad_rgl[name]
    good_table = good / "mat.binary"
    runs = {
        "render": (["render", path, "-o", tmp_path / "x.exr", "--resolution", "8", "--quiet"], [tmp_path / "x.exr"]),
        "metrics": (["metrics", "--ref", good_table, path, "--resolution", "16", "--quiet"], []),
        "metrics_ref": (["metrics", "--ref", path, good_table, "--resolution", "16", "--quiet"], []),
        "plot": (["plot", good_table, path, "-o", tmp_path / "x.png"], [tmp_path / "x.png"]),
        "compare": (["compare", path, good_table, "-o", tmp_path / "s.png", "--resolution", "16", "--quiet"],
                    [tmp_path / "s.png"]),
        "sample": (["sample", path, "-n", "5", "-o", tmp_path / "s.csv"], [tmp_path / "s.csv"]),
        "encode": (["encode", path, "-m", good / "model.safetensors", "-o", tmp_path / "embs"],
                   [tmp_path / "embs" / f"{path.stem}.emb"]),
    }
    for what, (args, outputs) in runs.items():
        code, _, err = run_cli(capsys, args)
        assert code == 2, (what, err)
        check_line(one_error_line(err), path, message)
        for out in outputs:
            assert not os.path.exists(out), (what, out)
    nothing_written(tmp_path)


def test_convert_output_refusals(bad_rgl, good, tmp_path, capsys):
    good_bsdf_path = bad_rgl["missing"][0].parent / "good.bsdf"
    cases = [
        (["convert", good_bsdf_path, "-o", tmp_path / "x.emb"],
         f"{tmp_path / 'x.emb'}: convert writes a MERL table (.binary) or an RGL file (.bsdf); an embedding "
         f"(.emb) is made by `brdfkit encode`"),
        (["convert", good_bsdf_path, "-o", tmp_path / "x.binary", "--resolution", "8"],
         f"{tmp_path / 'x.binary'}: options of an RGL .bsdf output (--resolution) given for a MERL table"),
        (["convert", good / "samples.csv", "-o", tmp_path / "x.bsdf"],
         f"{good / 'samples.csv'}: not a BRDF file: not a MERL table (.binary), an RGL file (.bsdf) or an "
         f"embedding (.emb)"),
    ]
    for args, line in cases:
        code, _, err = run_cli(capsys, args)
        assert code == 2
        assert one_error_line(err) == f"brdfkit: error: {line}"
    code, _, err = run_cli(capsys, ["convert", good_bsdf_path, "-o", good_bsdf_path])
    assert code == 2 and "brdfkit: error: " in one_error_line(err)
    assert os.listdir(tmp_path) == []


def test_an_empty_field_of_a_vast_shape_is_one_line(tmp_path):
    """Found by the fuzzer: a field with a zero dimension and others beyond any file
    (count 0, so no byte is missing) was reshaped and raised NumPy's ValueError."""
    import struct

    import numpy as np

    from brdfkit.errors import FormatError
    from brdfkit.io.rgl.container import read_tensor_file, write_tensor_file

    path = tmp_path / "vast.bsdf"
    write_tensor_file(path, {"a": np.zeros((2, 3), np.float32)})
    raw = bytearray(path.read_bytes())
    at = raw.index(b"a") + 1 + 11  # after the name: rank (2), dtype (1), offset (8), then the shape
    struct.pack_into("<2Q", raw, at, 2 ** 62, 0)
    path.write_bytes(bytes(raw))
    with pytest.raises(FormatError, match="larger than the file"):
        read_tensor_file(path)
