"""A BRDF file of any kind, opened by one loader.

brdfkit's commands take BRDFs as files of these kinds (:data:`KINDS`):

=========== ============= ================================================================
suffix      kind          opened as
=========== ============= ================================================================
``.binary`` ``merl``      the dense table it holds (:func:`brdfkit.io.merl.read_merl`)
``.bsdf``   ``rgl``       an RGL file (Dupuy and Jakob 2018): for a render, evaluated as
                          Mitsuba 3 evaluates it, conditioned on the view
                          (:class:`brdfkit.render.measured.MeasuredBRDF`); as a table, at the
                          MERL grid's directions made reciprocal by the least-squares
                          rule (:func:`brdfkit.io.rgl_bsdf.read_bsdf_table`)
``.emb``    ``embedding`` the hyponet its latent decodes to, with the model that made it
                          (:class:`brdfkit.hypernet.neural_brdf.NeuralBRDF`), or for a
                          basis embedding the closed form of the basis that model ships
                          (:func:`brdfkit.methods.embedding.embedding_brdf`)
=========== ============= ================================================================

:func:`read_table` gives any of them as a dense table (what ``plot``, ``metrics`` and
``compare`` score); :func:`load_brdf` as a renderable BRDF, which evaluates only the
directions a render queries (an embedding is never decoded to a dense table for a
render, nor is an RGL file, which a table would make reciprocal). An embedding's model comes from :class:`EmbeddingModel`: the one a command was
given (``-m``), else the built-in whose fingerprint the first embedding records, loaded
once for all the files of a command.

May import: the ground floor, :mod:`brdfkit.io`, :mod:`brdfkit.models`,
:mod:`brdfkit.hypernet`, :mod:`brdfkit.methods.embedding`, :mod:`brdfkit.render.renderable` and
:mod:`brdfkit.render.measured`;
torch only for an embedding or a render.
"""

from __future__ import annotations

import os

import numpy as np

from brdfkit.errors import InputError

__all__ = ["KINDS", "TABLE_KINDS", "OUTPUT_KINDS", "brdf_kind", "EmbeddingModel", "read_table", "load_brdf", "convert"]

KINDS = {".binary": "merl", ".bsdf": "rgl", ".emb": "embedding"}
"""BRDF file suffixes and their kinds."""
TABLE_KINDS = ("merl", "rgl")
"""The kinds that hold a table (read without a model)."""


def brdf_kind(path) -> str:
    """``"merl"``, ``"rgl"`` or ``"embedding"`` from a file's suffix; InputError otherwise.

    Examples
    --------
    >>> brdf_kind("teflon.binary"), brdf_kind("mix.EMB"), brdf_kind("satin_gold_rgb.bsdf")
    ('merl', 'embedding', 'rgl')
    """
    kind = KINDS.get(os.path.splitext(os.fspath(path))[1].lower())
    if kind is None:
        raise InputError(f"{os.fspath(path)}: not a BRDF file: not a MERL table (.binary), an RGL file "
                         f"(.bsdf) or an embedding (.emb)")
    return kind


def _read_table_file(path, kind: str) -> np.ndarray:
    """The table of a ``merl`` or ``rgl`` file."""
    if kind == "merl":
        from brdfkit.io.merl import read_merl

        return read_merl(path)
    from brdfkit.io.rgl_bsdf import read_bsdf_table

    return read_bsdf_table(path)


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
    unmeasured; an RGL ``.bsdf`` evaluated at the grid's directions; an embedding decoded
    by its model (``models``: default, the built-in it names)."""
    path = os.fspath(path)
    kind = brdf_kind(path)
    if kind in TABLE_KINDS:
        return _read_table_file(path, kind)
    from brdfkit.io.embedding import read_embedding

    from brdfkit.methods.embedding import embedding_brdf

    model = (models or EmbeddingModel()).for_file(path)
    return embedding_brdf(model, read_embedding(path), path).to_table()


def load_brdf(path, model_path=None, device=None, model=None):
    """Open a BRDF file for rendering.

    Parameters
    ----------
    path
        A MERL ``.binary`` table, an RGL ``.bsdf`` file (evaluated straight from the
        file, conditioned on the view as Mitsuba 3 does) or an embedding ``.emb``.
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
    TableBRDF, MeasuredBRDF or NeuralBRDF
        (:mod:`brdfkit.render.renderable`, :mod:`brdfkit.render.measured`,
        :mod:`brdfkit.hypernet.neural_brdf`), with ``name`` set to the file stem.
    """
    from brdfkit.atomic import check_input_file

    path = check_input_file(path)
    name = os.path.splitext(os.path.basename(path))[0]
    kind = brdf_kind(path)
    if kind == "rgl":
        from brdfkit.io.rgl_bsdf import read_bsdf
        from brdfkit.render.measured import MeasuredBRDF

        return MeasuredBRDF(read_bsdf(path), name=name)
    if kind == "merl":
        from brdfkit.render.renderable import TableBRDF

        return TableBRDF(_read_table_file(path, kind), name=name, device=device)
    from brdfkit.io.embedding import read_embedding
    from brdfkit.methods.embedding import embedding_brdf

    models = model if isinstance(model, EmbeddingModel) else EmbeddingModel(model_path, model=model, device=device)
    brdf = embedding_brdf(models.for_file(path), read_embedding(path), name=path)
    brdf.name = name
    return brdf


OUTPUT_KINDS = {".binary": "merl", ".bsdf": "rgl"}
"""What :func:`convert` writes (an ``.emb`` is made by ``brdfkit encode``)."""


def convert(src, dst, *, models: EmbeddingModel | None = None, settings=None, spectral: bool = False,
            description: str | None = None, reciprocity: str = "least-squares") -> dict:
    """Convert a BRDF file into a MERL ``.binary`` table or an RGL ``.bsdf`` file.

    Parameters
    ----------
    src
        Any BRDF file (:data:`KINDS`): read as its dense table (:func:`read_table`).
    dst
        The output, ``.binary`` or ``.bsdf`` (:data:`OUTPUT_KINDS`), written atomically;
        never one of the inputs.
    models
        The model ``.emb`` inputs decode with (default: the built-in the embedding names).
    settings
        :class:`brdfkit.io.rgl.fit.FitSettings` of a ``.bsdf`` output (default: its
        defaults).
    spectral
        Write a spectral ``.bsdf`` (pbrt-v4, Mitsuba's spectral variants) instead of RGB
        (Mitsuba's RGB variants); :func:`brdfkit.io.rgl_bsdf.rgb_to_spectra`.
    description
        The ``.bsdf`` file's description (default: brdfkit and the input's name).
    reciprocity
        How a ``.bsdf`` input's two conditionings become the one value per reciprocal
        pair a table holds (:data:`brdfkit.io.rgl_bsdf.RULES`; default ``least-squares``).

    Returns
    -------
    dict
        ``{"input_kind", "output_kind", "bytes", "read_s", "write_s"}``, and for a
        ``.bsdf`` input ``"non_reciprocity"`` (the log RMS between its two
        conditionings, :meth:`brdfkit.io.rgl_bsdf.RglBsdf.reciprocal_table`) and
        ``"reciprocity"``, the rule applied.

    Raises
    ------
    InputError
        An output of another suffix, one equal to an input, options of a ``.bsdf``
        output for a ``.binary`` one, or a bad input (its reader's one-line error).
    """
    import time

    from brdfkit.atomic import check_input_file, refuse_overwrite_of_inputs

    src, dst = os.fspath(src), os.fspath(dst)
    out_kind = OUTPUT_KINDS.get(os.path.splitext(dst)[1].lower())
    if out_kind is None:
        raise InputError(f"{dst}: convert writes a MERL table (.binary) or an RGL file (.bsdf); "
                         f"an embedding (.emb) is made by `brdfkit encode`")
    if out_kind == "merl" and (spectral or settings is not None):
        raise InputError(f"{dst}: the resolution and colour options apply to an RGL .bsdf output, "
                         f"not to a MERL table")
    in_kind = brdf_kind(src)
    refuse_overwrite_of_inputs(dst, [src, getattr(models, "model_path", None)])
    if settings is not None:
        settings.check()
    check_input_file(src)
    t0 = time.perf_counter()
    extra = {}
    if in_kind == "rgl":
        from brdfkit.io.rgl_bsdf import read_bsdf

        table, asymmetry = read_bsdf(src).reciprocal_table(reciprocity)
        extra = {"non_reciprocity": asymmetry, "reciprocity": reciprocity}
    else:
        table = read_table(src, models)
    t1 = time.perf_counter()
    if out_kind == "merl":
        from brdfkit.io.merl import write_merl

        write_merl(dst, table)
    else:
        from brdfkit.io.rgl_bsdf import FitSettings, write_bsdf

        if description is None:
            description = f"brdfkit: {os.path.basename(src)}"
        write_bsdf(dst, table, settings or FitSettings(), spectral=spectral, description=description)
    return {"input_kind": in_kind, "output_kind": out_kind, "bytes": os.path.getsize(dst),
            "read_s": t1 - t0, "write_s": time.perf_counter() - t1, **extra}
