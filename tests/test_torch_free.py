"""The everyday jobs of basis and residual embeddings, and of plain tables, import no torch
(issue 44 item 1): ``encode``, ``decode``, ``render``, ``metrics``, ``interpolate`` and
``convert`` run in one fresh interpreter with the shipped built-ins (a basis, and
``merl80-l40``'s residual), and torch is not in ``sys.modules`` after them; and a table
encoded after another in a batch gives the ``.emb`` bytes it gives alone (item 3)."""

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
def test_a_table_encoded_after_another_in_one_process_gives_its_bytes_alone(tmp_path, monkeypatch, capsys):
    """``brdfkit encode a b bad`` (one process) writes for ``b``, encoded after ``a``, what
    ``b`` encoded alone gives, to the byte; the unreadable input fails alone. (``--jobs 2``
    against alone, for every shipped built-in and kind: ``tests/test_routes_encode.py``'s
    ``test_a_batch_of_two_in_two_processes``; all three on real tables, in fresh
    processes: ``tests/test_batch_bytes.py``.)"""
    from conftest import run_cli

    monkeypatch.delenv("BRDFKIT_BUILTIN_MODELS", raising=False)
    model = _shipped_residual()
    names = []
    for i in range(2):
        write_merl(tmp_path / f"m{i}.binary", _table(i + 1))
        names.append(tmp_path / f"m{i}.binary")
    (tmp_path / "bad.binary").write_bytes(b"not a table")
    opts = ["-m", model, "--size", "9", "--steps", "2"]
    code, stdout, err = run_cli(capsys, ["encode", *names, tmp_path / "bad.binary", *opts, "-o", tmp_path / "batch"])
    assert code == 2 and "bad.binary" in err and "encoded 2 of 3 files" in stdout + err, err
    code, _, err = run_cli(capsys, ["encode", names[1], *opts, "-o", tmp_path / "alone"])
    assert code == 0, err
    assert (tmp_path / "alone" / "m1.emb").read_bytes() == (tmp_path / "batch" / "m1.emb").read_bytes()


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
