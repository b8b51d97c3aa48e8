"""The basis residual (``brdfkit.residual``): its file, its NumPy decode against the torch
module it was trained as, training through ``brdfkit fit --method residual`` (seeded,
resumable), encode and decode through the registry's ``residual`` kind, blends, and
every way a residual embedding is refused."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest

from brdfkit.basis import load_basis
from brdfkit.errors import ModelMismatchError
from brdfkit.io.embedding import read_embedding
from brdfkit.residual import ResidualConfig, load_residual, save_residual
from brdfkit.residual.network import ResidualNet, evaluate, hyponet_weights, net_input

from conftest import run_brdfkit, run_cli, run_cli_uncaptured, quiet_env
from helpers_training import tiny_library

TINY = ["-O", "sizes=6,12", "-O", "width=8", "-O", "hidden=16", "-O", "batch=4", "-O", "cells=256",
        "-O", "checkpoint_every=2"]


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """A tiny basis of the synthetic library and a residual of it, 6 steps (``brdfkit fit``
    in this process: the tests that need a process of its own start theirs)."""
    lib = tiny_library(tmp_path_factory)
    out = tmp_path_factory.mktemp("residual")
    basis = out / "basis.safetensors"
    code, err = run_cli_uncaptured(["fit", "--method", "basis", lib, "--components", "4", "-o", basis])
    assert code == 0, err
    res = out / "res.safetensors"
    code, err = run_cli_uncaptured(["fit", "--method", "residual", lib, "-O", f"basis={basis}", "--steps", "6",
                                    *TINY, "-o", res])
    assert code == 0, err
    return lib, basis, res


def test_numpy_decode_is_the_torch_module(tmp_path):
    import torch

    cfg = ResidualConfig(k_min=1, k_max=5, width=8, hidden=16)
    torch.manual_seed(0)
    net = ResidualNet(cfg)
    with torch.no_grad():
        for p in net.parameters():
            p.add_(0.1 * torch.randn_like(p))
    z = net_input(np.random.default_rng(0).standard_normal((3, 3)), 5)
    hd = np.random.default_rng(1).standard_normal((100, 6)).astype(np.float32)
    state = {k: v.numpy() for k, v in net.state_dict().items()}
    weights = hyponet_weights(state, cfg, z)
    with torch.no_grad():
        want = net(torch.as_tensor(z), torch.as_tensor(hd)).numpy()
    got = np.stack([evaluate(weights, hd, row) for row in range(3)])
    np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-6)


@pytest.mark.slow
def test_an_untrained_residual_is_its_basis(tmp_path):
    """The last layer starts at zero: before training the model decodes as the basis."""
    from brdfkit.basis import load_basis
    from brdfkit.io.digest import file_digest
    from brdfkit.testing.examples import tiny_basis_file

    bpath = tiny_basis_file(tmp_path / "b.safetensors")
    cfg = ResidualConfig(k_min=1, k_max=4, width=8, hidden=16)
    save_residual(tmp_path / "r.safetensors", [(cfg, ResidualNet(cfg).state_dict())],
                  basis_digest=file_digest(bpath), basis_file="b.safetensors")
    res = load_residual(tmp_path / "r.safetensors")
    c = np.array([[0.5, -0.2, 0.1], [0.1, 0.3, -0.4]])
    np.testing.assert_array_equal(res.decode(c, 1.0), res.decode(c, 0.0))
    np.testing.assert_allclose(res.decode(c, 0.0), load_basis(bpath).leading(2).decode(c), rtol=1e-6)


@pytest.mark.slow
def test_fit_writes_one_network_a_size_and_resumes_to_the_bit(trained, tmp_path):
    """A network for each size, in one file that names its basis; a run stopped by Ctrl-C
    (after its first checkpoint) and resumed gives the same bytes as a run never stopped
    (the fixture's; so the same run twice gives the same bytes)."""
    import signal
    import subprocess
    import time

    from brdfkit.io.digest import file_digest
    from conftest import brdfkit_command

    lib, basis, res = trained
    r = load_residual(res)
    assert r.basis_digest == file_digest(basis) and r.meta["steps"] == 6 and r.meta["world_size"] == 1
    assert r.sizes() == (6, 12) and [(c.k_min, c.k_max) for c, _ in r.nets] == [(2, 2), (4, 4)]
    part = tmp_path / "part.safetensors"
    run = ["fit", "--method", "residual", lib, "-O", f"basis={basis}", *TINY, "-o", part, "--steps", "6"]
    proc = subprocess.Popen(brdfkit_command() + [str(a) for a in run], env=quiet_env(), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    ckpt = tmp_path / "part.safetensors.ckpt"
    for _ in range(600):
        if ckpt.exists() or proc.poll() is not None:
            break
        time.sleep(0.1)
    proc.send_signal(signal.SIGINT)
    proc.communicate(timeout=300)
    assert ckpt.exists()
    code, err = run_cli_uncaptured(run + ["--resume"])  # in this process: the stop is what needed one
    assert code == 0, err
    assert part.read_bytes() == res.read_bytes()  # the fixture's run, never stopped: the same run twice


@pytest.mark.slow
def test_a_basis_fitted_twice_is_the_same_bytes(trained, tmp_path):
    """safetensors' own writer orders the header as a hash map does, differently in each
    process: brdfkit writes its own, sorted (a basis's SHA-256 names it in embeddings)."""
    lib, basis, _ = trained
    r = run_brdfkit(["fit", "--method", "basis", lib, "--components", "4", "-o", tmp_path / "b.safetensors"],
                    env=quiet_env())
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "b.safetensors").read_bytes() == basis.read_bytes()


@pytest.mark.parametrize("option, words", [("foo", "-O 'foo': expected KEY=VALUE"),
                                            ("colour=red", "fit --method residual takes -O")])
def test_the_checkpoint_tool_refuses_bad_options_in_one_line(tmp_path, capsys, option, words):
    """``tools/residual_checkpoint.py`` reads ``-O`` as ``brdfkit fit`` does: one line, exit 2."""
    import importlib.util

    path = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "tools", "residual_checkpoint.py")
    spec = importlib.util.spec_from_file_location("residual_checkpoint", path)
    tool = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tool)
    code = tool.main([str(tmp_path), "-o", str(tmp_path / "r.safetensors"), "-O", "basis=b.safetensors", "-O", option])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1 and words in err, err


@pytest.mark.slow
@pytest.mark.parametrize("opt", ["-O", "--minutes"])
def test_fit_refuses_bad_options_in_one_line(trained, tmp_path, opt, capsys):
    lib, basis, _ = trained
    extra = ["-O", "sizes=99"] if opt == "-O" else ["--minutes", "1"]
    code, _, err = run_cli(capsys, ["fit", "--method", "residual", lib, "-O", f"basis={basis}", *extra,
                                    "-o", tmp_path / "x"])
    assert code == 2 and len(err.strip().splitlines()) == 1 and not (tmp_path / "x").exists()


@pytest.mark.slow
def test_encode_decode_blend_through_the_residual_kind(trained, tmp_path, capsys):
    """``encode`` with a residual file makes a ``residual`` embedding that records both
    parts' digests, the same bytes on one thread and on two (both in this process: the
    thread count, not the process, is what could change them); ``decode`` reads it back
    without torch's help; a blend of two stays a valid, positive material. (Every shipped
    residual route through encode, decode and interpolate: the route matrix.)"""
    from brdfkit import runtime
    from brdfkit.io.digest import file_digest

    lib, basis, res = trained
    opts = ["-m", res, "--size", "12", "--steps", "4"]
    # both tables on one thread (the blend's two ends), the first again on two: fixed pieces, the same bytes
    try:
        for threads, tables, out in ((1, ["synth-000", "synth-001"], "a"), (2, ["synth-000"], "b")):
            runtime.set_cpu_threads(threads)
            code, _, err = run_cli(capsys, ["encode", *(lib / f"{t}.binary" for t in tables), *opts,
                                            "-o", tmp_path / out])
            assert code == 0, err
    finally:
        runtime._CPU_THREADS.clear()
    assert (tmp_path / "a" / "synth-000.emb").read_bytes() == (tmp_path / "b" / "synth-000.emb").read_bytes()
    emb = read_embedding(tmp_path / "a" / "synth-000.emb")
    assert emb.kind == "residual" and emb.size == 12
    assert emb.parts == {"basis": file_digest(basis), "residual": file_digest(res)}
    assert emb.options["correction"] in (0.0, 1.0)
    code, _, err = run_cli(capsys, ["interpolate", tmp_path / "a" / "synth-000.emb", tmp_path / "a" / "synth-001.emb",
                                    "--t", "0.3", "-o", tmp_path / "mix.emb"])
    assert code == 0, err
    code, _, err = run_cli(capsys, ["decode", tmp_path / "mix.emb", "-m", res, "-o", tmp_path / "mix.binary"])
    assert code == 0, err
    from brdfkit.io.merl import read_merl

    table = read_merl(tmp_path / "mix.binary")
    measured = np.isfinite(table)
    assert measured.any() and (table[measured] > 0).all()


def test_a_residual_embedding_is_refused_by_another_decoder_in_one_line(trained, tmp_path):
    from brdfkit.io.embedding import Embedding
    from brdfkit.io.digest import file_digest
    from brdfkit.residual.brdf import check_embedding

    lib, basis, res = trained
    r = load_residual(res)
    good = Embedding(np.zeros(6), "residual", file_digest(res), parts={"basis": r.basis_digest}, options={})
    check_embedding(good, r, file_digest(res))
    for bad, what in ((Embedding(np.zeros(6), "residual", "0" * 64), "made with"),
                      (Embedding(np.zeros(6), "residual", file_digest(res), parts={"basis": "1" * 64}), "basis"),
                      (Embedding(np.zeros(9), "residual", file_digest(res)), "numbers"),
                      (Embedding(np.zeros(6), "residual", file_digest(res), options={"correction": 3.0}), "outside")):
        with pytest.raises(ModelMismatchError, match=what):
            check_embedding(bad, r, file_digest(res))


def test_a_residual_file_that_lies_is_refused(trained, tmp_path):
    from brdfkit.errors import FormatError, InputError

    _, basis, res = trained
    r = load_residual(res)
    save_residual(tmp_path / "other.safetensors", r.nets, basis_digest="2" * 64, basis_file="none")
    with pytest.raises(InputError, match="basis it corrects"):
        load_residual(tmp_path / "other.safetensors")
    cfg, state = r.nets[0]
    # Its writer reads what it made back first: a file its reader refuses is not written...
    from brdfkit.atomic import UnreadableOutput

    with pytest.raises(UnreadableOutput, match="head.bias"):
        save_residual(tmp_path / "bad.safetensors", [(cfg, dict(state, **{"head.bias": state["head.bias"][:3]}))],
                      basis_digest=r.basis_digest)
    assert not (tmp_path / "bad.safetensors").exists()
    # ... and one made otherwise is refused by the reader.
    from brdfkit.io.tensorfile import open_safetensors, write_safetensors

    with open_safetensors(str(res), framework="numpy") as f:
        header, tensors = f.metadata(), {k: f.get_tensor(k) for k in f.keys()}
    tensors["net0.head.bias"] = tensors["net0.head.bias"][:3]
    write_safetensors(tmp_path / "bad.safetensors", tensors, header)
    with pytest.raises(FormatError, match="head.bias"):
        load_residual(tmp_path / "bad.safetensors", basis=(r.basis, r.basis_digest))
    (tmp_path / "junk.safetensors").write_bytes(b"not a file")
    with pytest.raises(FormatError):
        load_residual(tmp_path / "junk.safetensors")


def test_a_new_kind_is_one_registry_entry(monkeypatch, tmp_path):
    """A toy kind (a material as its mean albedo, 3 numbers) added as one entry of KINDS:
    encode and decode take it with no other change."""
    from brdfkit import api
    from brdfkit.embeddings import EmbeddingKind, registry
    from brdfkit.io.embedding import Embedding
    from brdfkit.testing.examples import lambertian_table

    class Flat:
        def __init__(self, values):
            self.values = values

        def to_table(self):
            return lambertian_table(tuple(np.pi * self.values))

    def encode(obj, digest, table, *, source, size, steps, refine, max_seconds=None):
        return Embedding(np.nanmean(table.reshape(-1, 3), axis=0), "toy", digest, source)

    toy = EmbeddingKind("toy", "mean albedo", "basis", lambda o: (3,), lambda o: 3, encode,
                        lambda o, d, e, n, dev: Flat(e.values))
    monkeypatch.setitem(registry.KINDS, "toy", toy)
    path = tmp_path / "toy.safetensors"
    from brdfkit.testing.examples import tiny_basis_file

    tiny_basis_file(path)  # a file whose header says "basis", the toy's part
    emb = api.encode(lambertian_table((0.3, 0.2, 0.1)), str(path), kind="toy")
    assert emb.kind == "toy" and emb.size == 3
    table = api.decode(emb, str(path))
    np.testing.assert_allclose(np.nanmax(table.reshape(-1, 3), axis=0), np.array([0.3, 0.2, 0.1]) / np.pi)


def test_int8_storage_decodes_as_the_float32_network_to_its_rounding(trained, tmp_path):
    """The built-ins store the heads in int8 (a scale a row): the correction stays within a
    few thousandths of the float32 network's, and the other tensors are float16."""
    _, _, res = trained
    r = load_residual(res)
    save_residual(tmp_path / "q.safetensors", r.nets, basis_digest=r.basis_digest, storage="int8")
    q = load_residual(tmp_path / "q.safetensors", basis=(r.basis, r.basis_digest))
    c = np.array([[1.0, 0.5, -0.2], [0.3, -0.1, 0.2]])
    a, b = r.correction(c), q.correction(c)
    assert np.abs(a - b).max() <= 5e-3 * max(np.abs(a).max(), 1e-3)
    assert os.path.getsize(tmp_path / "q.safetensors") < 0.45 * os.path.getsize(res)


@pytest.mark.slow
def test_two_process_fit_gives_one_residual_with_identical_ranks(trained, tmp_path):
    """``torchrun --nproc_per_node 2`` (gloo, CPU): one file, written by rank 0 alone,
    whose weights both ranks agree on."""
    import subprocess

    pytest.importorskip("torch.distributed")
    from conftest import brdfkit_command
    from test_ddp import torchrun

    lib, basis, _ = trained
    out = tmp_path / "r.safetensors"
    env = quiet_env()
    env.pop("WORLD_SIZE", None)
    cmd = torchrun() + ["--nproc_per_node", "2", "--no-python", *brdfkit_command(), "fit", "--method", "residual",
                        str(lib), "-O", f"basis={basis}", *TINY, "--steps", "4", "--device", "cpu", "-o", str(out)]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300, env=env, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert sorted(os.listdir(tmp_path)) == ["r.safetensors", "r.safetensors.ckpt"]
    from brdfkit.io.digest import file_digest

    r = load_residual(out, basis=(load_basis(basis), file_digest(basis)))
    assert r.meta["world_size"] == 2 and len(set(r.meta["rank_digests"])) == 1


def test_unmeasured_cells_are_left_out_of_the_loss():
    """A table's holes (NaN in the training pairs) give no target: the loss and its gradient
    are those of the measured cells alone, not of the basis cancelled there."""
    import torch

    from brdfkit.residual.training import TRAIN_DEFAULTS, _loss, _step_batch

    rng = np.random.default_rng(0)
    mapped = rng.standard_normal((6, 50)).astype(np.float16)
    mapped[0, :25] = np.nan  # a table with holes
    z = torch.as_tensor(rng.standard_normal((6, 3)).astype(np.float32))
    comp, sigma = torch.as_tensor(rng.standard_normal((3, 50)).astype(np.float32)), torch.ones(3)
    opts = dict(TRAIN_DEFAULTS, batch=64, cells=16, mixup=0.5)
    zb, cells, tb, measured = _step_batch(torch.Generator().manual_seed(0), z, mapped, comp, sigma, opts, torch, 3, 3)
    assert measured is not None and not bool(measured.all()) and bool(torch.isfinite(tb).all())
    pred = torch.zeros_like(tb, requires_grad=True)
    loss = _loss(pred, tb, measured)
    loss.backward()
    assert bool((pred.grad[~measured] == 0).all()) and bool((pred.grad[measured] != 0).any())
    want = float(((tb[measured]) ** 2).mean())
    assert abs(float(loss) - want) < 1e-5 * max(1.0, want)
    full = np.nan_to_num(mapped) + 1.0  # no holes: the plain mean, as before masking existed
    _, _, tb2, m2 = _step_batch(torch.Generator().manual_seed(0), z, full.astype(np.float16), comp, sigma, opts,
                                torch, 3, 3)
    assert m2 is None and float(_loss(torch.zeros_like(tb2), tb2, None)) == float((tb2 ** 2).mean())


@pytest.mark.slow
def test_codes_and_a_cosine_rate_train_to_the_same_bytes_twice(trained, tmp_path):
    """The auto-decoder codes, the cosine learning rate and the render-weighted cells
    (``-O codes_lr``, ``-O lr_end``, ``-O render_weight``): seeded, so the same run twice
    gives the same bytes, and they change what is learnt."""
    lib, basis, res = trained
    run = ["fit", "--method", "residual", lib, "-O", f"basis={basis}", *TINY, "-O", "codes_lr=0.01",
           "-O", "lr_end=0.1", "-O", "render_weight=0.5", "--steps", "6"]
    outs = []
    for name in ("a", "b"):
        code, err = run_cli_uncaptured(run + ["-o", tmp_path / f"{name}.safetensors"])
        assert code == 0, err
        outs.append((tmp_path / f"{name}.safetensors").read_bytes())
    assert outs[0] == outs[1] and outs[0] != res.read_bytes()
    from brdfkit.residual.residual_file import read_header

    meta = json.loads(read_header(tmp_path / "a.safetensors")["meta"])
    assert meta["options"]["codes_lr"] == 0.01 and meta["options"]["lr_end"] == 0.1


def test_render_weights_are_where_the_objective_scenes_look(trained):
    """A cell's render weight is positive only where an objective scene's pairs reach it,
    mean 1 per channel, and in proportion to how much a small change of the cell's mapped
    value moves the scenes' display-encoded renders (two cells compared by finite
    differences); its pool draws only where the weight is positive."""
    from brdfkit.basis.mapping import EPS
    from brdfkit.materials.synthetic import Material, table
    from brdfkit.render.display import display_encode
    from brdfkit.residual.render_weights import cell_pool, render_weights, scene_maps

    import glob

    from brdfkit.basis import fit_basis

    lib, _, _ = trained  # the shipped bases' weight floor: no cell where x' cannot resolve rho
    pca = fit_basis(sorted(glob.glob(os.path.join(lib, "*.binary"))), 4, w_floor=0.005)
    maps = scene_maps(pca, resolution=8)
    t = table(Material("glossy", "dielectric", 0.3, albedo=(0.1, 0.1, 0.1)))
    g = render_weights(pca, t, maps)
    reached = np.zeros(pca.cells.size, bool)
    for _, _, _, at in maps:
        reached[at] = True
    assert g.shape == (pca.cells.size, 3) and np.allclose(g.mean(axis=0), 1.0, rtol=1e-4)
    assert bool((g[~reached] == 0).all()) and bool((g[reached] > 0).any())

    def moved(i, delta=1e-3):  # display-space change of the scenes when x' of cell i moves by delta
        flat = t.reshape(-1, 3).copy()
        c, w = pca.cells[i], pca.cell_weight()[i]
        flat[c, 0] = ((flat[c, 0] * w + EPS) * np.exp(delta) - EPS) / w
        return sum(float(((display_encode(sc.render_table(flat.reshape(t.shape)))
                           - display_encode(sc.render_table(t)))[:, 0] ** 2).sum()) for sc, _, _, _ in maps)

    order = np.argsort(g[:, 0])
    big = order[-1]
    mid = order[min(np.searchsorted(g[order, 0], 0.01 * g[big, 0]), order.size - 2)]
    assert moved(big) / moved(mid) == pytest.approx(g[big, 0] / g[mid, 0], rel=0.05)
    pool = cell_pool(g[:, 0], seed=0, size=20000)
    assert bool(np.isin(pool, np.flatnonzero(g[:, 0] > 0)).all())


def test_members_are_planned_a_size_each_and_configs_read_as_before():
    """``-O members=M``: M networks a size, each its own member number; a config of member 0
    writes the JSON it wrote before members existed (files of one network a size keep
    their bytes), and a member's config reads back."""
    from brdfkit.residual.training import TRAIN_DEFAULTS, plan

    assert plan(dict(TRAIN_DEFAULTS, sizes="9,21", members=2)) == [(3, 3, 0), (3, 3, 1), (7, 7, 0), (7, 7, 1)]
    assert plan(dict(TRAIN_DEFAULTS, sizes="9")) == [(3, 3, 0)]
    assert "member" not in ResidualConfig(3, 3).to_json()
    cfg = ResidualConfig(3, 3, member=2)
    assert ResidualConfig.from_json(cfg.to_json()) == cfg
    with pytest.raises(ValueError, match="member"):
        ResidualConfig(3, 3, member=-1)


@pytest.mark.slow
def test_members_encode_choose_decode_blend_and_a_cut_training_writes_its_finished_networks(tmp_path_factory, tmp_path,
                                                                                            capsys):
    """A file of two members a size: encode records the member it chose (its gain option),
    decode adds that member's correction, a blend of two members' embeddings decodes as the
    blend of their corrections (the mapped space is linear in them), and the finished
    networks of a training's checkpoint are written as the whole run wrote them."""
    from brdfkit.residual.brdf import ResidualBRDF, check_embedding
    from brdfkit.residual.model import gain_options
    from brdfkit.residual.training import write_finished
    from helpers_training import tiny_library

    lib = tiny_library(tmp_path_factory)
    basis = tmp_path / "basis.safetensors"
    code, _, err = run_cli(capsys, ["fit", "--method", "basis", lib, "--components", "4", "-o", basis])
    assert code == 0, err
    res = tmp_path / "res.safetensors"
    opts = ["-O", f"basis={basis}", "--steps", "4", "-O", "members=2", *TINY]
    code, _, err = run_cli(capsys, ["fit", "--method", "residual", lib, *opts, "-o", res])
    assert code == 0, err
    r = load_residual(res)
    assert [(c.k_min, c.member) for c, _ in r.nets] == [(2, 0), (2, 1), (4, 0), (4, 1)]
    assert r.members(2) == (0, 1)
    code, _, err = run_cli(capsys, ["encode", lib / "synth-000.binary", "-m", res, "--size", "6", "--steps", "2",
                                    "-o", tmp_path / "e"])
    assert code == 0, err
    emb = read_embedding(tmp_path / "e" / "synth-000.emb")
    c, g = check_embedding(emb, r, emb.decoder)
    assert emb.options in (gain_options(None), gain_options(0), gain_options(1)) and set(g) <= {0, 1}
    np.testing.assert_allclose(ResidualBRDF(r, c, g).to_table(), r.decode(c, g))

    base = r.mapped(c, 0.0)
    one, two = r.mapped(c, {0: 1.0}) - base, r.mapped(c, {1: 1.0}) - base
    assert np.abs(one - two).max() > 1e-4  # two networks, two corrections
    blend = r.mapped(c, {0: 0.25, 1: 0.75})
    np.testing.assert_allclose(blend, base + 0.25 * one + 0.75 * two, atol=1e-5)
    from brdfkit.io.embedding import Embedding

    a = Embedding(emb.values, "residual", emb.decoder, "a", parts=emb.parts, options=gain_options(0))
    b = Embedding(emb.values, "residual", emb.decoder, "b", parts=emb.parts, options=gain_options(1))
    from brdfkit import api

    mix = api.interpolate(a, b, 0.75)
    assert check_embedding(mix, r, emb.decoder)[1] == {0: 0.25, 1: 0.75}

    # the finished networks of the checkpoint (the last network's last checkpoint holds the
    # three before it) are the whole run's first three, to the bit
    import shutil

    shutil.copyfile(str(res) + ".ckpt", tmp_path / "cut.safetensors.ckpt")
    n = write_finished([lib], tmp_path / "cut.safetensors", basis=str(basis), steps=4, members=2,
                       **dict(o.split("=", 1) for o in TINY[1::2]))
    cut = load_residual(tmp_path / "cut.safetensors")
    assert n == 3 and [cfg for cfg, _ in cut.nets] == [cfg for cfg, _ in r.nets[:3]]
    for (_, s1), (_, s2) in zip(cut.nets, r.nets):
        assert all(np.array_equal(s1[k], s2[k]) for k in s1)
