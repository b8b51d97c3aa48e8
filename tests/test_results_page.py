"""``benchmarks/results.py``, the generator of ``docs/notes/results.md``: the page from two real
(tiny) bench results with ``--skip-run``, issue 22's done-when check, the links folder.

The bench results are real runs on a tiny budget: one synthetic material, N = 40, one
draw, 16-pixel renders, untrained tiny models (a hypernetwork, a learnt prior, a
3-component PCA basis); the compression result gets a copy of its one record under a
second material's name, so that the page's MERL / RGL split has a row each.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys

import pytest

from brdfkit.io.merl import write_merl

from conftest import quiet_env
from helpers_model import make_model, material_table

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCRIPT = os.path.join(REPO, "benchmarks", "results.py")
sys.path.append(os.path.join(REPO, "benchmarks"))  # results.py imports results_page

import results  # noqa: E402
import results_page  # noqa: E402


def _prior(path, tables) -> None:
    import torch

    from brdfkit.basis import fit_basis
    from brdfkit.prior.prior_file import save_prior
    from brdfkit.prior.model import PriorConfig, PriorModel, prior_net

    basis = fit_basis(tables, n_components=3, names=["a", "b"])
    cfg = PriorConfig(n_components=3, latent_dim=4, width=8)
    torch.manual_seed(0)
    save_prior(path, PriorModel(basis, prior_net(cfg), cfg, {"materials": ["a", "b"]}))
    return basis


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """``(proxies, runs)``: proxies ``merl/mat-a``, ``rgl/rgl_b_rgb``; the two bench folders."""
    from brdfkit.bench import BenchConfig, run_bench
    from brdfkit.basis import save_basis

    root = tmp_path_factory.mktemp("results")
    proxies, runs, models = root / "proxies", root / "runs", root / "models"
    for d in (proxies / "merl", proxies / "rgl", runs, models):
        d.mkdir(parents=True)
    write_merl(proxies / "merl" / "mat-a.binary", material_table(1))
    write_merl(proxies / "rgl" / "rgl_b_rgb.binary", material_table(2))
    make_model(models / "hyp.safetensors")
    basis = _prior(models / "prior.safetensors", [material_table(0), material_table(2)])
    save_basis(models / "basis.safetensors", basis)
    common = dict(ipca=str(models / "basis.safetensors"), resolution=16, jobs=1, threads=1, device="cpu",
                  cache=str(runs / "bench-cache"))
    run_bench(BenchConfig(output=str(runs / "bench-sparse"), data=str(proxies / "merl"),
                          model=str(models / "hyp.safetensors"), models={"prior": str(models / "prior.safetensors")},
                          methods=("prior", "ipca", "nbrdf", "hypernet"), n=(40,), seeds=1,
                          options={"nbrdf": {"steps": 20}}, **common), progress=False)
    run_bench(BenchConfig(output=str(runs / "bench-compression"), compression_models=(str(models / "hyp.safetensors"),),
                          compression_data=str(proxies / "rgl"), **common), progress=False)
    path = runs / "bench-compression" / "bench.json"
    doc = json.loads(path.read_text())
    doc["records"] += [dict(r, material="mat-a") for r in doc["records"]]
    doc["materials"]["compression"].append("mat-a")
    path.write_text(json.dumps(doc))
    # what the CLI records (run in-process, the run has none) and a test list it covers in part
    path = runs / "bench-sparse" / "bench.json"
    doc = json.loads(path.read_text())
    (root / "test.txt").write_text("mat-a\nmat-z\n")
    doc["config"].update(command="brdfkit bench --tiny", test_list=str(root / "test.txt"))
    path.write_text(json.dumps(doc))
    return proxies, runs


def _script(*args, cwd=REPO):
    return subprocess.run([sys.executable, SCRIPT, *map(str, args)], capture_output=True, text=True, cwd=cwd,
                          env=quiet_env(), timeout=300)


@pytest.mark.slow
def test_page_from_bench_results(runs, tmp_path):
    proxies, rdir = runs
    out = tmp_path / "docs" / "results.md"
    out.parent.mkdir()
    proc = _script("--proxies", proxies, "--runs", rdir, "--skip-run", "--out", out)
    assert proc.returncode == 0, proc.stderr
    page = out.read_text()
    for title in ("## What differs from the paper", "## Issue 22's done-when check", "#### PSNR (dB)",
                  "#### Delta E 2000", "#### SSIM", "#### BRDF log RMSE", "#### Run time per reconstruction",
                  "#### The learnt prior against each other method", "## Compression", "## How to regenerate"):
        assert title in page, title
    assert "| N | paper hypernet | prior | ipca | nbrdf | hypernet |" in page
    assert "| 40 | 29.58 |" in page and "| 40 | 3.19 |" in page
    assert "prior PSNR higher than hypernet" in page
    # the done-when lines, on the page and printed, from the numbers
    assert "* N = 40: prior PSNR " in page and "draws 0" in page
    assert "* N = 400: not measured" in page and "* N = 4000: not measured" in page
    assert "* 20 planned against 40 uniform: not measured" in page
    assert re.search(r"\* Done when met: (no|not established)", page)  # never "yes" without N = 400, 4000
    assert "the learnt prior 2, the IPCA basis 2; the same set: yes; test materials among them: 0" in page
    assert "**Coverage: 1 of the 2 test materials** of `test.txt` (missing: mat-z)" in page
    assert "N = 40: prior PSNR " in proc.stdout and "Done when met:" in proc.stdout
    # compression: all, MERL and RGL rows of each model, the paper's figure on the IPCA row
    assert "| hypernet-7 (hyp) | all | 2 |" in page and "| hypernet-7 (hyp) | RGL | 1 |" in page
    assert "| basis-3 (9 numbers, basis) | MERL | 1 | 100.00 | - |" in page
    assert "| basis-3 (9 numbers, basis) | all | 2 | 100.00 ± 0.00 | - |" in page
    assert "2 materials (1 MERL, 1 RGL)" in page
    # the commands, verbatim
    cmds = results.plan(str(proxies), str(rdir), "../shared/data/merl-test.txt", 2)
    assert " ".join(cmds["sparse"]) in page and " ".join(cmds["compression"]) in page
    assert "records another command" in page  # the tiny runs are not those commands
    for name in ("bench-error-vs-cpu-time.png", "bench-error-vs-n.png", "bench-compression.png"):
        assert (out.parent / "images" / name).stat().st_size > 0
        assert f"images/{name}" in page


@pytest.mark.slow
def test_compression_records_of_earlier_runs(runs):
    """A compression bench.json from before the renames (the size as ``latent``, the labels
    ``latent-K`` and ``pca-K``) still gives its rows and the paper's figures."""
    proxies, rdir = runs
    doc = json.loads((rdir / "bench-compression" / "bench.json").read_text())
    for r in doc["records"]:
        r["latent"] = r.pop("size")
        r["method"] = r["method"].replace("hypernet-", "latent-").replace("basis-3 (9", "pca-3 (9")
    page = "\n".join(results_page.compression_section(doc, str(proxies), figure=False))
    assert "| latent-7 (hyp) | all | 2 |" in page and "| latent-7 (hyp) | RGL | 1 |" in page
    assert "| pca-3 (9 numbers, basis) | MERL | 1 | 100.00 | - |" in page


def test_missing_bench_is_one_line(tmp_path):
    proc = _script("--proxies", tmp_path, "--runs", tmp_path, "--skip-run", "--out", tmp_path / "r.md")
    assert proc.returncode == 2
    assert proc.stderr.strip().count("\n") == 0 and "bench.json: missing" in proc.stderr
    assert not (tmp_path / "r.md").exists()


def test_done_when_verdicts():
    def recs(shift):
        out = []
        for n in (20, 40, 160, 400, 2000, 4000):
            for s in (0, 1, 2):
                for mat in ("a", "b"):
                    rows = [("prior", "uniform", 0.1, 41.0), ("ipca", "uniform", 0.2 + shift, 39.0)]
                    if n == 20:
                        rows = [("prior", "planned", 0.1, 41.5)]
                    for m, smp, rmse, psnr in rows:
                        out.append({"kind": "sparse", "material": mat, "method": m, "n": n, "seed": s,
                                    "sampling": smp, "log_rmse": rmse, "psnr": psnr, "delta_e": 1.0, "ssim": 0.9,
                                    "time_s": 1.0})
        return out

    check = results_page.done_when({"records": recs(0.0)})
    assert check["verdict"] == "yes" and all(all(r["met"]) for r in check["rows"])
    assert check["rows"][-1]["a"]["psnr"] == 41.5 and check["rows"][-1]["b"]["psnr"] == 41.0
    worse = recs(0.0)
    for r in worse:
        if r["method"] == "prior" and r["n"] == 400:
            r["log_rmse"] = 0.17  # 0.85 of IPCA's: above 0.8
    check = results_page.done_when({"records": worse})
    assert check["verdict"] == "no" and check["rows"][2]["met"] == [True, False]
    assert results_page.done_lines(check)[2].startswith(
        "N = 400: prior PSNR 41.00 vs ipca 39.00 dB (target ipca + 1): met; log RMSE 0.1700 vs 0.2000, ratio 0.85")
    planned_worse = [dict(r, psnr=40.0) if r["sampling"] == "planned" else r for r in recs(0.0)]
    check = results_page.done_when({"records": planned_worse})
    assert check["verdict"] == "no" and check["rows"][-1]["met"] == [False]
    assert "**missed**" in results_page.done_lines(check)[-2]
    labelled = results_page.with_sampling_labels({"records": recs(0.0)})
    assert {r["method"] for r in labelled["records"]} == {"prior", "ipca", "prior (planned)"}


def test_links_folder(tmp_path):
    for sub, name in (("merl", "a"), ("rgl", "b"), ("rgl", "c")):
        (tmp_path / sub).mkdir(exist_ok=True)
        (tmp_path / sub / f"{name}.binary").write_bytes(b"x")
    folder = tmp_path / "all"
    assert results.link_all(str(tmp_path), str(folder)) == 3
    (tmp_path / "rgl" / "c.binary").unlink()
    assert results.link_all(str(tmp_path), str(folder)) == 2
    assert sorted(os.listdir(folder)) == ["a.binary", "b.binary"]
    (tmp_path / "rgl" / "A.binary").write_bytes(b"x")
    with pytest.raises(results.InputError, match="in both"):
        results.link_all(str(tmp_path), str(folder))


@pytest.mark.slow
def test_run_order(runs, tmp_path, monkeypatch, capsys):
    """Without ``--skip-run``: the fits (their outputs missing), the benches and the links
    folder in order, then the page from what the benches wrote (commands not run here)."""
    proxies, rdir = runs
    ran = []
    monkeypatch.setattr(results, "run", lambda argv: ran.append(argv))
    test_list = rdir.parent / "test.txt"
    assert results.main(["--proxies", str(proxies), "--runs", str(rdir), "--jobs", "1", "--test-list",
                         str(test_list), "--out", str(tmp_path / "results.md")]) == 0
    cmds = results.plan(str(proxies), str(rdir), str(test_list), 1)
    assert ran == [cmds["fit151"], cmds["compression"], cmds["fit80k"], cmds["unseen"], cmds["fit80"],
                   cmds["planned"], cmds["uniform"], cmds["sparse"]]
    assert sorted(os.listdir(rdir / "all151")) == ["mat-a.binary", "rgl_b_rgb.binary"]
    assert "Done when met:" in capsys.readouterr().out and (tmp_path / "results.md").exists()


def test_the_papers_ipca_figure_sits_beside_eight_components():
    import results_page  # benchmarks/ is on sys.path (above)

    assert results_page._paper_comp("basis-8 (24 numbers)", 24) == "29.89"
    assert results_page._paper_comp("basis-8 (24 numbers, ipca80)", 24) == "29.89"
    assert results_page._paper_comp("basis-13 (39 numbers, ipca80)", 39) == "-"
    assert results_page._paper_comp("basis-2 (6 numbers)", 6) == "-"
    assert results_page._paper_comp("hypernet-40 (merl-rgl-l40)", 40) == "47.68"
    assert results_page._paper_comp("hypernet-16 (tiny)", 16) == "-"
    assert results_page._paper_comp("basis-39 (merl80-basis)", 39) == "-"  # a basis embedding, not a projection
    assert results_page._paper_comp("basis-24 (merl80-basis)", 24) == "-"
    # the labels of earlier records
    assert results_page._paper_comp("pca-8 (24 numbers)", None) == "29.89"
    assert results_page._paper_comp("pca-8 (24 numbers, ipca80)", None) == "29.89"
    assert results_page._paper_comp("pca-13 (39 numbers, ipca80)", None) == "-"
    assert results_page._paper_comp("pca-2 (6 numbers)", None) == "-"
    assert results_page._paper_comp("latent-40 (merl-rgl-l40)", 40) == "47.68"
    assert results_page._paper_comp("latent-16 (tiny)", 16) == "-"
    assert results_page._paper_comp("ipca 8 components", None) == "29.89"
    assert results_page._paper_comp("hypernet 40-D (merl-rgl-l40)", 40) == "47.68"
