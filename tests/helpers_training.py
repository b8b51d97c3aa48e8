"""Shared helpers of the training tests (fit, resume, DDP, demo).

Not a conftest: plain functions imported by the test modules that need them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from brdfkit.io.merl import is_merl_file


def synthetic_library(tmp_path_factory, n: int = 3, seed: int = 1) -> Path:
    """A folder of ``n`` synthetic MERL tables (random GGX materials ``synth-000`` ... of
    :func:`brdfkit.materials.synthetic.library` with ``seed``), written once per test run
    and shared, read-only, by the test modules of both pytest-xdist workers (a table takes
    about a second to compute)."""
    import os
    import shutil
    import tempfile

    from brdfkit.materials.synthetic import write_library

    base = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        base = base.parent  # this run's folder, above each worker's own
    folder = base / f"synthetic-lib-{n}-seed-{seed}"
    if not all(is_merl_file(folder / f"synth-{i:03d}.binary") for i in range(n)):
        part = Path(tempfile.mkdtemp(prefix=f".{folder.name}-", dir=base))
        write_library(part, n, seed=seed, stiff=False)
        try:
            os.rename(part, folder)
        except OSError:  # the other worker wrote it first: the same tables
            shutil.rmtree(part, ignore_errors=True)
    return folder


def tiny_library(tmp_path_factory, n: int = 3) -> Path:
    """The training tests' library: :func:`synthetic_library` of ``n`` tables, seed 1."""
    return synthetic_library(tmp_path_factory, n, seed=1)


def mapped_mse_and_log_rmse(net, rho_ref, table, n_samples=200, n_cells=100_000, seed=5):
    """Reconstruct ``table`` from ``n_samples`` of its samples with ``net`` (encode, then
    the hyponet at ``n_cells`` random measured cells) and score it.

    Returns ``(mapped-space MSE, brdf_log_rmse over those cells)``.
    """
    import torch

    from brdfkit.geometry import N_CELLS, cell_angles, cell_index, hd_vectors
    from brdfkit.hypernet.network import hyponet_forward
    from brdfkit.hypernet.mapping import from_mapped, to_mapped
    from brdfkit.evaluation.metrics import brdf_log_rmse
    from brdfkit.acquisition.sampling import draw_samples

    flat = table.reshape(N_CELLS, 3)
    ref = np.asarray(rho_ref, np.float64).reshape(N_CELLS, 3)
    s = draw_samples(table, n_samples, seed=seed)
    ctx = to_mapped(s.rgb, ref[cell_index(s.theta_h, s.theta_d, s.phi_d)])
    measured = np.flatnonzero(np.isfinite(flat).all(1))
    cells = np.random.default_rng(seed).choice(measured, size=min(n_cells, measured.size), replace=False)
    with torch.no_grad():
        z = net.encode(torch.tensor(s.hd(), dtype=torch.float32)[None],
                       torch.tensor(ctx, dtype=torch.float32)[None])
        hd = torch.tensor(hd_vectors(*cell_angles(cells)), dtype=torch.float32)[None]
        pred = hyponet_forward(net.hyponet_weights(z), hd)[0].double().numpy()
    target = to_mapped(flat[cells], ref[cells])
    out = np.full((N_CELLS, 3), np.nan)
    out[cells] = from_mapped(pred, ref[cells])
    return float(np.mean((pred - target) ** 2)), brdf_log_rmse(out.reshape(table.shape), table)
