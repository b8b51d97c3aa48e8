"""The kinds of embedding by name, and how an embedding finds the decoder it needs.

An embedding (:class:`brdfkit.io.embedding.Embedding`) is a material as ``size`` numbers of
one *kind*, decoded by one file, its *decoder*, which it names by SHA-256:

========== ==================================================== =====================
kind       what the numbers are                                 decoder
========== ==================================================== =====================
``basis``  coefficients of a PCA basis's leading components,     a basis file
           ``3 K`` numbers, refined on renders                   (:mod:`brdfkit.basis`)
           (:mod:`brdfkit.basis.coefficients`)
``latent`` a hypernetwork's latent (Gokbudak et al. 2024),       a hypernetwork model
           refined on renders (:mod:`brdfkit.hypernet`)          file
========== ==================================================== =====================

Each kind is one :class:`EmbeddingKind` in :data:`KINDS`, registered by name as
:data:`brdfkit.methods.METHODS` registers the reconstruction methods: it resolves a
``-m`` value to its decoder file, loads it, encodes a table and opens an embedding for
rendering. :func:`choose_decoder` picks the kind and file ``encode`` uses;
:func:`decoder_for` finds an embedding's own, by the ``-m`` value given or by the digest
the embedding records among the installed built-ins
(:func:`brdfkit.models.builtin.find_by_digest`). Loaded decoders are kept per process.

May import: what :mod:`brdfkit.methods` may, and :mod:`brdfkit.basis`.
"""

from __future__ import annotations

import dataclasses
import functools
import os
from typing import Callable

import numpy as np

from brdfkit.errors import InputError, ModelMismatchError

__all__ = ["Decoder", "EmbeddingKind", "KINDS", "get_kind", "choose_decoder", "decoder_for", "load_decoder",
           "open_embedding", "encode_with"]


@dataclasses.dataclass(frozen=True)
class Decoder:
    """A loaded decoder: its ``kind``, the loaded ``obj`` (a
    :class:`~brdfkit.basis.model.PcaBasis` or a :class:`~brdfkit.hypernet.loaded.NeuralModel`),
    the ``digest`` embeddings name it by, its ``path`` and a ``label`` for messages."""

    kind: str
    obj: object
    digest: str
    path: str
    label: str

    @classmethod
    def of_model(cls, model) -> "Decoder":
        """The latent decoder of a hypernetwork loaded already
        (:class:`~brdfkit.hypernet.loaded.NeuralModel`)."""
        return cls("latent", model, model.fingerprint, getattr(model, "path", ""), model.short_fingerprint)

    @property
    def sizes(self) -> tuple:
        """The sizes (numbers per material) its embeddings may have."""
        return tuple(get_kind(self.kind).sizes(self.obj))

    @property
    def default_size(self) -> int:
        """The size its embeddings have unless asked for another."""
        return int(get_kind(self.kind).default_size(self.obj))

    def check_size(self, size: int) -> None:
        """:class:`InputError` (one line listing the sizes it offers) for a size it does not offer."""
        sizes = self.sizes
        if size not in sizes:
            shown = f"{sizes[0]}, {sizes[1]}, ... {sizes[-1]}" if len(sizes) > 3 else ", ".join(map(str, sizes))
            raise InputError(f"--size {size}: {self.kind} embeddings of {self.label} hold {shown} numbers")


@dataclasses.dataclass(frozen=True)
class EmbeddingKind:
    """One kind of embedding.

    Attributes
    ----------
    name, summary
        Registry key (``brdfkit encode --kind``) and one line for help texts.
    resolve
        ``resolve(spec) -> path``: the decoder file a ``-m`` value names (a path as it
        is, a built-in's name its part of this kind; :class:`InputError` otherwise).
    load
        ``load(path, device) -> (obj, digest)``.
    sizes
        ``sizes(obj) -> sizes``: the numbers per material it offers.
    default_size
        ``default_size(obj) -> int``.
    encode
        ``encode(obj, digest, table, *, source, size, steps, max_seconds, refine) ->
        Embedding``.
    open
        ``open(obj, digest, emb, name, device) -> BRDF``: a renderable BRDF
        (``eval_dirs``, ``to_table``), after checking the embedding against the decoder.
    """

    name: str
    summary: str
    resolve: Callable = dataclasses.field(repr=False)
    load: Callable = dataclasses.field(repr=False)
    sizes: Callable = dataclasses.field(repr=False)
    default_size: Callable = dataclasses.field(repr=False)
    encode: Callable = dataclasses.field(repr=False)
    open: Callable = dataclasses.field(repr=False)


# -- basis embeddings


def _basis_resolve(spec):
    from brdfkit.models.builtin import resolve_basis

    return resolve_basis(spec)


def _basis_load(path, device):
    from brdfkit.basis.basis_file import load_basis
    from brdfkit.io.digest import cached_file_digest

    return load_basis(path), cached_file_digest(path)


def _basis_sizes(basis):
    from brdfkit.basis.coefficients import basis_sizes

    return basis_sizes(basis)


def _basis_default_size(basis):
    from brdfkit.basis.coefficients import DEFAULT_SIZE

    return min(DEFAULT_SIZE, 3 * basis.n_components)


def _basis_encode(basis, digest, table, *, source, size, steps, max_seconds, refine):
    from brdfkit.basis.coefficients import encode_coefficients

    return encode_coefficients(basis, table, digest=digest, size=size, source=source, steps=steps if refine else 0)


def _basis_open(basis, digest, emb, name, device):
    from brdfkit.basis.coefficients import BasisBRDF, check_coefficients

    return BasisBRDF(basis, check_coefficients(emb, basis, digest, name), name=name or "embedding", device=device)


# -- hypernetwork latents


def _latent_resolve(spec):
    from brdfkit.models.builtin import resolve_model

    return resolve_model(spec)


def _latent_load(path, device):
    from brdfkit.hypernet.model_file import load_model

    model = load_model(path, device=device)
    return model, model.fingerprint


def _latent_encode(model, digest, table, *, source, size, steps, max_seconds, refine):
    from brdfkit.hypernet.encoding import encode_table

    if not refine:
        return encode_table(model, table, source)
    from brdfkit.hypernet.refine_on_screen import DEFAULT_STEPS, compress_table
    from brdfkit.render.objective import ObjectiveConfig

    cfg = ObjectiveConfig(steps=DEFAULT_STEPS if steps is None else steps, max_seconds=max_seconds)
    return compress_table(model, table, cfg, source).embedding


def _latent_open(model, digest, emb, name, device):
    from brdfkit.hypernet.neural_brdf import NeuralBRDF

    return NeuralBRDF.from_embedding(model, emb, name)


KINDS: dict[str, EmbeddingKind] = {
    "basis": EmbeddingKind("basis", "coefficients of a PCA basis, refined on renders (3 numbers a component)",
                           _basis_resolve, _basis_load, _basis_sizes, _basis_default_size, _basis_encode,
                           _basis_open),
    "latent": EmbeddingKind("latent", "a hypernetwork's latent, refined on renders (Gokbudak et al. 2024)",
                            _latent_resolve, _latent_load, lambda m: (int(m.cfg.latent_dim),),
                            lambda m: int(m.cfg.latent_dim), _latent_encode, _latent_open),
}
"""The embedding kinds by name."""


def get_kind(name: str) -> EmbeddingKind:
    """The kind called ``name``; :class:`InputError` listing the known ones otherwise."""
    try:
        return KINDS[name]
    except (KeyError, TypeError):
        raise InputError(f"unknown embedding kind {name!r}; known: {', '.join(KINDS)}") from None


@functools.lru_cache(maxsize=4)
def _loaded(kind: str, path: str, stamp: tuple, device: str) -> Decoder:
    obj, digest = KINDS[kind].load(path, None if device == "auto" else device)
    return Decoder(kind, obj, digest, path, os.path.basename(path))


def load_decoder(kind: str, path: str | os.PathLike, device=None) -> Decoder:
    """The decoder of ``kind`` in the file ``path``, loaded once per process while the file
    keeps its size and time."""
    from brdfkit.atomic import check_input_file

    path = os.path.abspath(check_input_file(path))
    st = os.stat(path)
    return _loaded(get_kind(kind).name, path, (st.st_size, st.st_mtime_ns), "auto" if device is None else str(device))


def _file_kind(path: str) -> str:
    """The kind whose decoder a model file is, by the format its header records."""
    from brdfkit.methods.choice import file_method

    method = file_method(path)
    if method == "prior":
        raise InputError(f"{path}: a learnt-prior model file does not decode embeddings; pass its basis file or a "
                         f"built-in's name")
    return "basis" if method == "ipca" else "latent"


def choose_decoder(kind: str | None, spec, device=None) -> Decoder:
    """The decoder ``brdfkit encode`` uses for ``--kind`` ``kind`` and ``-m`` ``spec``.

    ``spec`` ``None`` means the default built-in. A built-in's name gives its basis unless
    ``kind`` is ``"latent"`` (a built-in without a basis: its hypernetwork); a file gives
    the kind its format says. A given ``kind`` takes the part of that kind.

    Raises
    ------
    InputError
        No model given and none installed, an unknown name or kind, a file of another kind
        than ``kind``, a built-in without the part ``kind`` needs.
    """
    from brdfkit.models.builtin import builtin_models, default_model, is_path_spec, read_manifest

    if kind is not None:
        get_kind(kind)
    if spec is None:
        entry = next((m for m in read_manifest().installed() if m.default), None)
        if entry is None or default_model() is None:
            raise InputError("no model given: pass -m NAME or -m FILE, or set BRDFKIT_MODEL (no default built-in "
                             "model is installed; `brdfkit models` lists the built-in ones)")
        spec = entry.name
    spec = os.fspath(spec)
    if is_path_spec(spec):
        found = _file_kind(spec)
        if kind is not None and kind != found:
            raise InputError(f"{spec}: a {found} decoder, not a {kind} one (--kind {kind})")
        return load_decoder(found, spec, device)
    if kind is None:
        entry = next((m for m in builtin_models() if m.name == spec), None)
        kind = "basis" if entry is not None and entry.basis else "latent"
    return load_decoder(kind, KINDS[kind].resolve(spec), device)


def decoder_for(emb, spec=None, device=None, name: str = "") -> Decoder:
    """The decoder of embedding ``emb``: the part of its kind that ``-m`` value ``spec``
    names, else the installed built-in part whose digest ``emb`` records.

    Raises
    ------
    InputError
        An unknown kind; no ``spec`` and no installed built-in with that digest.
    ModelMismatchError
        ``spec`` names a decoder of another digest.
    """
    from brdfkit.models.builtin import find_by_digest

    what = f"embedding {name}" if name else "embedding"
    kind = get_kind(emb.kind)
    if spec is None:
        path = find_by_digest(emb.decoder)
        if path is None:
            raise InputError(f"{what}: its {emb.kind} decoder {emb.decoder[:12]} is not among the installed built-in "
                             f"models; pass the file that made it with -m")
    else:
        path = kind.resolve(spec)
    dec = load_decoder(emb.kind, path, device)
    if dec.digest != emb.decoder:
        raise ModelMismatchError(f"{what} was made with {emb.kind} decoder {emb.decoder[:12]}, not with "
                                 f"{dec.label} ({dec.digest[:12]}); encode the material again with it")
    return dec


def open_embedding(emb, decoder: Decoder, name: str = ""):
    """The renderable BRDF (``eval_dirs``, ``to_table``) of ``emb`` with its decoder."""
    if decoder.kind != emb.kind:
        raise ModelMismatchError(f"embedding {name or ''}: a {emb.kind} embedding, not a {decoder.kind} one")
    device = getattr(decoder.obj, "device", None)
    return KINDS[emb.kind].open(decoder.obj, decoder.digest, emb, name, device)


def encode_with(decoder: Decoder, table: np.ndarray, *, source: str = "", size: int | None = None,
                steps: int | None = None, max_seconds: float | None = None, refine: bool = True):
    """A dense table as an embedding of ``decoder`` (see :func:`brdfkit.api.encode`).

    Raises
    ------
    InputError
        A size the decoder does not offer.
    """
    kind = KINDS[decoder.kind]
    size = decoder.default_size if size is None else size
    decoder.check_size(size)
    return kind.encode(decoder.obj, decoder.digest, table, source=source, size=size, steps=steps,
                       max_seconds=max_seconds, refine=refine)
