"""A trained hypernetwork packed for shipping as a built-in model (:mod:`brdfkit.models`).

``tools/pack_builtin.py`` runs these: :func:`pack_network` re-saves a trained file
compactly, :func:`manifest_entry` reads a bundle's manifest entry from it, and
:func:`brdfkit.models.builtin.write_manifest` writes the manifest; :func:`load_builtin`
loads a built-in's network by name.
"""

from __future__ import annotations

import os

from brdfkit.hypernet.network_file import load_network, save_network
from brdfkit.models.builtin import resolve_network

__all__ = ["load_builtin", "pack_network", "manifest_entry"]


def load_builtin(spec: str | os.PathLike, device=None):
    """Load a built-in's hypernetwork by name (or a network file by path,
    :func:`resolve_network`).

    Returns
    -------
    brdfkit.hypernet.loaded.LoadedNetwork
    """
    return load_network(resolve_network(spec), device=device)


def pack_network(src: str | os.PathLike, dst: str | os.PathLike, *, half: bool = True,
                 reference_file: str | None = None) -> str:
    """Re-save a trained network file for shipping: reference at its measured cells only,
    float16 unless ``half=False``, optionally in a shared reference file beside ``dst``
    (:func:`brdfkit.hypernet.network_file.save_network`). Returns the new file's digest (for the
    manifest; with ``half`` it differs from the source's)."""
    m = load_network(src, device="cpu")
    return save_network(dst, m.net, m.rho_ref, m.meta, m.mapping, compact=True, half=half,
                        reference_file=reference_file)


def manifest_entry(path: str | os.PathLike, name: str, *, command: str, validation: dict,
                   materials_list: str | None = None) -> dict:
    """A bundle's manifest entry (version 2) for a (packed) network file in the built-in
    folder, its latent size, digest and training figures read from the file; other parts
    are added to its ``parts``."""
    m = load_network(path, device="cpu")
    mats = m.meta.get("materials")
    return {"name": name, "parts": {"network": {"file": os.path.basename(os.fspath(path)), "digest": m.digest}},
            "latent_dim": m.cfg.latent_dim, "materials": len(mats) if isinstance(mats, list) else mats,
            "materials_list": materials_list, "steps": m.meta.get("steps"), "train_seconds": m.meta.get("wall_time_s"),
            "command": command, "validation": {str(k): float(v) for k, v in validation.items()}}
