"""A material's embedding of either kind, made from a table and opened for rendering.

An embedding (:class:`brdfkit.io.embedding.Embedding`) is a hypernetwork latent
(Gokbudak et al. 2024; :mod:`brdfkit.hypernet`) or a *basis embedding*, the coefficients
of the PCA basis a built-in model ships (:mod:`brdfkit.methods.ipca.embedding`, issue
29). :func:`encode_table` makes one from a dense table, the basis kind by default where
the model has a basis; :func:`embedding_brdf` opens either with its model.

May import: what :mod:`brdfkit.methods` may, and :mod:`brdfkit.methods.ipca`.
"""

from __future__ import annotations

import numpy as np

from brdfkit.errors import InputError, ModelMismatchError

__all__ = ["KINDS", "basis_components", "embedding_brdf", "embedding_size", "encode_table"]

KINDS = ("basis", "latent")
"""The kinds of embedding ``brdfkit encode --kind`` names."""


def encode_table(model, table: np.ndarray, name: str = "", *, refine: bool = True, steps: int | None = None,
                 max_seconds: float | None = None, kind: str | None = None):
    """A dense table as an embedding of ``model`` (see :func:`brdfkit.api.encode`).

    ``kind`` ``None`` makes a basis embedding where the model ships a basis
    (:func:`~brdfkit.methods.ipca.embedding.model_basis`), else a latent; ``"basis"``
    refuses a model without one (:class:`InputError`); ``"latent"`` is the set encoder's
    pass, refined on screen unless ``refine`` is false. ``steps`` bounds either
    refinement (its kind's default when ``None``); ``max_seconds`` caps a latent's.
    """
    if kind not in (None,) + KINDS:
        raise InputError(f"embedding kind {kind!r}: expected 'basis' or 'latent'")
    if kind != "latent":
        from brdfkit.methods.ipca.embedding import (
            components_for,
            encode_basis,
            model_basis,
        )

        found = model_basis(model)
        if found is None and kind == "basis":
            raise InputError(f"model {model.fingerprint[:12]} ships no PCA basis (only the installed built-ins "
                             f"with a learnt prior do); encode a latent instead")
        if found is not None:
            basis, digest = found
            return encode_basis(basis, table, fingerprint=digest, model_fingerprint=model.fingerprint,
                                components=components_for(model.cfg.latent_dim, basis), source=name,
                                steps=(steps if refine else 0))
    from brdfkit.hypernet.encoding import encode_table as encoder_pass

    if not refine:
        return encoder_pass(model, table, name)
    from brdfkit.hypernet.refine_on_screen import (
        DEFAULT_STEPS,
        CompressConfig,
        compress_table,
    )

    cfg = CompressConfig(steps=DEFAULT_STEPS if steps is None else steps, max_seconds=max_seconds)
    return compress_table(model, table, cfg, name).embedding


def embedding_brdf(model, emb, name: str = ""):
    """The renderable BRDF of an embedding with the model that made it: its hyponet
    (:class:`~brdfkit.hypernet.neural_brdf.NeuralBRDF`), or for a basis embedding the
    basis the model ships (:class:`~brdfkit.methods.ipca.embedding.BasisBRDF`).

    Raises
    ------
    ModelMismatchError
        Another model made it, or (a basis embedding) the model ships no basis or another one.
    """
    from brdfkit.hypernet.neural_brdf import NeuralBRDF

    if emb.basis is None:
        return NeuralBRDF.from_embedding(model, emb, name)
    from brdfkit.methods.ipca.embedding import (
        BasisBRDF,
        basis_coefficients,
        model_basis,
    )

    what = f"embedding {name}" if name else "embedding"
    if emb.model_fingerprint != model.fingerprint:
        raise ModelMismatchError(f"{what} was made with model {emb.model_fingerprint[:12]}, not with the given model "
                                 f"{model.fingerprint[:12]}; encode the material again with this model")
    found = model_basis(model)
    if found is None:
        raise ModelMismatchError(f"{what} holds PCA basis coefficients, and model {model.fingerprint[:12]} ships no "
                                 f"basis (only the installed built-ins with a learnt prior do)")
    basis, digest = found
    return BasisBRDF(basis, basis_coefficients(emb, basis, digest, name), name=name or "embedding",
                     device=getattr(model, "device", None))


def basis_components(model) -> int | None:
    """Components per channel of ``model``'s default basis embedding, or ``None`` (it
    ships no basis: its default is the latent)."""
    from brdfkit.methods.ipca.embedding import components_for, model_basis

    found = model_basis(model)
    return None if found is None else components_for(model.cfg.latent_dim, found[0])


def embedding_size(model):
    """What :func:`encode_table` makes of a table with ``model`` by default, for labels:
    ``"basis-39"`` (a basis embedding's numbers) or the latent size (an ``int``)."""
    k = basis_components(model)
    return int(model.cfg.latent_dim) if k is None else f"basis-{3 * k}"
