"""``brdfkit bench`` on a tiny budget: 2 synthetic test materials, 2 N, a tiny hypernetwork
trained here, a 2-component PCA basis, NBRDF with few steps, 16-pixel renders."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from brdfkit.bench import BenchConfig, run_bench, sample_seed, summarise
from brdfkit.io.merl import read_merl

from conftest import TINY, no_bench_plots, run_cli
from helpers_training import tiny_library

RES = 16


@pytest.fixture(scope="module")
def library(tmp_path_factory):
    """The three synthetic tables of the training tests, a 2-component PCA basis of them and a
    test list of two."""
    from brdfkit.basis import fit_basis, save_basis

    root = tmp_path_factory.mktemp("bench")
    lib = tiny_library(tmp_path_factory)
    names = sorted(p.stem for p in lib.glob("*.binary"))
    basis = root / "basis.safetensors"
    save_basis(basis, fit_basis(sorted(lib.glob("*.binary")), n_components=2))
    test_list = root / "test.txt"
    test_list.write_text(f"# two of the three\n{names[0]}\n{names[2]}\n")
    return {"root": root, "lib": lib, "names": names, "basis": basis, "test_list": test_list}


@pytest.fixture(scope="module")
def setup(library):
    """``library`` and a tiny hypernetwork trained on its tables (30 steps): only the
    end-to-end run needs it."""
    from brdfkit.hypernet.training.loop import fit

    model = library["root"] / "tiny.safetensors"
    fit(library["lib"], model, latent_dim=6, steps=30, seed=0, progress=False, **TINY)
    return {**library, "model": model}


@pytest.mark.slow
def test_bench_cli_end_to_end(setup, tmp_path, capsys, monkeypatch):
    import brdfkit.embeddings

    # The compressions' refinement on screen, 3 steps instead of the default's (seconds a
    # table): the records, not the scores, are checked (as hypernet.steps=20 below)
    encode_with = brdfkit.embeddings.encode_with
    monkeypatch.setattr(brdfkit.embeddings, "encode_with",
                        lambda *a, **kw: encode_with(*a, **{**kw, "steps": 3}))
    out = tmp_path / "out"
    comp = tmp_path / "comp"
    comp.mkdir()
    shutil.copy(setup["lib"] / f"{setup['names'][1]}.binary", comp)
    shutil.copy(setup["lib"] / f"{setup['names'][0]}.binary", comp / "alias.binary")
    # in this process (the command line's entry point): a process of its own adds only its start-up
    code, stdout, stderr = run_cli(capsys, [
        "bench", "--data", setup["lib"], "--test-list", setup["test_list"],
        "-m", setup["model"], "--ipca", setup["basis"], "--n", "40,160", "--seeds", "1",
        "--nbrdf-steps", "30", "-O", "hypernet.steps=20", "--resolution", str(RES), "--compression-models", f"{setup['model']},pca-1",
        "--compression-data", comp, "--threads", "1", "-o", out])
    assert code == 0, stderr[-3000:]
    assert stdout == ""  # progress and messages go to stderr
    # pca-K, the old spelling of basis-K, still runs, with a note
    assert "note: pca-1 is now basis-1" in stderr
    result = json.loads((out / "bench.json").read_text())
    assert result["complete"] and result["format"] == "brdfkit-bench"
    assert set(result["environment"]["method_defaults"]) == {"hypernet", "ipca", "nbrdf", "prior"}
    assert result["environment"]["method_defaults"]["hypernet"] == {"refine": True, "refine_target": "weights",
                                                                    "steps": 300}
    test_names = [setup["names"][0], setup["names"][2]]
    assert result["materials"]["sparse"] == test_names

    sparse = [r for r in result["records"] if r["kind"] == "sparse"]
    assert len(sparse) == 2 * 2 * 3
    assert {(r["material"], r["method"], r["n"]) for r in sparse} == \
        {(m, meth, n) for m in test_names for meth in ("hypernet", "ipca", "nbrdf") for n in (40, 160)}
    for r in sparse:
        assert "error" not in r, r
        assert r["time_s"] > 0 and r["cpu_s"] > 0 and r["render_s"] > 0
        assert 0 < r["psnr"] <= 100 and r["delta_e"] >= 0 and -1 <= r["ssim"] <= 1 and r["log_rmse"] > 0
        assert r["sample_seed"] == sample_seed(0, r["n"], r["material"])

    # A record is what the library computes from the same draw (IPCA is deterministic).
    from brdfkit.methods import get_method
    from brdfkit.evaluation.metrics import brdf_log_rmse
    from brdfkit.acquisition.sampling import draw_samples

    rec = next(r for r in sparse if r["method"] == "ipca" and r["n"] == 160)
    table = read_merl(setup["lib"] / f"{rec['material']}.binary")
    recon = get_method("ipca").reconstruct(draw_samples(table, 160, seed=rec["sample_seed"]), str(setup["basis"]))
    assert rec["log_rmse"] == pytest.approx(brdf_log_rmse(recon, table), rel=1e-9)

    # The summary row is the mean of its records.
    row = next(r for r in result["summary"]["sparse"] if r["method"] == "nbrdf" and r["n"] == 40)
    vals = [r["psnr"] for r in sparse if r["method"] == "nbrdf" and r["n"] == 40]
    assert row["psnr"] == pytest.approx(np.mean(vals)) and row["count"] == 2 and row["failures"] == 0
    assert row["psnr_sd_seeds"] is None  # one draw: no spread over draws
    assert row["psnr_sd_materials"] == pytest.approx(np.std(vals, ddof=1))

    comp_recs = [r for r in result["records"] if r["kind"] == "compression"]
    assert result["config"]["compression_models"] == [f"{setup['model']}:hypernet-6", "basis-1"]
    assert [r["method"] for r in comp_recs] == ["hypernet-6 (tiny)", "basis-1 (3 numbers)",
                                                "basis-2 (6 numbers, basis)"] * 2
    assert [r["size"] for r in comp_recs] == [6, 3, 6] * 2 and not any("latent" in r for r in comp_recs)
    assert all("error" not in r and r["time_s"] > 0 for r in comp_recs)
    # basis-1 is the projection onto the basis's leading component
    from brdfkit.basis import load_basis

    one = load_basis(setup["basis"]).leading(1)
    rec = next(r for r in comp_recs if r["method"] == "basis-1 (3 numbers)" and r["material"] == "alias")
    table = read_merl(comp / "alias.binary")
    assert rec["log_rmse"] == pytest.approx(brdf_log_rmse(one.decode(one.project(table)), table), rel=1e-9)
    # the model and the basis were trained on all three library tables, not on alias.binary
    assert {(r["material"], r["trained_on"]) for r in comp_recs} == {(setup["names"][1], True), ("alias", False)}

    # The cached reference render is the reference-scene render of the table itself.
    from brdfkit.render.renderable import TableBRDF
    from brdfkit.render.image import read_exr
    from brdfkit.render.quadrature import render
    from brdfkit.render.scene import Scene

    cached = sorted((out / "cache").glob(f"{test_names[0]}-{RES}px-*.exr"))
    # one render per table: alias.binary (a copy of a test material) reused its render
    assert len(cached) == 1 and len(list((out / "cache").glob("*.exr"))) == 3
    img, _ = render(TableBRDF(read_merl(setup["lib"] / f"{test_names[0]}.binary"), device="cpu"), Scene(resolution=RES))
    np.testing.assert_allclose(read_exr(cached[0]), img, rtol=1e-6, atol=1e-7)

    md = (out / "bench.md").read_text()
    assert "## Sparse reconstruction" in md and "## Compression" in md and "Failures" not in md
    assert "| hypernet | 40 |" in md and "| basis-2 (6 numbers, basis) | 6 |" in md
    assert "| model | numbers | PSNR (dB) |" in md and "| basis-1 (3 numbers) | 3 |" in md
    assert "| hypernet-6 (tiny) | no |" in md and "| basis-2 (6 numbers, basis) | yes |" in md
    from PIL import Image

    for png in ("error_vs_n.png", "error_vs_time.png", "error_vs_cpu_time.png", "compression.png"):
        with Image.open(out / png) as im:
            assert im.format == "PNG" and im.size[0] > 300
    assert not list(out.glob(".brdfkit-tmp-*"))


@pytest.mark.slow
def test_a_broken_material_is_recorded_not_fatal(library, tmp_path, monkeypatch):
    data = tmp_path / "data"
    data.mkdir()
    good = library["names"][0]
    shutil.copy(library["lib"] / f"{good}.binary", data)
    (data / "broken.binary").write_bytes((library["lib"] / f"{good}.binary").read_bytes()[:1000])
    cfg = BenchConfig(output=str(tmp_path / "out"), data=str(data), ipca=str(library["basis"]), n=(40,),
                      seeds=2, methods=("ipca",), resolution=8)
    result = run_bench(cfg, progress=False)
    bad = [r for r in result["records"] if r["material"] == "broken"]
    ok = [r for r in result["records"] if r["material"] == good]
    assert len(bad) == 2 and all("broken.binary" in r["error"] for r in bad)
    assert len(ok) == 2 and all("error" not in r for r in ok)
    assert ok[0]["sample_seed"] != ok[1]["sample_seed"]  # two draws
    row = result["summary"]["sparse"][0]
    assert (row["count"], row["failures"], row["materials"]) == (2, 2, 1)
    md = (tmp_path / "out" / "bench.md").read_text()
    assert "## Failures (2)" in md and "broken, ipca:" in md
    assert (tmp_path / "out" / "error_vs_n.png").is_file()  # the plots of a run with failures
    plotted = no_bench_plots(monkeypatch)  # the runs and merges below: their records, not their plots

    # One more draw later, merged with the first run.
    from brdfkit.cli import main
    from brdfkit.errors import InputError

    before = sorted((tmp_path / "out" / "cache").iterdir())
    assert len(before) == 1
    run_bench(BenchConfig(output=str(tmp_path / "more"), data=str(data), ipca=str(library["basis"]), n=(40,),
                          seeds=1, first_seed=2, methods=("ipca",), resolution=8,
                          cache=str(tmp_path / "out" / "cache")), progress=False)
    assert sorted((tmp_path / "out" / "cache").iterdir()) == before  # the reference came from the cache
    with pytest.raises(SystemExit) as e:
        main(["bench", "--merge", str(tmp_path / "out"), "--merge", str(tmp_path / "more"), "-o",
              str(tmp_path / "merged"), "-q"])
    assert e.value.code == 0
    merged = json.loads((tmp_path / "merged" / "bench.json").read_text())
    assert sorted(r["seed"] for r in merged["records"] if r["material"] == good) == [0, 1, 2]
    assert merged["summary"]["sparse"][0]["count"] == 3
    assert "3 draw(s) (seeds 0, 1, 2)" in (tmp_path / "merged" / "bench.md").read_text()
    from brdfkit.bench import merge_results

    with pytest.raises(InputError, match="both hold sparse"):
        merge_results([tmp_path / "out", tmp_path / "merged"], str(tmp_path / "again"))
    # --replace: the later run's ipca records (seeds 0-2) replace the earlier run's (0-1).
    again = merge_results([tmp_path / "out", tmp_path / "merged"], str(tmp_path / "again"), replace=True)
    ipca = [r for r in again["records"] if r["method"] == "ipca" and r["material"] == good]
    want = [r for r in merged["records"] if r["method"] == "ipca" and r["material"] == good]
    assert ipca == want and len(ipca) == 3

    # An interrupted run (only `good` finished) merges on request, over the common materials.
    part = json.loads((tmp_path / "more" / "bench.json").read_text())
    part.update(complete=False, records=[r for r in part["records"] if r["material"] == good])
    (tmp_path / "part.json").write_text(json.dumps(part))
    with pytest.raises(InputError, match="did not finish"):
        merge_results([tmp_path / "out", tmp_path / "part.json"], str(tmp_path / "p"))
    got = merge_results([tmp_path / "out", tmp_path / "part.json"], str(tmp_path / "p"), allow_incomplete=True)
    assert not got["complete"] and got["dropped_materials"] == ["broken"]
    assert {r["material"] for r in got["records"]} == {good} and len(got["records"]) == 3
    assert "materials dropped because not every merged run covered them: broken" in (tmp_path / "p" / "bench.md").read_text()
    # Runs of one built-in's name made with other parts of it (a retrained model) are not merged.
    part.update(complete=True, parts={"merl80-l40": {"basis": "0" * 64}})
    (tmp_path / "part.json").write_text(json.dumps(part))
    other = dict(part, parts={"merl80-l40": {"basis": "1" * 64}})
    (tmp_path / "other.json").write_text(json.dumps(other))
    with pytest.raises(InputError, match="other parts of the built-in model 'merl80-l40'"):
        merge_results([tmp_path / "part.json", tmp_path / "other.json"], str(tmp_path / "q"), replace=True)
    assert plotted == [str(tmp_path / n) for n in ("more", "merged", "again", "p")]  # each run and merge that wrote


def test_usage_errors_are_one_line(library, tmp_path, capsys):
    from brdfkit.cli import main

    base = ["bench", "--data", str(library["lib"]), "-o", str(tmp_path / "o"), "-q"]
    cases = [(base + ["--ipca", str(library["basis"])], "method 'hypernet' needs --model"),
             (base + ["--methods", "ipca,pca", "--ipca", str(library["basis"])], "unknown method 'pca'"),
             (base + ["--methods", "nbrdf", "--n", "40,x"], "--n: '40,x' is not a comma-separated"),
             (base + ["--methods", "nbrdf", "--test-list", str(library["test_list"]), "--data", str(tmp_path)],
              "holds no .binary files"),
             (["bench", "-o", str(tmp_path / "o")], "nothing to run")]
    missing = tmp_path / "missing.txt"
    missing.write_text("not-a-material\n")
    cases.append((base + ["--methods", "nbrdf", "--test-list", str(missing)], "no table for test material(s) not-a-material"))
    for argv, message in cases:
        with pytest.raises(SystemExit) as e:
            main(argv)
        err = capsys.readouterr().err
        assert e.value.code == 2, (argv, err)
        assert message in err and err.count("\n") == 1, err
    assert not (tmp_path / "o" / "bench.json").exists()


def test_summary_spreads():
    recs = []
    for seed, shift in ((0, 0.0), (1, 2.0)):
        for mat, base in (("a", 10.0), ("b", 20.0)):
            recs.append({"kind": "sparse", "material": mat, "method": "x", "n": 40, "seed": seed,
                         "psnr": base + shift, "delta_e": 1.0, "ssim": 0.9, "log_rmse": 0.1, "time_s": 1.0})
    recs.append({"kind": "sparse", "material": "c", "method": "x", "n": 40, "seed": 0, "error": "boom"})
    row = summarise(recs)["sparse"][0]
    assert row["psnr"] == pytest.approx(16.0)
    assert row["psnr_sd_seeds"] == pytest.approx(np.std([15.0, 17.0], ddof=1))
    assert row["psnr_sd_materials"] == pytest.approx(np.std([11.0, 21.0], ddof=1))
    assert (row["count"], row["failures"], row["materials"]) == (4, 1, 2)


def test_compression_records_of_earlier_runs_still_summarise(tmp_path):
    """Compression records written before the size column was called ``size`` hold it as
    ``latent``: the summary, the merge and bench.md read either."""
    from brdfkit.bench.report import write_markdown
    from brdfkit.bench.summary import record_size

    def rec(mat, psnr, old):
        r = {"kind": "compression", "material": mat, "method": "pca-2 (6 numbers)", "psnr": psnr, "delta_e": 1.0,
             "ssim": 0.9, "log_rmse": 0.1, "time_s": 1.0, "trained_on": False}
        r["latent" if old else "size"] = 6
        return r

    recs = [rec("a", 10.0, True), rec("b", 20.0, False)]
    assert [record_size(r) for r in recs] == [6, 6]
    rows = summarise(recs)["compression"]
    assert len(rows) == 1 and rows[0]["size"] == 6 and rows[0]["psnr"] == pytest.approx(15.0)
    old_summary = {"compression": [dict({k: v for k, v in rows[0].items() if k != "size"}, latent=6)],
                   "sparse": []}
    result = {"config": {"command": "brdfkit bench", "jobs": 1, "compression_data": "comp", "resolution": 16},
              "environment": {"machine": "m", "cpus": 2, "torch": "t", "threads": 1, "device": "cpu"},
              "started": "then", "elapsed_s": 1.0, "complete": True, "records": recs,
              "materials": {"compression_count": 2}, "summary": old_summary}
    write_markdown(str(tmp_path / "bench.md"), result)
    assert "| pca-2 (6 numbers) | 6 |" in (tmp_path / "bench.md").read_text()


def test_basis_k_entries_and_their_old_spelling(capsys):
    """``--compression-models basis-K`` is the projection onto the ``--ipca`` basis's K leading
    components; ``pca-K``, its old spelling, still works, with a one-line note; a file
    whose name starts with ``basis-`` stays a file."""
    from brdfkit.bench.config import _basis_spelling, basis_components
    from brdfkit.errors import InputError

    assert basis_components("basis-13") == basis_components("pca-13") == 13
    assert basis_components("merl80-l40:basis-21") is None and basis_components("merl80-l40") is None
    assert basis_components("basis-merl.safetensors") is None
    for bad in ("basis-0", "pca-0", "pca-x"):
        with pytest.raises(InputError, match="K takes a whole number"):
            basis_components(bad)
    assert _basis_spelling("basis-13") == "basis-13" and capsys.readouterr().err == ""
    assert _basis_spelling("pca-13") == "basis-13"
    assert capsys.readouterr().err.strip() == "note: pca-13 is now basis-13"
    cfg = BenchConfig(output="o", compression_models=("pca-2", "basis-3"), compression_data="d", ipca="b")
    assert cfg.compressors()[:2] == [("basis", 2), ("basis", 3)]
    with pytest.raises(InputError, match="basis-K takes the K leading components of --ipca"):
        BenchConfig(output="o", compression_models=("pca-2",), compression_data="d").validate()


def test_methods_model_files_and_options_by_name(library, tmp_path):
    """A method's model file and options come by method name (``--model-file``, ``-O``),
    so a new method of brdfkit.methods needs no new bench field."""
    from brdfkit.errors import InputError
    from brdfkit.methods.nbrdf import DEFAULT_STEPS

    base = dict(output=str(tmp_path / "o"), data=str(library["lib"]), n=(40,), seeds=1)
    cfg = BenchConfig(**base, methods=("ipca", "nbrdf"), models={"ipca": str(library["basis"])},
                      options={"nbrdf": {"lr": 0.005}})
    cfg.validate()
    assert cfg.model_file("ipca") == str(library["basis"]) and cfg.model_file("nbrdf") is None
    assert cfg.method_options("nbrdf").lr == 0.005 and cfg.method_options("nbrdf").steps == DEFAULT_STEPS
    for kwargs, message in ((dict(methods=("nbrdf",), models={"nbrdf": str(library["basis"])}), "takes no model file"),
                            (dict(methods=("ipca",)), "method 'ipca' needs --ipca FILE"),
                            (dict(methods=("nbrdf",), options={"nbrdf": {"lam": 1.0}}), "takes the option"),
                            (dict(methods=("nbrdf",), options={"nbrdf": {"steps": 0}}), "steps must be")):
        with pytest.raises(InputError, match=message):
            BenchConfig(**base, **kwargs).validate()


def test_renderer_digest_covers_every_module_a_reference_render_reads():
    """A change to any module the quadrature render goes through must invalidate the
    cached reference renders: the digest reads each of them."""
    import builtins
    import os

    from brdfkit.bench.worker import renderer_digest

    read = []
    real_open = builtins.open

    def spy(file, *a, **k):
        read.append(os.path.basename(str(file)))
        return real_open(file, *a, **k)

    builtins.open = spy
    try:
        renderer_digest()
    finally:
        builtins.open = real_open
    assert {"quadrature.py", "scene.py", "envmap.py", "renderable.py", "coordinates.py", "grid.py", "trilinear.py",
            "nodes.py", "pairs.py"} <= set(read)


@pytest.mark.slow
def test_resume_keeps_finished_materials_and_runs_the_rest(library, tmp_path, monkeypatch):
    from brdfkit.errors import InputError

    no_bench_plots(monkeypatch)

    cfg = BenchConfig(output=str(tmp_path / "out"), data=str(library["lib"]), ipca=str(library["basis"]), n=(40,),
                      seeds=1, methods=("ipca",), resolution=8)
    full = run_bench(cfg, progress=False)
    assert len(full["records"]) == 3
    # An interruption after the first material: its records are kept as written, with a
    # mark the rerun cannot make, and the two others run again to the same figures.
    path = tmp_path / "out" / "bench.json"
    part = json.loads(path.read_text())
    first = dict(part["records"][0], mark="kept")
    part.update(complete=False, records=[first], elapsed_s=12.5)
    path.write_text(json.dumps(part))
    resumed = run_bench(cfg, progress=False, resume=True)
    assert resumed["complete"] and resumed["elapsed_s"] >= 12.5
    assert resumed["records"][0] == first
    key = lambda r: r["material"]  # noqa: E731
    again = sorted(resumed["records"][1:], key=key)
    want = sorted((r for r in full["records"] if r["material"] != first["material"]), key=key)
    assert [(r["material"], r["log_rmse"]) for r in again] == [(r["material"], r["log_rmse"]) for r in want]
    # Resuming a finished run runs nothing; another configuration is refused.
    assert len(run_bench(cfg, progress=False, resume=True)["records"]) == 3
    other = BenchConfig(output=str(tmp_path / "out"), data=str(library["lib"]), ipca=str(library["basis"]), n=(160,),
                        seeds=1, methods=("ipca",), resolution=8)
    with pytest.raises(InputError, match="these differ: n"):
        run_bench(other, progress=False, resume=True)
    # So is a run of other built-in parts under the same names (a model retrained since).
    part["parts"] = {"merl80-l40": {"basis": "0" * 64}}
    path.write_text(json.dumps(part))
    with pytest.raises(InputError, match="needs the same built-in models"):
        run_bench(cfg, progress=False, resume=True)
