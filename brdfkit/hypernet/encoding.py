"""Fitting a material into a model: measurements in, embedding out.

Gokbudak et al. 2024, Sec. 3: the set encoder maps every sample ``[H, D, rho']`` (half
and difference vectors with ``phi_h = 0``, log-relative mapped RGB) through a shared MLP
and averages, so any number of samples in any order gives an embedding. Sample values go
through :func:`brdfkit.hypernet.mapping.to_mapped` with the model's ``rho_ref`` at the samples' own
angles (:meth:`~brdfkit.hypernet.loaded.LoadedNetwork.reference_at`); the encoder runs through
the fused kernel :func:`brdfkit.hypernet.kernels.encode_mean`.
"""

from __future__ import annotations

import numpy as np

from brdfkit.io.embedding import Embedding
from brdfkit.errors import InputError
from brdfkit.geometry import N_CELLS, TABLE_SHAPE, grid_hd
from brdfkit.hypernet.kernels import encode_mean

__all__ = ["encode_samples", "encode_table"]


def encode_samples(model, samples, source: str = "") -> Embedding:
    """Embedding of a :class:`~brdfkit.io.samples.SampleSet` (any ``N >= 1``, any order).

    Parameters
    ----------
    model
        :class:`~brdfkit.hypernet.loaded.LoadedNetwork`.
    samples
        The measurements (angles in radians, RGB in 1/sr).
    source
        Provenance; defaults to ``samples.source``.

    Returns
    -------
    Embedding
        Kind ``"hypernet"``: the float32 latent, the model's digest as its decoder,
        ``sample_count = N``.
    """
    n = len(samples)
    if n < 1:
        raise InputError(f"{source or samples.source or 'samples'}: no samples to encode")
    hd = np.asarray(samples.hd(), dtype=np.float64)
    ref = model.reference_at(samples.theta_h, samples.theta_d, samples.phi_d)
    latent = encode_mean(model, hd, np.asarray(samples.rgb, dtype=np.float64), ref)
    return Embedding(latent, "hypernet", model.digest, source or samples.source, n)


def encode_table(model, table: np.ndarray, source: str = "") -> Embedding:
    """Embedding of a dense ``(90, 90, 180, 3)`` table (1/sr, NaN where unmeasured) from
    all its measured cells; ``sample_count`` records how many."""
    arr = np.asarray(table)
    if arr.shape != TABLE_SHAPE:
        raise InputError(f"{source or 'table'}: shape {arr.shape}, expected {TABLE_SHAPE}")
    flat = arr.reshape(N_CELLS, 3)
    idx = np.flatnonzero(np.isfinite(flat).all(axis=1))
    if idx.size == 0:
        raise InputError(f"{source or 'table'}: no measured cells to encode")
    ref = model.rho_ref.reshape(N_CELLS, 3)[idx].astype(np.float64)
    bad = ~np.isfinite(ref)
    if bad.any():
        ref = np.where(bad, model.reference_fallback()[None, :], ref)
    latent = encode_mean(model, grid_hd()[idx], flat[idx].astype(np.float64, copy=False), ref)
    return Embedding(latent, "hypernet", model.digest, source, int(idx.size))
