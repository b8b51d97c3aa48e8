"""A BRDF file of any type, opened by one loader.

brdfkit's commands take BRDFs as files of these types (:data:`FILE_TYPES`):

=========== ============= ================================================================
suffix      type          opened as
=========== ============= ================================================================
``.binary`` ``merl``      the dense table it holds (:func:`brdfkit.io.merl.read_merl`)
``.bsdf``   ``rgl``       an RGL file (Dupuy and Jakob 2018): for a render, evaluated as
                          Mitsuba 3 evaluates it, conditioned on the view
                          (:class:`brdfkit.render.measured.MeasuredBRDF`); as a table, at the
                          MERL grid's directions made reciprocal by the least-squares
                          rule (:func:`brdfkit.io.rgl_bsdf.read_bsdf_table`)
``.emb``    ``embedding`` what its decoder makes of it: a basis embedding's closed form
                          (:class:`brdfkit.basis.coefficients.BasisBRDF`), a latent's
                          hyponet (:class:`brdfkit.hypernet.neural_brdf.NeuralBRDF`);
                          :func:`brdfkit.embeddings.decoders.open_embedding`
=========== ============= ================================================================

:func:`read_table` gives any of them as a dense table (what ``plot``, ``metrics`` and
``compare`` score); :func:`load_brdf` as a renderable BRDF, which evaluates only the
directions a render queries (an embedding is never decoded to a dense table for a
render, nor is an RGL file, which a table would make reciprocal). An embedding's decoder
comes from :class:`EmbeddingDecoders`: the one a command was given (``-m``), else the
installed built-in part whose digest the embedding records, each loaded once for all
the files of a command.

May import: the ground floor, :mod:`brdfkit.io`, :mod:`brdfkit.models`,
:mod:`brdfkit.hypernet`, :mod:`brdfkit.embeddings`, :mod:`brdfkit.render.renderable` and
:mod:`brdfkit.render.measured`;
torch only for an embedding or a render.
"""

from __future__ import annotations

import os

import numpy as np

from brdfkit.errors import InputError

__all__ = ["FILE_TYPES", "TABLE_TYPES", "OUTPUT_TYPES", "file_type", "EmbeddingDecoders", "read_table", "load_brdf", "convert"]

FILE_TYPES = {".binary": "merl", ".bsdf": "rgl", ".emb": "embedding"}
"""BRDF file suffixes and their types."""
TABLE_TYPES = ("merl", "rgl")
"""The file types that hold a table (read without a model)."""


def file_type(path) -> str:
    """``"merl"``, ``"rgl"`` or ``"embedding"`` from a file's suffix; InputError otherwise.

    Examples
    --------
    >>> file_type("teflon.binary"), file_type("mix.EMB"), file_type("satin_gold_rgb.bsdf")
    ('merl', 'embedding', 'rgl')
    """
    ftype = FILE_TYPES.get(os.path.splitext(os.fspath(path))[1].lower())
    if ftype is None:
        raise InputError(f"{os.fspath(path)}: not a BRDF file: not a MERL table (.binary), an RGL file "
                         f"(.bsdf) or an embedding (.emb)")
    return ftype


def _read_table_file(path, ftype: str) -> np.ndarray:
    """The table of a ``merl`` or ``rgl`` file."""
    if ftype == "merl":
        from brdfkit.io.merl import read_merl

        return read_merl(path)
    from brdfkit.io.rgl_bsdf import read_bsdf_table

    return read_bsdf_table(path)


class EmbeddingDecoders:
    """The decoders ``.emb`` files decode with, each loaded once, on first need.

    Parameters
    ----------
    model_path
        A ``-m`` value (a built-in's name or a decoder file): each embedding takes the part
        of its kind it names (:func:`brdfkit.embeddings.decoders.decoder_for`); ``None``: the
        installed built-in part whose digest the embedding records.
    model
        An already loaded decoder (a :class:`~brdfkit.embeddings.decoders.Decoder`, or a
        :class:`~brdfkit.hypernet.loaded.LoadedNetwork` for latents), instead of ``model_path``.
    device
        Torch device of a hypernetwork (default: CUDA if available, else CPU).
    before_load
        Called once, before the first decoder that runs in torch is loaded (a hypernetwork's,
        :attr:`brdfkit.embeddings.kind.EmbeddingKind.torch`): ``brdfkit render`` and ``metrics``
        size torch's thread pool there, and import no torch for the other kinds.
    """

    def __init__(self, model_path=None, *, model=None, device=None, before_load=None):
        self.model_path = model_path
        self.device = device
        self._given = model
        self._before_load = before_load

    def decoder(self, emb, name: str = ""):
        """The :class:`~brdfkit.embeddings.decoders.Decoder` of embedding ``emb`` (checked)."""
        from brdfkit.embeddings import Decoder, decoder_for, get_kind

        given = self._given
        if given is not None and not isinstance(given, Decoder):  # a loaded hypernetwork
            given = Decoder.of_network(given)
        if given is not None and given.kind == emb.kind and given.digest == emb.decoder:
            return given
        if self._before_load is not None and get_kind(emb.kind).torch:
            hook, self._before_load = self._before_load, None
            hook()
        return decoder_for(emb, self.model_path, self.device, name)

    def open(self, path, name: str | None = None):
        """The renderable BRDF of the embedding file ``path`` (``eval_dirs``, ``to_table``)."""
        from brdfkit.io.embedding import read_embedding
        from brdfkit.embeddings import open_embedding

        emb = read_embedding(path)
        brdf = open_embedding(emb, self.decoder(emb, os.fspath(path)), os.fspath(path))  # messages name the file
        if name:
            brdf.name = name
        return brdf


def read_table(path, models: EmbeddingDecoders | None = None) -> np.ndarray:
    """A BRDF file as a dense table: float64 ``(90, 90, 180, 3)``, 1/sr, NaN where
    unmeasured; an RGL ``.bsdf`` evaluated at the grid's directions; an embedding decoded
    by its decoder (``models``: default, the built-in part whose digest it records)."""
    path = os.fspath(path)
    ftype = file_type(path)
    if ftype in TABLE_TYPES:
        return _read_table_file(path, ftype)
    return (models or EmbeddingDecoders()).open(path).to_table()


def load_brdf(path, model_path=None, device=None, model=None):
    """Open a BRDF file for rendering.

    Parameters
    ----------
    path
        A MERL ``.binary`` table, an RGL ``.bsdf`` file (evaluated straight from the
        file, conditioned on the view as Mitsuba 3 does) or an embedding ``.emb``.
    model_path
        The decoder (a built-in's name or a file) an ``.emb`` was made with; ``None``:
        the installed built-in part whose digest the embedding records.
    device
        Torch device (default: CUDA if available, else CPU).
    model
        An already loaded decoder (instead of ``model_path``), or an
        :class:`EmbeddingDecoders`.

    Returns
    -------
    TableBRDF, MeasuredBRDF, BasisBRDF or NeuralBRDF
        (:mod:`brdfkit.render.renderable`, :mod:`brdfkit.render.measured`,
        :mod:`brdfkit.basis.coefficients`, :mod:`brdfkit.hypernet.neural_brdf`), with
        ``name`` set to the file stem.
    """
    from brdfkit.atomic import check_input_file

    path = check_input_file(path)
    name = os.path.splitext(os.path.basename(path))[0]
    ftype = file_type(path)
    if ftype == "rgl":
        from brdfkit.io.rgl_bsdf import read_bsdf
        from brdfkit.render.measured import MeasuredBRDF

        return MeasuredBRDF(read_bsdf(path), name=name)
    if ftype == "merl":
        from brdfkit.render.renderable import TableBRDF

        return TableBRDF(_read_table_file(path, ftype), name=name, device=device)
    models = model if isinstance(model, EmbeddingDecoders) else EmbeddingDecoders(model_path, model=model, device=device)
    return models.open(path, name)


OUTPUT_TYPES = {".binary": "merl", ".bsdf": "rgl"}
"""What :func:`convert` writes (an ``.emb`` is made by ``brdfkit encode``)."""


def convert(src, dst, *, models: EmbeddingDecoders | None = None, settings=None, spectral: bool = False,
            description: str | None = None, reciprocity: str = "least-squares") -> dict:
    """Convert a BRDF file into a MERL ``.binary`` table or an RGL ``.bsdf`` file.

    Parameters
    ----------
    src
        Any BRDF file (:data:`FILE_TYPES`): read as its dense table (:func:`read_table`).
    dst
        The output, ``.binary`` or ``.bsdf`` (:data:`OUTPUT_TYPES`), written atomically;
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
        ``{"input_type", "output_type", "bytes", "read_s", "write_s"}``, and for a
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
    out_type = OUTPUT_TYPES.get(os.path.splitext(dst)[1].lower())
    if out_type is None:
        raise InputError(f"{dst}: convert writes a MERL table (.binary) or an RGL file (.bsdf); "
                         f"an embedding (.emb) is made by `brdfkit encode`")
    if out_type == "merl" and (spectral or settings is not None):
        raise InputError(f"{dst}: the resolution and colour options apply to an RGL .bsdf output, "
                         f"not to a MERL table")
    in_type = file_type(src)
    refuse_overwrite_of_inputs(dst, [src, getattr(models, "model_path", None)])
    if settings is not None:
        settings.check()
    check_input_file(src)
    t0 = time.perf_counter()
    extra = {}
    if in_type == "rgl":
        from brdfkit.io.rgl_bsdf import read_bsdf

        table, asymmetry = read_bsdf(src).reciprocal_table(reciprocity)
        extra = {"non_reciprocity": asymmetry, "reciprocity": reciprocity}
    else:
        table = read_table(src, models)
    t1 = time.perf_counter()
    if out_type == "merl":
        from brdfkit.io.merl import write_merl

        write_merl(dst, table)
    else:
        from brdfkit.io.rgl_bsdf import FitSettings, write_bsdf

        if description is None:
            description = f"brdfkit: {os.path.basename(src)}"
        write_bsdf(dst, table, settings or FitSettings(), spectral=spectral, description=description)
    return {"input_type": in_type, "output_type": out_type, "bytes": os.path.getsize(dst),
            "read_s": t1 - t0, "write_s": time.perf_counter() - t1, **extra}


def _register_with_mitsuba() -> None:
    """The Mitsuba plugin opens the files scenes name with :func:`load_brdf`."""
    from brdfkit.render.mitsuba3.bsdf import set_file_opener

    set_file_opener(load_brdf)


_register_with_mitsuba()
