"""The everyday jobs of basis and residual embeddings, and of plain tables, import no torch
(issue 44 item 1): ``encode``, ``decode``, ``render``, ``metrics``, ``interpolate`` and
``convert`` run in one fresh interpreter with the shipped built-ins (a basis, and
``merl80-l40``'s residual), and torch is not in ``sys.modules`` after them; and a batch
of tables gives the same ``.emb`` bytes with one process or several (item 3)."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from brdfkit.io.merl import write_merl


def _shipped_residual():
    """The shipped built-in that has a residual, or skip (a checkout without them)."""
    from brdfkit.models.builtin import models_folder, read_manifest

    bundle = next((m for m in read_manifest(models_folder()).installed() if m.part("residual") is not None), None)
    if bundle is None:
        pytest.skip("no shipped built-in model with a basis residual in this checkout")
    return bundle.name


def _table(seed):
    from brdfkit.materials import synthetic

    rng = np.random.default_rng(seed)
    lobe = synthetic.table(synthetic.Material("lobe", "dielectric", float(rng.uniform(0.08, 0.3))))
    return np.asarray(rng.uniform(0.02, 0.5, 3))[None, None, None, :] / np.pi + lobe


@pytest.mark.slow
def test_everyday_jobs_import_no_torch(tmp_path, monkeypatch):
    monkeypatch.delenv("BRDFKIT_BUILTIN_MODELS", raising=False)
    monkeypatch.delenv("BRDFKIT_MODEL", raising=False)
    model = _shipped_residual()
    write_merl(tmp_path / "t.binary", _table(0))
    jobs = [
        ["encode", "t.binary", "-m", model, "--kind", "basis", "--size", "9", "--steps", "2", "-o", "b"],
        ["encode", "t.binary", "-m", model, "--kind", "residual", "--size", "9", "--steps", "2", "-o", "r"],
        ["decode", "b/t.emb", "-o", "b.binary"],
        ["decode", "r/t.emb", "-o", "r.binary"],
        ["render", "r/t.emb", "-o", "r.exr", "--resolution", "16", "--quiet"],
        ["render", "t.binary", "-o", "t.exr", "--resolution", "16", "--quiet"],
        ["metrics", "--ref", "t.binary", "b/t.emb", "--resolution", "16", "--quiet", "--json"],
        ["interpolate", "r/t.emb", "r/t.emb", "-t", "0.5", "-o", "mid.emb", "--binary", "mid.binary"],
        ["convert", "b/t.emb", "-o", "c.binary"],
    ]
    code = ("import sys\nfrom brdfkit.cli import main\n"
            f"for args in {jobs!r}:\n"
            "    try:\n        main(args)\n    except SystemExit as e:\n        assert not e.code, (args, e.code)\n"
            "print('TORCH', 'torch' in sys.modules)")
    r = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=600,
                       env={**os.environ, "OMP_NUM_THREADS": "1"})
    assert r.returncode == 0, r.stderr[-3000:]
    assert r.stdout.split()[-2:] == ["TORCH", "False"], r.stdout[-2000:]
    for name in ("b.binary", "r.binary", "r.exr", "t.exr", "mid.emb", "mid.binary", "c.binary"):
        assert (tmp_path / name).stat().st_size > 0


@pytest.mark.slow
def test_a_batch_gives_the_same_bytes_in_one_process_or_two(tmp_path, monkeypatch, capsys):
    """``brdfkit encode a b c --jobs 2`` writes what ``--jobs 1`` writes, to the byte, and
    what each file encoded alone gives; one unreadable input fails alone."""
    from conftest import run_cli

    monkeypatch.delenv("BRDFKIT_BUILTIN_MODELS", raising=False)
    model = _shipped_residual()
    names = []
    for i in range(3):
        write_merl(tmp_path / f"m{i}.binary", _table(i + 1))
        names.append(tmp_path / f"m{i}.binary")
    (tmp_path / "bad.binary").write_bytes(b"not a table")
    out = {}
    for jobs in (1, 2):
        code, stdout, err = run_cli(capsys, ["encode", *names, tmp_path / "bad.binary", "-m", model, "--size", "9",
                                             "--steps", "2", "-o", tmp_path / f"j{jobs}", "--jobs", str(jobs)])
        assert code == 2 and "bad.binary" in err and "encoded 3 of 4 files" in stdout + err, err
        out[jobs] = [(tmp_path / f"j{jobs}" / f"m{i}.emb").read_bytes() for i in range(3)]
    assert out[1] == out[2]
    code, _, err = run_cli(capsys, ["encode", names[1], "-m", model, "--size", "9", "--steps", "2",
                                    "-o", tmp_path / "alone"])
    assert code == 0, err
    assert (tmp_path / "alone" / "m1.emb").read_bytes() == out[1][1]


def test_options_that_do_not_apply_are_refused_in_one_line(tmp_path, capsys):
    """``--size`` and ``--kind basis`` with a ``.csv`` sample set, and ``--max-seconds``
    with a basis embedding, are refused before any work (they used to be ignored)."""
    from brdfkit.io.samples import write_samples
    from brdfkit.acquisition.sampling import draw_samples
    from brdfkit.testing.examples import lambertian_table, tiny_basis_file

    from conftest import one_error_line, run_cli

    write_samples(tmp_path / "s.csv", draw_samples(lambertian_table(), 40, seed=0))
    write_merl(tmp_path / "t.binary", lambertian_table())
    basis = tiny_basis_file(tmp_path / "basis.safetensors")
    for args, says in ((["encode", tmp_path / "s.csv", "-m", basis, "--size", "9"], "--size"),
                       (["encode", tmp_path / "s.csv", "-m", basis, "--kind", "basis"], "--kind basis"),
                       (["encode", tmp_path / "t.binary", "-m", basis, "--max-seconds", "2"], "--max-seconds")):
        code, out, err = run_cli(capsys, args)
        assert code == 2 and says in one_error_line(err), err
    assert not list(tmp_path.glob("*.emb"))
