"""``brdfkit demo`` end to end on a tiny budget (3 materials, 10 steps, tiny model)."""

from __future__ import annotations

import os
import re

import numpy as np
import pytest
from rich.console import Console

from brdfkit.demos.synthetic_training import choose_holdout, render_psnr, write_demo_library
from brdfkit.io.embedding import read_embedding
from brdfkit.io.merl import read_merl
from brdfkit.hypernet.network_file import load_network

from conftest import run_cli, tiny_cli_options


def test_holdout_spreads_over_random_materials():
    names = ["stiff-black", "stiff-grazing", "stiff-mirror", "stiff-white"] + [f"synth-{i:03d}" for i in range(16)]
    assert choose_holdout(names, 4) == ["synth-002", "synth-006", "synth-010", "synth-014"]
    assert choose_holdout(names[:5], 2) == ["stiff-grazing", "stiff-white"]


def test_render_psnr_through_the_reference_renderer():
    from brdfkit.materials.synthetic import STIFF, table

    score = render_psnr(resolution=12)
    if score is None:
        pytest.skip("brdfkit.render.quadrature.render is not available")
    white = table(STIFF[2])
    assert score(white, white) == float("inf")
    assert 0 < score(white * 0.5, white) < 30


@pytest.mark.slow
def test_demo_runs_end_to_end(tmp_path, capsys):
    out = tmp_path / "demo"
    tiny = tiny_cli_options(latent=False)
    # in this process (the command line's entry point): a process of its own adds only its start-up
    code, report, stderr = run_cli(capsys, ["demo", "--out", str(out), "--materials", "3", "--holdout", "1",
                                            "--steps", "10", "--no-render", *tiny])
    assert code == 0, stderr[-3000:]
    assert "Held-out materials: BRDF log RMSE" in report and "Times" in report
    mean = re.search(r"mean\s*[│|]\s*([\d.]+)\s*[│|]\s*([\d.]+)\s*[│|]\s*([\d.]+)\s*[│|]\s*([\d.]+)", report)
    assert mean, report
    assert all(np.isfinite(float(v)) for v in mean.groups())
    assert f"writing into {out}" in stderr.replace("\n", "")
    # No dense table kept by default: the library and the decoded tables lived in a
    # temporary folder and in memory.
    assert "were not kept" in report and not (out / "materials").exists() and not (out / "decoded").exists()
    assert not [n for n in os.listdir(out) if n.startswith(".")]

    model = load_network(out / "model.safetensors", "cpu")
    held = model.meta["excluded"]
    assert len(held) == 1 and held[0] not in model.meta["materials"]
    assert model.meta["steps"] == 10
    name = held[0]
    # Every file the report lists exists, and they are what they claim to be.
    for rel in re.findall(r"^\s+(\S+[^/\s])\s+\(\d", report, flags=re.M):
        assert (out / rel).is_file(), rel
    for f in (f"{name}.emb", f"{name}-40samples.emb", f"{name}-400samples.emb"):
        emb = read_embedding(out / "embeddings" / f)
        assert emb.decoder == model.digest
    mixes = [f for f in os.listdir(out / "embeddings") if "+" in f]
    assert len(mixes) == 1


@pytest.mark.slow
def test_demo_keep_tables_writes_library_and_decoded(tmp_path, monkeypatch):
    """``keep_tables``: the library and the decoded tables written, and a kept library
    reused by the next run with the same count and seed. The full tables' encodes make
    the encoder's pass alone (what is checked is where the tables go; the refinement on
    screen, seconds a table, is the end-to-end test's)."""
    import brdfkit.api
    from brdfkit.demos.synthetic_training import run_demo

    from conftest import TINY

    encode = brdfkit.api.encode
    monkeypatch.setattr(brdfkit.api, "encode", lambda data, model, **kw: encode(data, model, **{**kw, "refine": False}))
    out = tmp_path / "demo"
    res = run_demo(str(out), steps=2, n_materials=3, holdout=1, render=False, device="cpu", keep_tables=True,
                   options={**TINY, "latent_dim": 4})
    assert res.keep_tables and sorted(os.listdir(out / "materials")) == sorted(
        [os.path.basename(p) for p in res.materials] + ["library.json"])
    decoded = read_merl(out / "decoded" / f"{res.held[0]}.binary")
    assert np.isfinite(decoded).any()
    assert len([f for f in os.listdir(out / "decoded") if "+" in f]) == 1
    assert all(os.path.isfile(p) for p in res.files)
    # A kept library (--keep-tables) is reused by the next run with the same count and seed.
    name = res.held[0]
    mtime = os.path.getmtime(out / "materials" / f"{name}.binary")
    paths = write_demo_library(str(out / "materials"), 3, 0, Console(stderr=True))
    assert len(paths) == 3 and os.path.getmtime(out / "materials" / f"{name}.binary") == mtime
