"""``brdfkit demo`` end to end on a tiny budget (4 materials, 20 steps, tiny model)."""

from __future__ import annotations

import os
import re
import subprocess

import numpy as np
import pytest
from rich.console import Console

from brdfkit.demo import choose_holdout, render_psnr, write_demo_library
from brdfkit.embedding import read_embedding
from brdfkit.merl import read_merl
from brdfkit.model.file import load_model

from conftest import brdfkit_command, quiet_env, tiny_cli_options


def test_holdout_spreads_over_random_materials():
    names = ["stiff-black", "stiff-grazing", "stiff-mirror", "stiff-white"] + [f"synth-{i:03d}" for i in range(16)]
    assert choose_holdout(names, 4) == ["synth-002", "synth-006", "synth-010", "synth-014"]
    assert choose_holdout(names[:5], 2) == ["stiff-grazing", "stiff-white"]


def test_render_psnr_through_the_reference_renderer():
    from brdfkit.synthetic import STIFF, table

    score = render_psnr(resolution=12)
    if score is None:
        pytest.skip("brdfkit.render.quadrature.render is not available")
    white = table(STIFF[2])
    assert score(white, white) == float("inf")
    assert 0 < score(white * 0.5, white) < 30


def test_demo_runs_end_to_end(tmp_path):
    out = tmp_path / "demo"
    tiny = tiny_cli_options(latent=False)
    cmd = [*brdfkit_command(), "demo", "--out", str(out), "--materials", "4", "--holdout", "1",
           "--steps", "20", "--no-render", *tiny]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300, env=quiet_env())
    assert proc.returncode == 0, proc.stderr[-3000:]
    report = proc.stdout
    assert "Held-out materials: BRDF log RMSE" in report and "Times" in report
    mean = re.search(r"mean\s*[│|]\s*([\d.]+)\s*[│|]\s*([\d.]+)\s*[│|]\s*([\d.]+)\s*[│|]\s*([\d.]+)", report)
    assert mean, report
    assert all(np.isfinite(float(v)) for v in mean.groups())
    assert f"writing everything into {out}" in proc.stderr.replace("\n", "")

    model = load_model(out / "model.safetensors", "cpu")
    held = model.meta["excluded"]
    assert len(held) == 1 and held[0] not in model.meta["materials"]
    assert model.meta["steps"] == 20
    name = held[0]
    # Every file the report lists exists, and they are what they claim to be.
    for rel in re.findall(r"^\s+(\S+[^/\s])\s+\(\d", report, flags=re.M):
        assert (out / rel).is_file(), rel
    for f in (f"{name}.emb", f"{name}-40samples.emb", f"{name}-400samples.emb"):
        emb = read_embedding(out / "embeddings" / f)
        assert emb.model_fingerprint == model.fingerprint
    decoded = read_merl(out / "decoded" / f"{name}.binary")
    assert np.isfinite(decoded).any()
    mixes = [f for f in os.listdir(out / "decoded") if "+" in f]
    assert len(mixes) == 1
    # A second run reuses the library (same count and seed) instead of regenerating it.
    mtime = os.path.getmtime(out / "materials" / f"{name}.binary")
    paths = write_demo_library(str(out / "materials"), 4, 0, Console(stderr=True))
    assert len(paths) == 4 and os.path.getmtime(out / "materials" / f"{name}.binary") == mtime
