"""The render-aligned error (:mod:`brdfkit.render.screen`), compression refined on screen
(:mod:`brdfkit.hypernet.refine_on_screen`, ``brdfkit encode --steps/--no-refine``) and screen tuning
(:mod:`brdfkit.hypernet.tuning`, ``brdfkit tune``): the small render is the reference scene's,
refinement is never worse than the encoder's pass on held-out pixels, and bad settings
are one-line errors."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from brdfkit import api
from brdfkit.hypernet.refine_on_screen import compress_table
from brdfkit.render.objective import ObjectiveConfig
from brdfkit.errors import InputError
from brdfkit.render import screen as screen_mod

from conftest import one_error_line, run_cli, tmp_leftovers
from helpers_model import make_model, material_table


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    d = tmp_path_factory.mktemp("compression")
    make_model(d / "model.safetensors", seed=0)
    return d, api.load_model(d / "model.safetensors", "cpu")


def test_screen_renders_what_the_quadrature_renders(tiny):
    """The small render is the reference scene's quadrature, to float32 rounding, for a
    table and for a hyponet (evaluated at the pairs only)."""
    from brdfkit.hypernet.neural_brdf import NeuralBRDF
    from brdfkit.render.renderable import TableBRDF
    from brdfkit.render.quadrature import render
    from brdfkit.render.scene import Scene

    _, m = tiny
    sc = screen_mod.screen(resolution=12)
    table = material_table(1)
    img, mask = render(TableBRDF(table, device="cpu"), Scene(resolution=12))
    np.testing.assert_allclose(sc.render_table(table), img[mask], rtol=2e-5, atol=1e-7)
    brdf = NeuralBRDF.from_embedding(m, api.encode(table, m, refine=False))
    img, mask = render(brdf, Scene(resolution=12))
    np.testing.assert_allclose(sc.render_hyponet(m, brdf.weights).detach().numpy(), img[mask],
                               rtol=2e-5, atol=1e-6)


def test_screen_error_is_the_metrics_psnr_and_has_gradients(tiny):
    from brdfkit.evaluation.metrics import psnr

    _, m = tiny
    sc = screen_mod.screen(resolution=12)
    a = sc.render_table(material_table(1)).astype(np.float32)
    b = sc.render_table(material_table(0)).astype(np.float32)
    img_a, img_b = np.zeros((sc.pixels, 1, 3)), np.zeros((sc.pixels, 1, 3))
    img_a[:, 0], img_b[:, 0] = a, b
    assert screen_mod.screen_psnr(a, b) == pytest.approx(psnr(img_a, img_b), abs=1e-4)
    assert screen_mod.screen_psnr(a, a) == 100.0
    assert screen_mod.screen_psnr(torch.from_numpy(a), torch.from_numpy(b)) == pytest.approx(psnr(img_a, img_b),
                                                                                             abs=1e-4)
    z = torch.zeros(1, m.cfg.latent_dim, requires_grad=True)
    screen_mod.screen_error(sc.render_hyponet(m, m.net.hyponet_weights(z)), torch.from_numpy(a)).backward()
    assert z.grad is not None and torch.isfinite(z.grad).all() and z.grad.abs().sum() > 0


def test_rotated_environment_turns_the_lights():
    from brdfkit.render.envmap import reference_envmap

    ref, rot = reference_envmap(), screen_mod.rotated_envmap(0.5)
    w = ref.image.shape[1]
    np.testing.assert_array_equal(rot.image[:, w // 2:], ref.image[:, :w - w // 2])
    for a, b in zip(ref.bright, rot.bright):
        assert (b[0] - a[0]) % 1.0 == pytest.approx(0.5) and b[2:] == a[2:]


@pytest.mark.slow
def test_refinement_is_never_worse_than_the_encoder_pass(tiny):
    _, m = tiny
    table = material_table(1)
    r = compress_table(m, table, ObjectiveConfig(steps=40, resolution=16))
    before, after = r.heldout
    assert after <= before
    assert r.best_step % 5 == 0 and r.best_step <= r.steps <= 40
    if r.best_step == 0:
        np.testing.assert_array_equal(r.embedding.values, r.encoder.values)
    else:
        assert after < before
    # Deterministic: a budget of steps, a convergence stop, no clock.
    again = compress_table(m, table, ObjectiveConfig(steps=40, resolution=16))
    np.testing.assert_array_equal(again.embedding.values, r.embedding.values)
    np.testing.assert_array_equal(r.encoder.values, api.encode(table, m, refine=False).values)


def test_zero_steps_is_the_encoder_pass(tiny):
    _, m = tiny
    table = material_table(1)
    z0 = api.encode(table, m, refine=False).values
    np.testing.assert_array_equal(api.encode(table, m, steps=0).values, z0)
    r = compress_table(m, table, ObjectiveConfig(steps=0))
    assert r.steps == 0 and r.embedding is r.encoder


@pytest.mark.parametrize("kw", [dict(steps=-1), dict(steps=2.5), dict(max_seconds=0.0),
                                dict(max_seconds=float("nan")), dict(holdout=1.0),
                                dict(pairs_per_pixel=0), dict(uniform_share=2.0)])
def test_bad_compress_settings_are_input_errors(kw):
    with pytest.raises(InputError):
        ObjectiveConfig(**kw)


@pytest.mark.slow
def test_encode_cli_refines_by_default_and_no_refine_is_the_papers_pass(tiny, tmp_path, capsys):
    from brdfkit.io.embedding import read_embedding
    from brdfkit.io.merl import write_merl

    d, m = tiny
    write_merl(tmp_path / "mat.binary", material_table(1))
    code, out, err = run_cli(capsys, ["encode", tmp_path / "mat.binary", "-m", d / "model.safetensors",
                                      "--no-refine", "-o", tmp_path / "plain"])
    assert code == 0 and "encoder pass" in out + err
    plain = read_embedding(tmp_path / "plain" / "mat.emb")
    np.testing.assert_allclose(plain.values, api.encode(material_table(1), m, refine=False).values, atol=1e-6)
    code, out, err = run_cli(capsys, ["encode", tmp_path / "mat.binary", "-m", d / "model.safetensors",
                                      "--steps", "10", "-o", tmp_path / "refined"])
    assert code == 0 and "refined on screen" in out + err
    assert read_embedding(tmp_path / "refined" / "mat.emb").values.shape == plain.values.shape
    code, out, err = run_cli(capsys, ["encode", tmp_path / "mat.binary", "-m", d / "model.safetensors",
                                      "--steps", "-2", "-o", tmp_path / "bad"])
    assert code == 2 and "Traceback" not in err and "--steps" in err
    assert not (tmp_path / "bad" / "mat.emb").exists()


@pytest.mark.slow
def test_tune_fits_the_renders_writes_a_model_and_resumes(tiny, tmp_path):
    from brdfkit.io.merl import write_merl
    from brdfkit.hypernet.tuning import TuneOptions, tune

    d, m = tiny
    data = tmp_path / "data"
    data.mkdir()
    write_merl(data / "a.binary", material_table(1))
    write_merl(data / "b.binary", material_table(0))
    opts = TuneOptions(batch=2, pairs_per_pixel=4, scenes=("studio-0",), query=64, context=64, resolution=8)
    out = tmp_path / "tuned.safetensors"
    done = tune(d / "model.safetensors", data, out, steps=3, options=opts)
    assert done["steps"] == 3 and done["materials"] == ["a", "b"]
    tuned = api.load_model(out, "cpu")
    three_steps = tuned.digest
    assert tuned.meta["tune"]["from"] == m.digest and tuned.digest != m.digest
    np.testing.assert_array_equal(tuned.rho_ref, m.rho_ref)
    # Resumed to 5 steps = run to 5 in one go (the batches are seeded by the step).
    tune(d / "model.safetensors", data, out, steps=5, options=opts, resume=True)
    one_go = tmp_path / "one-go.safetensors"
    tune(d / "model.safetensors", data, one_go, steps=5, options=opts)
    assert api.load_model(out, "cpu").digest == api.load_model(one_go, "cpu").digest
    assert not tmp_leftovers(tmp_path)
    with pytest.raises(InputError, match="another model, data or options"):
        tune(d / "model.safetensors", data, out, steps=6, options=TuneOptions(batch=1, scenes=("studio-0",), resolution=8),
             resume=True)
    # The learning rates may change on resuming (a second stage at other rates).
    faster = dataclasses.replace(opts, lr_decoder=1e-3, lr_latent=1e-2)
    assert tune(d / "model.safetensors", data, out, steps=6, options=faster, resume=True)["steps"] == 6
    # The ratio floor changes what is learnt, and a checkpoint of another floor weight is
    # another run's.
    floored = tmp_path / "floored.safetensors"
    tune(d / "model.safetensors", data, floored, steps=3, options=dataclasses.replace(opts, floor_weight=10.0))
    assert api.load_model(floored, "cpu").digest != three_steps
    with pytest.raises(InputError, match="another model, data or options"):
        tune(d / "model.safetensors", data, floored, steps=4, options=opts, resume=True)


@pytest.mark.parametrize("args, message", [
    (["-O", "scenes=reference"], "scenes"),
    (["-O", "batch=0"], "batch"),
    (["-O", "lr_decoder=x"], "not a number"),
    (["-O", "nope=1"], "unknown tune option"),
    ([], "--steps or --minutes"),
])
def test_tune_cli_bad_options(tiny, tmp_path, capsys, args, message):
    d, _ = tiny
    from brdfkit.io.merl import write_merl

    write_merl(tmp_path / "a.binary", material_table(1))
    extra = [] if not args or args[0] != "-O" else ["--steps", "1"]
    code, _, err = run_cli(capsys, ["tune", tmp_path / "a.binary", "-m", d / "model.safetensors",
                                    "-o", tmp_path / "o.safetensors", *extra, *args])
    assert code == 2 and "Traceback" not in err and message in one_error_line(err)
    assert not (tmp_path / "o.safetensors").exists()
