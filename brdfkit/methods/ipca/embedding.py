"""Basis embeddings: a material as the coefficients of a PCA basis (issue 29).

A hypernetwork's latent holds for the materials it was trained on and fails outside
them (``docs/compression.md``: 6.9 dB under a PCA of the same size on the 20 unseen
test materials). A basis embedding holds ``K`` coefficients per channel of the PCA basis
a built-in model ships (the leading ``K`` of its 32 components; ``3 K`` numbers, ``K =
latent_dim // 3``): the least-squares projection of the table, which is the PCA of that
size whatever the material, then refined on renders of the objective scenes
(:mod:`.refine_on_screen`; never a judged scene), keeping the projection wherever the
held-out pixels do not agree. Decoding is the basis's closed form
(:meth:`~.model.IpcaModel.decode`); blending two embeddings blends the log-mapped tables.

The embedding names its basis by the sha256 of the basis file
(:attr:`brdfkit.io.embedding.Embedding.basis`) and its model by the model's fingerprint,
as a hypernetwork latent does.
"""

from __future__ import annotations

import functools
import os

import numpy as np

from brdfkit.errors import ModelMismatchError

__all__ = [
    "DEFAULT_STEPS",
    "BasisBRDF",
    "basis_coefficients",
    "basis_fingerprint",
    "components_for",
    "encode_basis",
    "model_basis",
]

DEFAULT_STEPS = 80
"""Most refinement steps of a basis embedding (``brdfkit encode --steps``), chosen with
:data:`~.refine_on_screen.DEFAULT_LR` and :data:`~.refine_on_screen.DEFAULT_TRUST` on 20
training materials (``docs/compression.md``, issue 29)."""


def components_for(latent_dim: int, basis=None) -> int:
    """Components per channel of a model's basis embedding: as many as its latent holds
    numbers (``latent_dim // 3``; 13 for the 40-D built-ins, 39 numbers), at most the
    basis's own (when given)."""
    k = max(1, int(latent_dim) // 3)
    return k if basis is None else min(k, basis.n_components)


@functools.lru_cache(maxsize=4)
def _digest(path: str, size: int, mtime: int) -> str:
    from brdfkit.io.digest import file_digest

    return file_digest(path)


def basis_fingerprint(path: str | os.PathLike) -> str:
    """sha256 hex of a basis file (kept per file while its size and time stay)."""
    st = os.stat(path)
    return _digest(os.fspath(path), st.st_size, st.st_mtime_ns)


def encode_basis(basis, table, *, fingerprint: str, model_fingerprint: str, components: int,
                 source: str = "", steps: int | None = None):
    """A dense table as a basis embedding.

    Parameters
    ----------
    basis
        :class:`~.model.IpcaModel` with at least ``components`` components.
    table
        ``(90, 90, 180, 3)`` BRDF in 1/sr, NaN where unmeasured.
    fingerprint, model_fingerprint
        sha256 of the basis file (:func:`basis_fingerprint`), fingerprint of the model
        it ships with.
    components
        ``K``: the embedding holds ``3 K`` numbers.
    steps
        Most refinement steps (default :data:`DEFAULT_STEPS`; 0: the projection alone).

    Returns
    -------
    brdfkit.io.embedding.Embedding
        ``latent`` float32 ``(3 K,)``, the ``(K, 3)`` coefficients component-major;
        ``refinement`` records the steps.
    """
    from brdfkit.hypernet.refine_on_screen import CompressConfig
    from brdfkit.io.embedding import Embedding
    from brdfkit.methods.ipca.refine_on_screen import (
        DEFAULT_LR,
        DEFAULT_TRUST,
        refine_coefficients,
    )

    part = basis.leading(components)
    c0 = part.project(table)
    steps = DEFAULT_STEPS if steps is None else int(steps)
    c, rec = refine_coefficients(part, table, c0, CompressConfig(steps=steps, lr=DEFAULT_LR), trust=DEFAULT_TRUST)
    measured = int(np.isfinite(np.asarray(table).reshape(-1, 3)).all(axis=1).sum())
    record = {k: rec[k] for k in ("steps", "best_step", "stopped")} if steps else None
    return Embedding(np.asarray(c, np.float32).reshape(-1), model_fingerprint, source, measured,
                     refinement=record, basis=fingerprint)


def basis_coefficients(emb, basis, fingerprint: str, name: str = "") -> np.ndarray:
    """The ``(K, 3)`` float32 coefficients of a basis embedding, checked against the
    basis (its file's sha256 ``fingerprint``, enough components).

    Raises
    ------
    ModelMismatchError
        Another basis, or more components than the basis has (one line).
    """
    what = f"embedding {name}" if name else "embedding"
    if emb.basis != fingerprint:
        raise ModelMismatchError(f"{what} holds coefficients of basis {str(emb.basis)[:12]}, not of this model's "
                                 f"basis {fingerprint[:12]}; encode the material again with this model")
    k = emb.latent_dim // 3
    if k > basis.n_components:
        raise ModelMismatchError(f"{what} holds {k} components a channel; the basis has {basis.n_components}")
    return emb.latent.reshape(k, 3)


class BasisBRDF:
    """A basis embedding as a renderable BRDF (``eval_dirs``, ``to_table``).

    The closed-form decode of all 1.1 million cells (about 0.2 s on one CPU thread) costs
    less than one trilinear pass of a 128 px render (11.8 million pairs), and evaluating
    the basis at a render's direction pairs instead would gather ``K + 2`` values at
    each of their eight corners: so the table is decoded once, on first use, and looked
    up as :class:`brdfkit.render.renderable.TableBRDF` looks up any table.
    """

    def __init__(self, basis, coefficients, name: str = "embedding", device=None):
        self.basis = basis
        self.coefficients = np.asarray(coefficients, np.float32)
        self.name = name
        self.device = device
        self._table = None

    def to_table(self) -> np.ndarray:
        """float64 ``(90, 90, 180, 3)``, 1/sr, NaN off the basis's cells."""
        return self.basis.leading(self.coefficients.shape[0]).decode(self.coefficients)

    def eval_dirs(self, wi, wo):
        """BRDF ``(N, 3)`` float32 at local direction pairs (as :class:`~brdfkit.render.renderable.TableBRDF`)."""
        if self._table is None:
            from brdfkit.render.renderable import TableBRDF

            self._table = TableBRDF(self.to_table(), name=self.name, device=self.device)
        return self._table.eval_dirs(wi, wo)


@functools.lru_cache(maxsize=2)
def _load(path: str, digest: str):
    from brdfkit.methods.ipca.basis_file import load_ipca

    return load_ipca(path)


def model_basis(model):
    """The PCA basis a loaded model ships with and its file's sha256: ``(IpcaModel,
    str)``, or ``None`` (a model that is not an installed built-in with a learnt prior).
    Kept per process (loading a built-in's basis takes seconds)."""
    from brdfkit.models.builtin import basis_for_model

    path = basis_for_model(getattr(model, "fingerprint", None))
    if path is None:
        return None
    digest = basis_fingerprint(path)
    return _load(os.fspath(path), digest), digest
