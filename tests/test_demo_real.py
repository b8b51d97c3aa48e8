"""``brdfkit demo`` on the shipped real materials (``brdfkit.demos.real_materials``) and their NBRDF
decode (``brdfkit.materials.nbrdf_networks``).

The built-in folder is a temporary one (``$BRDFKIT_BUILTIN_MODELS``) holding untrained
tiny models under the names the demo asks for: ``merl80-l40`` (a hypernetwork of latent
size 40 and a learnt prior over a 3-component basis of two synthetic tables, the basis in
a shared file), ``merl-rgl-l40`` (latent 40) and ``merl-rgl-l7`` (latent 7), the latent
sizes of the shipped ones, so that the compressions' labels are the real ones. The tests
check the plumbing, the labels and the files, not how well untrained models do.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import types

import numpy as np
import pytest

from brdfkit.cli import main
from brdfkit.io.embedding import read_embedding
from brdfkit.io.merl import read_merl
from brdfkit.models import builtin
from brdfkit.hypernet import packing
from brdfkit.materials.nbrdf_networks import DEMO_WEIGHTS, LAYERS, load_nbrdf_weights, nbrdf_table

from conftest import TINY_CONFIG, brdfkit_command, quiet_env, run_cli
from helpers_model import make_model, material_table

SHARED = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "..", "shared")
TOOL = os.path.join(SHARED, "tools", "nbrdf_to_merl.py")
SHIPPED = ["blue-metallic-paint", "teflon", "chrome-steel", "violet-rubber"]
# The tiny shelf's hypernetworks: name, latent size (the shipped one's), seed.
SHELF = (("merl80-l40", 40, 0), ("merl-rgl-l40", 40, 2), ("merl-rgl-l7", 7, 1))
# The compressions' labels: the error columns and errors.json keys, and the sheet's tiles.
# The test shelf's merl80-l40 ships a 3-component basis (its learnt prior's): its default
# embeddings hold 9 numbers; its merl-rgl-l40 has no learnt prior, hence no basis: a latent.
LABELS = ["in-sample 40-D (merl-rgl-l40)", "in-sample 7-D (merl-rgl-l7)", "unseen basis-9 (merl80-l40)"]
TILES = ["in-sample 40-D", "in-sample 7-D", "unseen basis-9"]
SPARSE_COLUMNS = ["prior 40", "prior 400", "ipca 40", "ipca 400"]


@pytest.fixture(scope="module")
def shelf(tmp_path_factory):
    """A built-in folder with tiny untrained ``merl80-l40`` (and learnt prior),
    ``merl-rgl-l40`` and ``merl-rgl-l7``."""
    import torch

    from brdfkit.basis import fit_basis
    from brdfkit.prior.prior_file import save_prior
    from brdfkit.prior.model import PriorConfig, PriorModel, prior_net

    src = tmp_path_factory.mktemp("trained")
    folder = tmp_path_factory.mktemp("builtin")
    entries = []
    for name, latent, seed in SHELF:
        make_model(src / f"{name}.safetensors", {**TINY_CONFIG, "latent_dim": latent}, seed=seed)
        packing.pack_network(src / f"{name}.safetensors", folder / f"{name}.safetensors",
                           reference_file="tiny.reference.safetensors")
        entries.append(packing.manifest_entry(folder / f"{name}.safetensors", name, command="brdfkit fit (tiny)",
                                              validation={40: 0.3}))
    basis = fit_basis([material_table(0), material_table(1)], n_components=3, names=["stiff-white", "ggx"])
    cfg = PriorConfig(n_components=3, latent_dim=4, width=8)
    torch.manual_seed(0)
    fp = save_prior(folder / "merl80-l40.prior.safetensors",
                    PriorModel(basis, prior_net(cfg), cfg, {"materials": ["stiff-white", "ggx"]}),
                    basis_file="tiny.basis.safetensors")
    from brdfkit.prior.prior_file import basis_entry

    entries[0]["parts"].update(prior={"file": "merl80-l40.prior.safetensors", "digest": fp},
                               **basis_entry(folder / "merl80-l40.prior.safetensors"))
    builtin.write_manifest(folder, entries, default="merl80-l40")
    return folder


@pytest.fixture
def quick(monkeypatch, shelf):
    """The tiny shelf installed in this process, and a short refinement (3 steps a table):
    in-process runs read the demo's step count when called."""
    import brdfkit.demos.real_materials

    monkeypatch.setenv(builtin.BUILTIN_ENV, str(shelf))
    monkeypatch.setattr(brdfkit.demos.real_materials, "COMPRESSION_STEPS", 3)
    return shelf


def _run(args, env_folder=None, timeout=300):
    env = quiet_env()
    if env_folder is not None:
        env[builtin.BUILTIN_ENV] = str(env_folder)
    return subprocess.run([*brdfkit_command(), "demo", *map(str, args)], capture_output=True, text=True,
                          timeout=timeout, env=env)


# --- the shipped NBRDF networks ---------------------------------------------------------------

def test_shipped_weights_are_four_test_materials():
    nets = load_nbrdf_weights()
    assert list(nets) == SHIPPED
    for net in nets.values():
        assert {k: v.shape for k, v in net.items()} == LAYERS
        assert all(v.dtype == np.float32 for v in net.values())
    test_list = os.path.join(SHARED, "data", "merl-test.txt")
    if os.path.exists(test_list):
        with open(test_list, encoding="utf-8") as f:
            assert set(SHIPPED) <= set(f.read().split())


def test_weights_file_is_refused_in_one_line_when_bad(tmp_path):
    from brdfkit.errors import FormatError

    np.savez(tmp_path / "short.npz", names=np.array(["a"]), w1=np.zeros((1, 6, 21), np.float32))
    with pytest.raises(FormatError, match="no b1"):
        load_nbrdf_weights(tmp_path / "short.npz")
    arrays = {k: np.zeros((1, *s), np.float32) for k, s in LAYERS.items()}
    np.savez(tmp_path / "shape.npz", names=np.array(["a"]), **{**arrays, "w2": np.zeros((1, 21, 20), np.float32)})
    with pytest.raises(FormatError, match="'w2'"):
        load_nbrdf_weights(tmp_path / "shape.npz")
    np.savez(tmp_path / "pickled.npz", names=np.array([{"a": 1}], dtype=object), **arrays)
    with pytest.raises(FormatError):  # an object array needs pickle: never loaded
        load_nbrdf_weights(tmp_path / "pickled.npz")


def test_decode_is_physical_and_below_the_horizon_nan():
    from brdfkit.geometry import valid_mask

    table = nbrdf_table(load_nbrdf_weights()["teflon"], device="cpu")
    assert table.shape == (90, 90, 180, 3) and table.dtype == np.float64
    valid = valid_mask()
    assert np.isnan(table[~valid]).all() and np.isfinite(table[valid]).all()
    assert (table[valid] >= 0).all()
    # Teflon is a bright, nearly white diffuser: about 0.2 / sr at normal incidence.
    assert 0.05 < table[0, 0, 0].min() and table[0, 0, 0].max() < 1.0


@pytest.mark.slow
@pytest.mark.proxy
@pytest.mark.skipif(not (os.path.exists(TOOL) and os.path.exists(os.path.join(SHARED, "data", "nbrdf", "merl.npz"))),
                    reason="../shared/tools/nbrdf_to_merl.py and its data are not present")
def test_decode_matches_the_reference_tool(tmp_path):
    """The shared tool's .binary (from the published merl.npz) and the shipped networks'
    decode agree on every cell: the same weights and the same evaluation, up to float32
    rounding (amplified near 0 by exp(x) - 1)."""
    name = "chrome-steel"  # the mirror-like one: largest values, most cells clipped to 0
    proc = subprocess.run([sys.executable, TOOL, "merl", str(tmp_path), name], capture_output=True, text=True,
                          timeout=120, env=quiet_env())
    assert proc.returncode == 0, proc.stderr
    want = read_merl(tmp_path / f"{name}.binary")
    got = nbrdf_table(load_nbrdf_weights()[name], device="cpu")
    np.testing.assert_array_equal(np.isnan(got), np.isnan(want))
    np.testing.assert_allclose(got, want, rtol=5e-4, atol=1e-5)
    cells = [(0, 0, 0), (1, 40, 90), (30, 20, 45), (89, 10, 179)]
    for c in cells:
        np.testing.assert_allclose(got[c], want[c], rtol=5e-4, atol=1e-5)


def test_demo_weights_file_is_package_data():
    """pyproject ships brdfkit/data/*.npz (and the licence beside it) in the wheel."""
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    with open(os.path.join(root, "pyproject.toml"), encoding="utf-8") as f:
        text = f.read()
    assert '"data/*.npz"' in text and '"data/*.md"' in text
    assert os.path.dirname(DEMO_WEIGHTS).endswith(os.path.join("brdfkit", "data"))
    assert os.path.exists(os.path.join(os.path.dirname(DEMO_WEIGHTS), "README.md"))


# --- brdfkit demo ---------------------------------------------------------------------------

def _demo_in_process(args) -> tuple[int, str, str]:
    """``brdfkit ARGS`` in this process where no ``capsys`` is at hand (a module fixture):
    ``(exit code, stdout, stderr)``."""
    import contextlib
    import io

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            main([str(a) for a in args])
        except SystemExit as e:
            return e.code, out.getvalue(), err.getvalue()
    return 0, out.getvalue(), err.getvalue()


@pytest.fixture(scope="module")
def demo_run(shelf, tmp_path_factory):
    """One ``brdfkit demo`` on the tiny shelf, shared by the tests of what it prints and
    writes: two materials (so a blend), every table kept (``--keep-tables``), the sheets at
    8 px copied into a gallery (``--gallery``), each compression refined for 3 steps."""
    import types

    import brdfkit.demos.real_materials

    folder = tmp_path_factory.mktemp("demo-run")
    out, gallery = folder / "demo", folder / "images"
    gallery.mkdir()
    # in this process, the demo's refinement of 20 steps a table cut to 3 (as `quick`)
    assert brdfkit.demos.real_materials.COMPRESSION_STEPS == 20
    with pytest.MonkeyPatch.context() as mp:
        mp.delenv("BRDFKIT_MODEL", raising=False)
        mp.setenv(builtin.BUILTIN_ENV, str(shelf))
        mp.setattr(brdfkit.demos.real_materials, "COMPRESSION_STEPS", 3)
        code, report, stderr = _demo_in_process(["demo", "--out", out, "--only", "violet-rubber,teflon",
                                                 "--resolution", "8", "--keep-tables", "--gallery", gallery])
    assert code == 0, stderr[-3000:]
    return types.SimpleNamespace(out=out, gallery=gallery, report=report, stderr=stderr, shelf=shelf)


@pytest.mark.slow
def test_real_demo_prints_its_tables_labels_and_times(demo_run):
    report, stderr, out = demo_run.report, demo_run.stderr, demo_run.out
    flat = re.sub(r"\s+", " ", report)
    assert "Times" in report and "whole demo" in report
    for what in ("sparse", "compressed"):  # ranked by renders (issue 28)
        assert f"MERL test materials, {what}: PSNR dB / Delta E 2000 of 8 px reference-scene renders" in flat
    for name in ("violet-rubber", "teflon"):  # a row in each table: 4 sparse columns, 3 compressions
        rows = re.findall(rf"{name}\s*[│|]((?:\s*[\d.]+ / [\d.]+\s*[│|]?)+)", report)
        values = [[float(v) for v in re.findall(r"[\d.]+", row)] for row in rows]
        assert [len(v) for v in values] == [8, 6] and np.isfinite(sum(values, [])).all(), report
    assert len(re.findall(r"mean\s*[│|]", report)) == 2
    # The compressions' headers whole (wrapped at the model's name, not cut).
    assert "…" not in report and all(w in report for t in LABELS for w in t.split(" ("))
    # Each compression labelled by kind, in the explanation and the times; the budget said.
    assert "refined on screen, at most 3 steps" in flat and "brdfkit encode takes at most 40 by default" in flat
    # What each kind of column holds: the basis's coefficients (80 steps in encode), or a latent.
    assert ("basis-K: the full table compressed, as brdfkit encode does by default, into K numbers, the "
            "coefficients of the PCA basis the model ships") in flat
    from brdfkit.basis.coefficients import DEFAULT_STEPS

    assert f"brdfkit encode takes at most {DEFAULT_STEPS} by default" in flat
    assert "K-D: the full table compressed into the hypernetwork's K-D latent" in flat
    assert "by a hypernetwork (" not in flat
    assert "in-sample (merl-rgl-l40, merl-rgl-l7): trained on all 151 MERL + RGL materials, these included" in flat
    assert "unseen (merl80-l40): trained without the 20 MERL test materials" in flat
    for label in LABELS:
        assert re.search(rf"encode \+ refine \(3 steps\), {re.escape(label)} \(mean\)\s*[│|]\s*[\d.]+", report), report
        assert re.search(rf"decode, {re.escape(label)} \(mean\)\s*[│|]\s*[\d.]+", report), report
    assert f"writing into {out}" in stderr.replace("\n", "")
    assert "compressing (refined on screen, at most 3 steps)" in re.sub(r"\s+", " ", stderr)
    assert "materials/  (2 files, 70.0 MB)" in report and "not kept" not in report
    assert "Look: open" in report and "drag on a sphere to turn the light" in flat
    assert "rendering violet-rubber and 5 reconstructions in the reference scene" in re.sub(r"\s+", " ", stderr)
    assert "rendering violet-rubber and 3 reconstructions in the backlight scene" in re.sub(r"\s+", " ", stderr)
    assert "comparison sheets, reference and backlight (10 renders, 8 px)" in flat


@pytest.mark.slow
def test_real_demo_writes_its_tables_embeddings_and_errors(demo_run):
    out, shelf = demo_run.out, demo_run.shelf
    assert sorted(os.listdir(out)) == ["decoded", "embeddings", "errors.json", "materials", "plot-violet-rubber.png",
                                       "reconstructed", "samples", "sheet-violet-rubber-backlight.png",
                                       "sheet-violet-rubber.png", "view.html"]
    # The tables: the material, the four sparse reconstructions, three compressions, a blend.
    ref = read_merl(out / "materials" / "violet-rubber.binary")
    np.testing.assert_allclose(ref, nbrdf_table(load_nbrdf_weights()["violet-rubber"], device="cpu"),
                               rtol=1e-12, equal_nan=True)
    for stem in ("prior-40", "prior-400", "ipca-40", "ipca-400"):
        assert np.isfinite(read_merl(out / "reconstructed" / f"violet-rubber-{stem}.binary")).any()
    entries = {m.name: m for m in builtin.read_manifest(shelf).bundles}
    assert len({m.part("network").digest for m in entries.values()}) == 3
    for m, latent, _ in SHELF:
        emb = read_embedding(out / "embeddings" / f"teflon-{m}.emb")
        # merl80-l40 ships a basis (3 components): a basis embedding of 9 numbers, named by the basis file
        basis = m == "merl80-l40"
        assert (emb.kind, emb.size) == (("basis", 9) if basis else ("hypernet", latent))
        assert emb.decoder == entries[m].part("basis" if basis else "network").digest
        assert (out / "decoded" / f"teflon-{m}.binary").is_file()
    assert sorted(os.listdir(out / "decoded")) == sorted(
        [f"{n}-{m}.binary" for n in ("violet-rubber", "teflon") for m, _, _ in SHELF]
        + ["violet-rubber+teflon-t0.5-merl80-l40.binary"])
    blend = read_embedding(out / "embeddings" / "violet-rubber+teflon-t0.5-merl80-l40.emb")
    assert blend.decoder == entries["merl80-l40"].part("basis").digest
    assert len((out / "samples" / "teflon-40.csv").read_text().splitlines()) > 40
    doc = json.loads((out / "errors.json").read_text())
    assert doc["columns"] == SPARSE_COLUMNS + LABELS and list(doc["errors"]["teflon"]) == doc["columns"]
    assert [(c["column"], c["kind"], c["embedding"], c["size"]) for c in doc["compressions"]] == [
        (LABELS[0], "in-sample", "hypernet", 40), (LABELS[1], "in-sample", "hypernet", 7),
        (LABELS[2], "unseen", "basis", 9)]
    assert doc["compression_steps"] == 3 and doc["interpolation_model"] == "merl80-l40"
    assert doc["psnr"]["teflon"].keys() == doc["errors"]["teflon"].keys()  # the renders the tables rank by
    # The digests of the parts that made the figures, as the manifest records them: the
    # learnt prior and the basis of the sparse reconstructions, each compression's decoder.
    digest = lambda m, p: entries[m].part(p).digest  # noqa: E731
    assert doc["parts"] == {"merl80-l40": {p: digest("merl80-l40", p) for p in ("basis", "prior")},
                            "merl-rgl-l40": {"network": digest("merl-rgl-l40", "network")},
                            "merl-rgl-l7": {"network": digest("merl-rgl-l7", "network")}}
    # The page of the materials: the first, its unseen compression decoded by the page's shader, the other.
    page = (out / "view.html").read_text()
    data = json.loads(page.split('<script id="brdfkit-data" type="application/json">')[1].split("</script>")[0])
    assert [(m["label"], m["kind"]) for m in data["materials"]] == [
        ("violet-rubber", "table"), ("violet-rubber-merl80-l40", "live"), ("teflon", "table")]
    assert not [n for n in os.listdir(out) if n.startswith(".brdfkit-tmp-")]


@pytest.mark.slow
def test_real_demo_draws_its_sheets_and_copies_the_gallery(demo_run):
    """The sheets' scores in errors.json (what the gallery quotes), and the copies of the
    sheets, the plot and errors.json that ``--gallery`` makes for the docs."""
    out, gallery = demo_run.out, demo_run.gallery
    for png in ("sheet-violet-rubber.png", "sheet-violet-rubber-backlight.png", "plot-violet-rubber.png"):
        assert (out / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    doc = json.loads((out / "errors.json").read_text())
    assert list(doc["sheets"]) == ["reference", "backlight"]
    assert list(doc["sheets"]["reference"]) == ["prior, 40 samples", "prior, 400 samples", *TILES]
    assert list(doc["sheets"]["backlight"]) == TILES
    for row in (*doc["sheets"]["reference"].values(), *doc["sheets"]["backlight"].values()):
        assert set(row) == {"psnr", "delta_e", "ssim", "brdf_log_rmse", "delta_e_max"}
        assert row["delta_e_max"] >= row["delta_e"] >= 0
    assert sorted(os.listdir(gallery)) == ["demo-errors.json", "demo-plot.png", "demo-sheet-backlight.png",
                                           "demo-sheet.png"]
    for src, dst in (("errors.json", "demo-errors.json"), ("sheet-violet-rubber.png", "demo-sheet.png"),
                     ("sheet-violet-rubber-backlight.png", "demo-sheet-backlight.png"),
                     ("plot-violet-rubber.png", "demo-plot.png")):
        assert (gallery / dst).read_bytes() == (out / src).read_bytes()
    assert "Copied into" in demo_run.report


@pytest.mark.slow
def test_real_demo_without_render_keeps_no_table(quick, monkeypatch, capsys, tmp_path):
    """``brdfkit demo --no-render``: no sheet, so no dense table written, not even a
    temporary one, and the output says how to keep them."""
    import brdfkit.api
    import brdfkit.demos.real_materials

    calls, results = [], []
    encode, run_real_demo = brdfkit.api.encode, brdfkit.demos.real_materials.run_real_demo

    def recording_encode(data, model, **kw):
        calls.append((model.kind, model.sizes[-1], kw.get("refine", True), kw.get("steps")))
        return encode(data, model, **kw)

    monkeypatch.setattr(brdfkit.api, "encode", recording_encode)
    _no_plot(monkeypatch)
    # the command's own result, kept (the command imports the function when it runs)
    monkeypatch.setattr(brdfkit.demos.real_materials, "run_real_demo",
                        lambda *a, **kw: results.append(run_real_demo(*a, **kw)) or results[-1])
    code, stdout, stderr = run_cli(capsys, ["demo", "--out", tmp_path / "d", "--only", "chrome-steel", "--no-render",
                                            "--device", "cpu"])
    assert code == 0, stderr[-3000:]
    flat = re.sub(r"\s+", " ", stdout)
    assert "were not kept; --keep-tables writes them" in flat and "Look: open" not in flat
    assert "(8 tables, 0.28 GB); brdfkit material chrome-steel -o chrome-steel.binary writes" in flat
    assert "dense tables stay in memory" in re.sub(r"\s+", " ", stderr)
    res = results[0]
    assert res.materials == ["chrome-steel"] and res.sparse_method == "prior" and res.sheet is None
    assert res.columns == SPARSE_COLUMNS + LABELS
    assert [c[:3] for c in res.compressions] == [
        ("merl-rgl-l40", "in-sample", LABELS[0]), ("merl-rgl-l7", "in-sample", LABELS[1]),
        ("merl80-l40", "unseen", LABELS[2])]
    # Every full table refined on screen for the demo's steps, read when the demo runs.
    assert calls == [("hypernet", 40, True, 3), ("hypernet", 7, True, 3), ("basis", 9, True, 3)]
    assert res.compression_steps == 3
    assert [t for t, _ in res.times if t.startswith("encode")] == [
        f"encode + refine (3 steps), {label} (mean)" for label in LABELS]
    assert len(res.errors) == 1 and len(res.errors[0][1]) == 7
    assert res.times[-1][0] == "whole demo" and all(t >= 0 for _, t in res.times)
    assert all(os.path.isfile(p) for p in res.files)
    assert not any("+" in os.path.basename(p) for p in res.files)  # one material: no blend
    assert not res.keep_tables and not [p for p in res.files if p.endswith(".binary")]
    assert sorted(os.listdir(tmp_path / "d")) == ["embeddings", "errors.json", "plot-chrome-steel.png", "samples"]
    assert sorted(os.listdir(tmp_path / "d" / "embeddings")) == [
        "chrome-steel-merl-rgl-l40.emb", "chrome-steel-merl-rgl-l7.emb", "chrome-steel-merl80-l40.emb"]
    doc = json.loads((tmp_path / "d" / "errors.json").read_text())
    assert doc["columns"] == res.columns and doc["errors"]["chrome-steel"]["ipca 40"] == res.errors[0][1][2]
    assert doc["errors"]["chrome-steel"][LABELS[1]] == res.errors[0][1][5]
    assert ("write the MERL tables the sheet renders, to a temporary folder (0)", 0.0) in res.times
    # steps=0 (no refinement): the sheet test's runs


def test_compression_labels():
    from brdfkit.demos.real_materials import compression_labels

    assert [c[2:] for c in compression_labels({"merl-rgl-l40": 40, "merl-rgl-l7": 7, "merl80-l40": "basis-9"})] == \
        list(zip(LABELS, TILES))
    assert [c[2] for c in compression_labels({"merl-rgl-l40": "basis-39", "merl-rgl-l7": 7, "merl80-l40": 40})] == \
        ["in-sample basis-39 (merl-rgl-l40)", "in-sample 7-D (merl-rgl-l7)", "unseen 40-D (merl80-l40)"]
    # What the files hold, not what the names say; where short labels would coincide, the full ones.
    got = compression_labels({"merl-rgl-l40": 7, "merl-rgl-l7": 7, "merl80-l40": 16})
    assert [c[2:] for c in got] == [("in-sample 7-D (merl-rgl-l40)",) * 2, ("in-sample 7-D (merl-rgl-l7)",) * 2,
                                    ("unseen 16-D (merl80-l40)",) * 2]


def _no_plot(monkeypatch):
    """The demo's plot in this process from now on an empty file at its path (the
    matplotlib figure takes seconds; ``demo_run``'s tests check the plot drawn)."""
    import brdfkit.figures.brdf_plot

    monkeypatch.setattr(brdfkit.figures.brdf_plot, "plot_brdfs", lambda shown, path, **kw: open(path, "wb").close())


def _interrupted_sheet(monkeypatch, seen):
    import brdfkit.figures.comparison_sheet

    def sheet(ref, preds, output, **kw):
        seen.extend([ref, *preds])
        seen.append({p: read_merl(p) for p in [ref, *preds]})
        raise KeyboardInterrupt

    monkeypatch.setattr(brdfkit.figures.comparison_sheet, "comparison_sheet", sheet)


@pytest.mark.slow
def test_real_demo_sheet_tables_are_temporary_and_labelled(quick, monkeypatch, tmp_path, capsys):
    """The sheet's six inputs are named by their tiles' labels (the sheet labels its tiles
    with the file stems): the reference, the default method from both sample counts and
    the three compressions, in-sample and unseen. Without --keep-tables they go to a
    temporary folder in OUT that is removed at the end, and on Ctrl-C during the sheet
    too; with it, they are links to the kept tables, in a temporary folder likewise. (The
    sheets themselves: ``demo_run``.) At steps=0 every compression is the encoder's pass
    alone, and said so."""
    import brdfkit.api
    from brdfkit.demos.real_materials import run_real_demo
    from brdfkit.demos.real_outputs import StepClock, step_times

    calls = []
    encode = brdfkit.api.encode

    def recording_encode(data, model, **kw):
        calls.append((model.kind, model.sizes[-1], kw.get("refine", True), kw.get("steps")))
        return encode(data, model, **kw)

    monkeypatch.setattr(brdfkit.api, "encode", recording_encode)
    _no_plot(monkeypatch)
    tiles = ["teflon.binary", "prior, 40 samples.binary", "prior, 400 samples.binary",
             *(f"{t}.binary" for t in TILES)]
    for keep, out in ((False, tmp_path / "d"), (True, tmp_path / "k")):
        seen = []
        calls.clear()
        _interrupted_sheet(monkeypatch, seen)
        with pytest.raises(KeyboardInterrupt):
            # steps=0: the refinements change no table's place on the sheet, and cost seconds each
            run_real_demo(out, only=["teflon"], device="cpu", keep_tables=keep, resolution=8, steps=0)
        assert calls == [("hypernet", 40, False, 0), ("hypernet", 7, False, 0), ("basis", 9, False, 0)]  # no refinement
        assert "teflon: decoding its NBRDF network, reconstructing, compressing (encoder pass only)" in re.sub(
            r"\s+", " ", capsys.readouterr().err)
        tables = seen.pop()
        assert [os.path.basename(p) for p in seen] == tiles
        assert all(os.path.basename(os.path.dirname(p)).startswith(".brdfkit-tmp-demo-") for p in seen)
        assert not any(os.path.exists(p) for p in seen)
        assert not [n for n in os.listdir(out) if n.startswith(".")]
        if keep:  # the same tables as those kept, compression by compression
            kept = [out / "materials" / "teflon.binary", out / "reconstructed" / "teflon-prior-40.binary",
                    out / "reconstructed" / "teflon-prior-400.binary",
                    *(out / "decoded" / f"teflon-{m}.binary" for m in ("merl-rgl-l40", "merl-rgl-l7", "merl80-l40"))]
            for path, k in zip(seen, kept):
                np.testing.assert_array_equal(tables[path], read_merl(k))
        else:
            assert sorted(os.listdir(out)) == ["embeddings", "plot-teflon.png", "samples"]
    # The times' label of a run at steps=0 (the interrupted runs return none)
    files = types.SimpleNamespace(keep_tables=False, n_tables=0, scratch=None)
    times = step_times(StepClock(), [], [("merl-rgl-l40", "in-sample", LABELS[0], TILES[0])], 1, 2, files, 0, 6, 8)
    assert times[2][0] == f"encode (encoder pass only), {LABELS[0]} (mean)"


def test_sheets_render_at_128_px_by_default():
    """At 64 px a sphere is a blocky disc: the sheets and the renders the tables rank by
    are 128 px unless --resolution says otherwise."""
    import inspect

    from brdfkit.cli.demo import command
    from brdfkit.demos.real_materials import SHEET_RESOLUTION, run_real_demo

    assert SHEET_RESOLUTION >= 128
    assert inspect.signature(run_real_demo).parameters["resolution"].default == SHEET_RESOLUTION
    assert next(p for p in command.params if p.name == "resolution").default == SHEET_RESOLUTION


def test_no_builtin_models_is_one_line_pointing_at_train(tmp_path):
    proc = _run(["--out", tmp_path / "d"])  # the empty folder of conftest's no_model_env
    assert proc.returncode == 2
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("brdfkit: error: "), proc.stderr
    assert "brdfkit demo --train" in lines[0] and "no built-in model is installed" in lines[0]
    assert proc.stdout == "" and not (tmp_path / "d").exists()


def test_bad_options_are_one_line(shelf, monkeypatch, capsys, tmp_path):
    monkeypatch.setenv(builtin.BUILTIN_ENV, str(shelf))
    for args, words in ((["--only", "pink-felt"], "unknown demo material"),
                        (["--train", "--resolution", "32"], "--resolution"),
                        (["--steps", "3", "--only", "teflon"], "--only"),
                        (["--gallery", str(tmp_path / "nowhere")], "--gallery"),
                        (["--gallery", str(tmp_path), "--no-render"], "--no-render does not draw"),
                        (["--train", "--gallery", str(tmp_path)], "--gallery")):
        with pytest.raises(SystemExit) as e:
            main(["demo", "--out", str(tmp_path / "d"), *args])
        err = capsys.readouterr().err
        assert e.value.code == 2 and words in err and len(err.strip().splitlines()) == 1, err
    from brdfkit.demos.real_materials import run_real_demo
    from brdfkit.errors import InputError

    with pytest.raises(InputError, match="refinement steps must be a whole number >= 0"):
        run_real_demo(tmp_path / "b", steps=-1)
    assert not (tmp_path / "b").exists()
