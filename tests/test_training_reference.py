"""Training against another model's reference table (``fit(reference=...)``,
``brdfkit fit -O reference=...``), so that models trained on other materials share one
reference file once packed.

Tiny fits (``conftest.TINY``, 2 steps) on the 3 synthetic materials of the training tests;
reference models are untrained files written with the real ``save_network``.
"""

from __future__ import annotations

import numpy as np
import pytest

from brdfkit.cli import main
from brdfkit.errors import FormatError, InputError
from brdfkit.geometry import N_CELLS, TABLE_SHAPE
from brdfkit.hypernet.mapping import median_reference, to_mapped
from brdfkit.io.merl import read_merl
from brdfkit.models import builtin
from brdfkit.hypernet import packing
from brdfkit.hypernet.network_file import load_network
from brdfkit.hypernet.training.dataset import TrainingSet
from brdfkit.hypernet.training.loop import fit

from conftest import TINY, TINY_LATENT, tiny_cli_options
from helpers_model import make_model
from helpers_training import tiny_library

NAN_BLOCK = (slice(10, 20), slice(30, 40))  # theta_h, theta_d rows left unmeasured in the reference


@pytest.fixture(scope="module")
def lib(tmp_path_factory):
    return tiny_library(tmp_path_factory)


@pytest.fixture(scope="module")
def tables(lib):
    return [read_merl(lib / f"synth-00{i}.binary") for i in range(3)]


@pytest.fixture(scope="module")
def source(tmp_path_factory, tables):
    """A model file whose reference is not the training median (1.5 x the median of two of
    the tables) and is NaN on a block of cells measured in every table."""
    ref = (median_reference(tables[:2]) * np.float32(1.5)).astype(np.float32)
    ref[NAN_BLOCK] = np.nan
    path = tmp_path_factory.mktemp("reference") / "source.safetensors"
    fp = make_model(path, rho_ref=ref, seed=4)
    return path, fp


def tiny_fit(lib, out, **kw):
    return fit(lib, out, **{**TINY, "latent_dim": TINY_LATENT, "progress": False, "steps": 2, **kw})


def _cli(capsys, args):
    with pytest.raises(SystemExit) as e:
        main([str(a) for a in args])
    return e.value.code, capsys.readouterr().err


@pytest.mark.slow
def test_given_reference_replaces_the_median(lib, tables, source, tmp_path, monkeypatch):
    loaded = []
    real = TrainingSet.load

    def spy(cls, *a, **k):  # the training set fit builds, its values before the sampler takes them
        tset = real(*a, **k)
        loaded.append((tset.cells.copy(), tset.values.copy(), list(tset.own)))
        return tset

    monkeypatch.setattr(TrainingSet, "load", classmethod(spy))
    out = tmp_path / "m.safetensors"
    tiny_fit(lib, out, reference=str(source[0]))
    model, given = load_network(out, "cpu"), load_network(source[0], "cpu")
    assert model.rho_ref.tobytes() == given.rho_ref.tobytes()  # bit for bit, NaN included
    assert model.meta["reference_from"] == source[1]

    cells, values, own = loaded[0]
    flat = [t.reshape(N_CELLS, 3) for t in tables]
    measured = np.flatnonzero(np.all([np.isfinite(f).all(1) for f in flat], axis=0))
    ref_ok = np.isfinite(given.rho_ref.reshape(N_CELLS, 3)).all(1)
    assert (~ref_ok[measured]).sum() > 10_000  # the NaN block lies in the measured cells
    np.testing.assert_array_equal(cells, measured[ref_ok[measured]])
    ref_cells = given.rho_ref.reshape(N_CELLS, 3)[cells].astype(np.float64)
    rho = flat[own[0]][cells].astype(np.float32).astype(np.float64)  # the training set holds float32 tables
    want = to_mapped(rho, ref_cells).astype(np.float32)
    np.testing.assert_array_equal(values[0], want)


def test_default_records_no_reference_source(lib, tmp_path):
    out = tmp_path / "m.safetensors"
    tiny_fit(lib, out)
    assert load_network(out, "cpu").meta["reference_from"] is None


@pytest.mark.slow
def test_models_on_other_materials_share_one_reference_file(lib, tmp_path, monkeypatch):
    """The use: a model on 2 materials, one on 3 with the first's reference (named as a
    built-in), packed beside each other with one shared reference file."""
    first, second = tmp_path / "two.safetensors", tmp_path / "three.safetensors"
    tiny_fit(lib, first, exclude=["synth-002"])
    shelf = tmp_path / "shelf"
    shelf.mkdir()
    packing.pack_network(first, shelf / "two.safetensors", reference_file="ref.safetensors")
    entry = packing.manifest_entry(shelf / "two.safetensors", "two", command="fit", validation={})
    builtin.write_manifest(shelf, [entry], default="two")
    monkeypatch.setenv(builtin.BUILTIN_ENV, str(shelf))
    tiny_fit(lib, second, reference="two")
    assert load_network(second, "cpu").meta["reference_from"] == entry["parts"]["network"]["digest"]
    packing.pack_network(second, shelf / "three.safetensors", reference_file="ref.safetensors")
    a, b = (load_network(shelf / f"{n}.safetensors", "cpu") for n in ("two", "three"))
    assert a.rho_ref.tobytes() == b.rho_ref.tobytes()
    # Without the option the reference is the median of 3 materials, and cannot be shared.
    tiny_fit(lib, tmp_path / "own.safetensors")
    with pytest.raises(ValueError, match="another reference table") as e:
        packing.pack_network(tmp_path / "own.safetensors", shelf / "own.safetensors", reference_file="ref.safetensors")
    assert "-O reference=MODEL" in str(e.value) and "same materials" not in str(e.value)


def test_checkpoint_keys_are_documented(lib, source, tmp_path):
    """Every key a training checkpoint holds is listed in brdfkit.hypernet.training.checkpoint's docstring."""
    import re

    from brdfkit.hypernet.training import checkpoint

    out = tmp_path / "m.safetensors"
    tiny_fit(lib, out, reference=str(source[0]))
    state = checkpoint.load_checkpoint(checkpoint.checkpoint_path(out))
    assert state["reference_from"] == source[1]
    documented = set(re.findall(r"``(\w+)", checkpoint.__doc__))
    assert set(state) <= documented, sorted(set(state) - documented)


def test_bad_reference_is_one_line_exit_2(lib, source, tmp_path, capsys):
    out = tmp_path / "m.safetensors"
    for bad, words in ((tmp_path / "missing.safetensors", "no such file"),
                       (lib / "synth-000.binary", "MERL"),
                       ("merl-l40", "unknown model 'merl-l40'")):
        code, err = _cli(capsys, ["fit", lib, "-o", out, "--steps", "1", "-q", *tiny_cli_options(),
                                  "-O", f"reference={bad}"])
        lines = [ln for ln in err.splitlines() if ln.strip()]
        assert code == 2 and len(lines) == 1 and lines[0].startswith("brdfkit: error: "), err
        assert words in lines[0], err
    assert not out.exists()
    with pytest.raises(InputError, match="not a model file"):
        tiny_fit(lib, out, reference=3)
    with pytest.raises(InputError, match="also an input"):
        tiny_fit(lib, source[0], reference=str(source[0]))
    nothing = tmp_path / "nan.safetensors"
    make_model(nothing, rho_ref=np.full(TABLE_SHAPE, np.nan, np.float32))
    with pytest.raises(InputError, match="given reference"):
        tiny_fit(lib, out, reference=str(nothing))
    negative = tmp_path / "negative.safetensors"
    make_model(negative, rho_ref=np.full(TABLE_SHAPE, -1.0, np.float32))
    with pytest.raises(FormatError, match="negative"):
        tiny_fit(lib, out, reference=str(negative))


@pytest.mark.slow
def test_resume_with_another_reference_is_refused(lib, source, tmp_path):
    out = tmp_path / "m.safetensors"
    tiny_fit(lib, out)
    with pytest.raises(InputError, match=r"another reference table \(the median then, model .* now\)"):
        tiny_fit(lib, out, steps=3, resume=True, reference=str(source[0]))
    other = tmp_path / "r.safetensors"
    tiny_fit(lib, other, reference=str(source[0]))
    with pytest.raises(InputError, match="another reference table"):
        tiny_fit(lib, other, steps=3, resume=True)
    tiny_fit(lib, other, steps=3, resume=True, reference=str(source[0]))  # the same one: resumes
    assert load_network(other, "cpu").meta["resumed_from_steps"] == [2]
