"""Shared helpers of the model tests (model files, embeddings, api, model CLI).

Not a conftest: plain functions imported by the test modules that need them. Models are
untrained (the tests check plumbing, invariances and formats, not accuracy), saved with
the real :func:`brdfkit.hypernet.network_file.save_network` and loaded with the real loader.
"""

from __future__ import annotations

import functools

import numpy as np

from conftest import TINY_CONFIG


@functools.lru_cache(maxsize=None)
def material_table(index: int = 0) -> np.ndarray:
    """A synthetic MERL-grid table (computed once per test process; read-only).

    ``0``: the stiff white dielectric, used as the models' reference table;
    ``1``: a random GGX material of ``synthetic.library(seed=3)``.
    """
    from brdfkit.materials import synthetic

    mat = synthetic.STIFF[2] if index == 0 else synthetic.library(2, seed=3, stiff=False)[index - 1]
    t = synthetic.table(mat)
    t.setflags(write=False)
    return t


def make_model(path, config: dict | None = None, seed: int = 0, rho_ref=None) -> str:
    """Save an untrained model (``TINY_CONFIG`` unless ``config`` is given; ``{}`` is the
    paper's default architecture) and return its digest."""
    import torch

    from brdfkit.hypernet.network import HyperBRDF, HyperConfig
    from brdfkit.hypernet.network_file import save_network

    torch.manual_seed(seed)
    cfg = HyperConfig(**(TINY_CONFIG if config is None else config))
    ref = material_table(0) if rho_ref is None else rho_ref
    return save_network(path, HyperBRDF(cfg), ref, {"materials": ["stiff-white"], "steps": 0})



def write_inputs(folder, samples: str = "s.csv", n: int = 200):
    """``folder`` with the inputs of the command tests: ``mat.binary``
    (:func:`material_table` 1) and ``n`` samples of it (seed 0) named ``samples``."""
    from brdfkit.io.merl import write_merl
    from brdfkit.io.samples import write_samples
    from brdfkit.acquisition.sampling import draw_samples

    write_merl(folder / "mat.binary", material_table(1))
    write_samples(folder / samples, draw_samples(material_table(1), n, seed=0))
    return folder


def pack_tiny_builtins(src, folder, names, command=None, **entry) -> list:
    """Tiny untrained hypernetworks packed as built-ins into ``folder`` (trained copies in
    ``src``), sharing ``tiny.reference.safetensors``: one manifest entry each, for the
    ``(name, seed)`` pairs ``names``; ``command`` (default ``brdfkit fit (NAME)``) and
    ``entry`` (``validation=``, ``materials_list=`` ...) go into the entries."""
    from brdfkit.hypernet import packing

    entries = []
    for name, seed in names:
        make_model(src / f"{name}.safetensors", seed=seed)
        packing.pack_network(src / f"{name}.safetensors", folder / f"{name}.safetensors",
                           reference_file="tiny.reference.safetensors")
        entries.append(packing.manifest_entry(folder / f"{name}.safetensors", name,
                                              command=command or f"brdfkit fit ({name})", **entry))
    return entries
