"""A trained hypernetwork packed for shipping as a built-in model (:mod:`brdfkit.models`).

``benchmarks/pack_builtin.py`` runs these: :func:`pack_model` re-saves a trained file
compactly, :func:`manifest_entry` reads its manifest entry from it, and
:func:`brdfkit.models.builtin.write_manifest` writes the manifest; :func:`load_builtin`
loads a built-in by name.
"""

from __future__ import annotations

import os

from brdfkit.hypernet.model_file import load_model, save_model
from brdfkit.models.builtin import resolve_model

__all__ = ["load_builtin", "pack_model", "manifest_entry"]


def load_builtin(spec: str | os.PathLike, device=None):
    """Load a built-in model by name (or a model file by path, :func:`resolve_model`).

    Returns
    -------
    brdfkit.hypernet.loaded.NeuralModel
    """
    return load_model(resolve_model(spec), device=device)


def pack_model(src: str | os.PathLike, dst: str | os.PathLike, *, half: bool = True,
               reference_file: str | None = None) -> str:
    """Re-save a trained model file for shipping: reference at its measured cells only,
    float16 unless ``half=False``, optionally in a shared reference file beside ``dst``
    (:func:`brdfkit.hypernet.model_file.save_model`). Returns the new file's fingerprint (for the
    manifest; with ``half`` it differs from the source's)."""
    m = load_model(src, device="cpu")
    return save_model(dst, m.net, m.rho_ref, m.meta, m.mapping, compact=True, half=half,
                      reference_file=reference_file)


def manifest_entry(path: str | os.PathLike, name: str, *, command: str, validation: dict,
                   materials_list: str | None = None) -> dict:
    """A manifest entry for a (packed) model file in the built-in folder, its latent
    size, fingerprint and training figures read from the file."""
    m = load_model(path, device="cpu")
    mats = m.meta.get("materials")
    return {"name": name, "file": os.path.basename(os.fspath(path)), "latent_dim": m.cfg.latent_dim,
            "materials": len(mats) if isinstance(mats, list) else mats, "materials_list": materials_list,
            "steps": m.meta.get("steps"), "train_seconds": m.meta.get("wall_time_s"), "command": command,
            "validation": {str(k): float(v) for k, v in validation.items()}, "fingerprint": m.fingerprint}
