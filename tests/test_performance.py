"""The performance shortcuts (docs/notes/performance.md) compute the same numbers as the plain
definitions they replace."""

from __future__ import annotations

import numpy as np
import pytest

from brdfkit.geometry import N_CELLS, cell_angles, hd_vectors
from brdfkit.geometry import grid_hd


def test_grid_hd_is_the_per_cell_definition_bit_for_bit():
    """grid_hd broadcasts 90 half vectors and 16,200 difference vectors; every one of the
    1,458,000 rows must equal hd_vectors at that cell's own angles, rounded to float32."""
    hd = grid_hd()
    th, td, pd = cell_angles(np.arange(N_CELLS))
    assert hd.shape == (N_CELLS, 6) and hd.dtype == np.float32 and not hd.flags.writeable
    np.testing.assert_array_equal(hd, hd_vectors(th, td, pd).astype(np.float32))


def test_threads_follow_the_idle_cores():
    from brdfkit.runtime import threads_for_load

    assert threads_for_load(2, 0.0) == 2
    assert threads_for_load(2, 0.9) == 1
    assert threads_for_load(2, 11.0) == 1
    assert threads_for_load(16, 3.2) == 13


def test_thread_choice_leaves_a_user_setting_alone(monkeypatch):
    from brdfkit import runtime as threads

    env = {"OMP_NUM_THREADS": "7"}
    assert threads.set_default_threads(env) is None and env == {"OMP_NUM_THREADS": "7"}
    monkeypatch.setattr(threads.os, "getloadavg", lambda: (50.0, 50.0, 50.0))
    monkeypatch.setattr(threads, "running_others", lambda: 50)
    env = {}
    assert threads.set_default_threads(env) == 1 and env == {"OMP_NUM_THREADS": "1"}
    monkeypatch.setattr(threads.os, "getloadavg", lambda: (0.0, 0.0, 0.0))
    env = {}
    assert threads.set_default_threads(env) >= 1 and "OMP_NUM_THREADS" not in env


def test_a_finished_command_does_not_hold_threads_back(monkeypatch):
    """Load average 1.0 left by the previous command, nothing runnable now: both cores."""
    from brdfkit import runtime as threads

    monkeypatch.setattr(threads, "_cpus", lambda: 2)
    monkeypatch.setattr(threads.os, "getloadavg", lambda: (1.0, 1.0, 1.0))
    monkeypatch.setattr(threads, "running_others", lambda: 0)
    assert threads.idle_cores() == 2
    monkeypatch.setattr(threads, "running_others", lambda: 1)  # a job keeps a core busy
    assert threads.idle_cores() == 1
    monkeypatch.setattr(threads, "running_others", lambda: None)  # no /proc/loadavg
    assert threads.idle_cores() == 1


def test_blas_threads_sets_numpys_blas_and_restores_it():
    """``blas_threads(n)`` sets every BLAS loaded (found by threadpoolctl, whatever the
    build; one a module imported later brought too) for the block, and gives the count back
    after; ``None`` leaves it."""
    from threadpoolctl import threadpool_info

    from brdfkit.runtime import blas_threads

    def counts():
        return [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]

    with blas_threads(1):  # found once ...
        pass
    try:  # ... and again when a module brings another BLAS (SciPy's own OpenBLAS)
        import scipy.linalg  # noqa: F401
    except ImportError:
        pass
    before = counts()
    assert before, "threadpoolctl finds no BLAS in NumPy"
    other = 2 if before[0] == 1 else 1
    with blas_threads(other):
        assert counts() == [other] * len(before)
        with blas_threads(None):
            assert counts() == [other] * len(before)
    assert counts() == before


def test_beside_runs_a_piece_on_its_own_thread_or_now_and_gives_its_result_or_error():
    """``runtime.beside``: on a thread of its own with two threads allowed, now with one;
    either way ``result()`` is the function's value, or raises its error."""
    import threading

    from brdfkit import runtime

    def where(x):
        return x * 2, threading.current_thread().name

    def fails():
        raise ValueError("bad piece")

    try:
        for threads in (1, 2):
            runtime.set_cpu_threads(threads)
            value, name = runtime.beside(where, 21).result()
            assert value == 42 and (name == "brdfkit-beside") == (threads == 2)
            with pytest.raises(ValueError, match="bad piece"):
                runtime.beside(fails).result()
    finally:
        runtime._CPU_THREADS.clear()


def test_running_others_reads_this_machine():
    from brdfkit import runtime as threads

    n = threads.running_others()
    assert n is None or n >= 0


def test_fast_encoder_and_decoder_equal_the_model_definition(tmp_path):
    """The inference paths of brdfkit.hypernet (bias folded into the matrices, last encoder
    layer applied to the mean, the ten decoder MLPs stacked) against HyperBRDF itself."""
    import torch

    from brdfkit import api
    from brdfkit.hypernet import kernels
    from brdfkit.acquisition.sampling import draw_samples

    from helpers_model import make_model, material_table

    torch.set_num_threads(1)
    for config in (None, {"latent_dim": 7}):
        path = tmp_path / f"m{0 if config is None else 1}.safetensors"
        make_model(path, config=config, seed=3)
        model = api.load_model(path, device="cpu")
        s = draw_samples(material_table(1), 500, seed=2)
        emb = api.encode(s, model)
        ref = model.reference_at(s.theta_h, s.theta_d, s.phi_d)
        from brdfkit.hypernet.mapping import to_mapped

        x = np.concatenate([s.hd(), to_mapped(np.asarray(s.rgb, np.float64), ref)], axis=1)
        with torch.no_grad():
            z = model.net.encoder(torch.from_numpy(x.astype(np.float32))[None])[0].numpy()
            np.testing.assert_allclose(emb.values, z, rtol=1e-5, atol=1e-6)
            zt = torch.from_numpy(emb.values)[None]
            for (w, b), (w2, b2) in zip(model.net.hyponet_weights(zt), kernels.hyponet_weights(model, zt)):
                assert w.shape == w2.shape and b.shape == b2.shape
                np.testing.assert_allclose(w2.numpy(), w.numpy(), rtol=1e-5, atol=1e-6)
                np.testing.assert_allclose(b2.numpy(), b.numpy(), rtol=1e-5, atol=1e-6)
