"""A BRDF file of any kind, opened by one loader.

brdfkit's commands take BRDFs as files of these kinds (:data:`KINDS`):

=========== ============= ================================================================
suffix      kind          opened as
=========== ============= ================================================================
``.binary`` ``merl``      the dense table it holds (:func:`brdfkit.io.merl.read_merl`)
``.emb``    ``embedding`` the hyponet its latent decodes to, with the model that made it
                          (:class:`brdfkit.hypernet.neural_brdf.NeuralBRDF`)
=========== ============= ================================================================

:func:`read_table` gives any of them as a dense table (what ``plot``, ``metrics`` and
``compare`` score); :func:`load_brdf` as a renderable BRDF, which evaluates only the
directions a render queries (an embedding is never decoded to a dense table for a
render). An embedding's model comes from :class:`EmbeddingModel`: the one a command was
given (``-m``), else the built-in whose fingerprint the first embedding records, loaded
once for all the files of a command.

May import: the ground floor, :mod:`brdfkit.io`, :mod:`brdfkit.models`,
:mod:`brdfkit.hypernet` and :mod:`brdfkit.render.renderable`; torch only for an
embedding or a render.
"""

from __future__ import annotations

import os

import numpy as np

from brdfkit.errors import InputError

__all__ = ["KINDS", "brdf_kind", "EmbeddingModel", "read_table", "load_brdf"]

KINDS = {".binary": "merl", ".emb": "embedding"}
"""BRDF file suffixes and their kinds."""


def brdf_kind(path) -> str:
    """``"merl"`` or ``"embedding"`` from a file's suffix; InputError otherwise.

    Examples
    --------
    >>> brdf_kind("teflon.binary"), brdf_kind("mix.EMB")
    ('merl', 'embedding')
    """
    kind = KINDS.get(os.path.splitext(os.fspath(path))[1].lower())
    if kind is None:
        raise InputError(f"{os.fspath(path)}: not a BRDF file: not a MERL table (.binary) or an embedding (.emb)")
    return kind


class EmbeddingModel:
    """The model that ``.emb`` files decode with, loaded once, on first need.

    Parameters
    ----------
    model_path
        A model file or a built-in name (``-m``); ``None``: the installed built-in whose
        fingerprint the first embedding asked about records, else the default built-in
        (:func:`brdfkit.models.builtin.embedding_model`).
    model
        An already loaded :class:`~brdfkit.hypernet.loaded.NeuralModel` (instead of
        ``model_path``).
    device
        Torch device of the model (default: CUDA if available, else CPU).
    before_load
        Called once, before the model is loaded (the first use of torch): ``brdfkit
        metrics`` sizes torch's thread pool there.
    """

    def __init__(self, model_path=None, *, model=None, device=None, before_load=None):
        self.model_path = model_path
        self.device = device
        self._model = model
        self._before_load = before_load

    def for_file(self, emb_path):
        """The model of the embedding file ``emb_path`` (loaded on the first call)."""
        if self._model is None:
            from brdfkit.hypernet.model_file import load_model
            from brdfkit.models.builtin import embedding_model

            path = embedding_model(self.model_path, emb_path)
            if self._before_load is not None:
                hook, self._before_load = self._before_load, None
                hook()
            self._model = load_model(path, device=self.device)
        return self._model


def read_table(path, models: EmbeddingModel | None = None) -> np.ndarray:
    """A BRDF file as a dense table: float64 ``(90, 90, 180, 3)``, 1/sr, NaN where
    unmeasured; an embedding decoded by its model (``models``: default, the built-in it
    names)."""
    path = os.fspath(path)
    if brdf_kind(path) == "merl":
        from brdfkit.io.merl import read_merl

        return read_merl(path)
    from brdfkit.hypernet.neural_brdf import NeuralBRDF
    from brdfkit.io.embedding import read_embedding

    model = (models or EmbeddingModel()).for_file(path)
    return NeuralBRDF.from_embedding(model, read_embedding(path), path).to_table()


def load_brdf(path, model_path=None, device=None, model=None):
    """Open a BRDF file for rendering.

    Parameters
    ----------
    path
        A MERL ``.binary`` table or an embedding ``.emb``.
    model_path
        The model (``.safetensors``, or a built-in name) an ``.emb`` was made with;
        ``None``: the installed built-in whose fingerprint the embedding records, else
        the default built-in (:func:`brdfkit.models.builtin.model_for_embedding`).
    device
        Torch device (default: CUDA if available, else CPU).
    model
        An already loaded :class:`~brdfkit.hypernet.loaded.NeuralModel` (instead of
        ``model_path``), or an :class:`EmbeddingModel`.

    Returns
    -------
    brdfkit.render.renderable.TableBRDF or brdfkit.hypernet.neural_brdf.NeuralBRDF
        With ``name`` set to the file stem.
    """
    from brdfkit.atomic import check_input_file

    path = check_input_file(path)
    name = os.path.splitext(os.path.basename(path))[0]
    if brdf_kind(path) == "merl":
        from brdfkit.io.merl import read_merl
        from brdfkit.render.renderable import TableBRDF

        return TableBRDF(read_merl(path), name=name, device=device)
    from brdfkit.hypernet.neural_brdf import NeuralBRDF
    from brdfkit.io.embedding import read_embedding

    models = model if isinstance(model, EmbeddingModel) else EmbeddingModel(model_path, model=model, device=device)
    brdf = NeuralBRDF.from_embedding(models.for_file(path), read_embedding(path), name=path)
    brdf.name = name
    return brdf
