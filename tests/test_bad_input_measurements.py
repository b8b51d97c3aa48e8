"""Bad measurement files (pbrt-v2 / Cornell ``.brdf``, measurement CSVs) through every
command that reads sample files: sparse, validate, metrics, plan --within.

Each case: exit code 2, exactly one line on stderr that names the file and the problem,
no traceback, no output file and no temporary file left behind. The battery
(``helpers_measurements.bad_measurement_files``): truncated files, NaN, negative values,
wrong wavelength counts, angles out of range, degrees given for radians (and radians
for degrees), a word for a number, unknown columns, too few wavelengths.
"""

from __future__ import annotations

import pytest

from conftest import one_error_line, run_cli
from helpers_bad_input import check_line, nothing_written
from helpers_measurements import bad_measurement_files

NAMES = ["brdf_truncated", "brdf_empty", "brdf_nan", "brdf_negative", "brdf_count", "brdf_count_fraction",
         "brdf_wavelengths_short", "brdf_theta_range", "brdf_degrees", "brdf_word",
         "csv_truncated", "csv_nan", "csv_negative", "csv_wavelength_count", "csv_theta_range", "csv_degrees",
         "csv_radians_as_degrees", "csv_unknown", "csv_wavelengths_short"]


@pytest.fixture(scope="module")
def bad(tmp_path_factory):
    return bad_measurement_files(tmp_path_factory.mktemp("bad-measurements"))


def test_every_case_is_built(bad):
    assert sorted(bad) == sorted(NAMES)


@pytest.mark.parametrize("name", NAMES)
def test_bad_measurements_through_every_command(bad, good, tmp_path, capsys, name):
    path, message = bad[name]
    runs = {
        "sparse": (["sparse", path, "-m", good / "model.safetensors", "-o", tmp_path / "x.binary"],
                   tmp_path / "x.binary"),
        "validate": (["validate", path, "--method", f"hypernet={good / 'model.safetensors'}", "-o",
                      tmp_path / "v.json"], tmp_path / "v.json"),
        "metrics": (["metrics", "--ref", path, good / "mat.binary"], None),
        "plan": (["plan", "-n", "3", "--design", "uniform", "--within", path, "-o", tmp_path / "p.csv"],
                 tmp_path / "p.csv"),
    }
    for what, (args, output) in runs.items():
        code, _, err = run_cli(capsys, args)
        assert code == 2, (what, err)
        check_line(one_error_line(err), path, message)
        nothing_written(tmp_path, *([output] if output else []))
