"""Small, synthetic inputs for the docstrings' examples (run by ``tests/test_doctests.py``).

The examples of the public API run on these rather than on real measurements, so that
they run anywhere in a second or two: a Lambertian table, a PCA basis of three synthetic
materials, and an untrained hypernetwork small enough to encode and decode at once. None
stands for a real result.

Examples
--------
>>> lambertian_table().shape
(90, 90, 180, 3)
"""

from __future__ import annotations

import functools
import os

import numpy as np

__all__ = ["TINY_CONFIG", "lambertian_table", "tiny_basis", "tiny_basis_file", "tiny_model"]

TINY_CONFIG = dict(latent_dim=7, encoder_hidden=(16, 16), hypo_hidden=8, hypo_layers=2, decoder_hidden=16,
                   decoder_layers=1)
"""A hypernetwork architecture (:class:`~brdfkit.hypernet.network.HyperConfig`) that
encodes and decodes a dense table in well under a second on one core."""


def lambertian_table(albedo=(0.8, 0.5, 0.2)) -> np.ndarray:
    """A Lambertian material as a MERL-grid table: ``albedo / pi`` (1/sr) wherever both
    directions are above the horizon, NaN elsewhere; float64 ``(90, 90, 180, 3)``."""
    from brdfkit.geometry import TABLE_SHAPE, valid_mask

    table = np.full(TABLE_SHAPE, np.nan)
    table[valid_mask()] = np.asarray(albedo, np.float64) / np.pi
    return table


def tiny_model(path: str | os.PathLike, seed: int = 0) -> str:
    """Write an untrained hypernetwork of :data:`TINY_CONFIG` to ``path`` (its reference
    table :func:`lambertian_table`) and return the path; load it with
    :func:`brdfkit.load_model`."""
    import torch

    from brdfkit.hypernet.network_file import save_network
    from brdfkit.hypernet.network import HyperBRDF, HyperConfig

    torch.manual_seed(seed)
    save_network(path, HyperBRDF(HyperConfig(**TINY_CONFIG)), lambertian_table(), {"materials": [], "steps": 0})
    return os.fspath(path)


@functools.lru_cache(maxsize=2)
def _synthetic_tables() -> tuple:
    from brdfkit.materials.synthetic import library, table

    return tuple(table(m) for m in library(3, seed=0, stiff=False))


def tiny_basis(components: int = 4):
    """A :class:`~brdfkit.basis.model.PcaBasis` of ``components`` components (at most 8)
    fitted to three synthetic materials (:func:`brdfkit.materials.synthetic.library`)."""
    from brdfkit.basis.fit import fit_basis

    return fit_basis(_synthetic_tables(), components)


def tiny_basis_file(path: str | os.PathLike, components: int = 4) -> str:
    """Write :func:`tiny_basis` to ``path`` (format ``brdfkit-basis``) and return the path."""
    from brdfkit.basis.basis_file import save_basis

    save_basis(path, tiny_basis(components))
    return os.fspath(path)
