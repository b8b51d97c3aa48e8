"""How ``encode`` picks its decoder, and how an embedding finds the one it needs.

A *decoder* is a loaded part of a model that turns an embedding's numbers into a BRDF
(:class:`Decoder`). :func:`choose_decoder` loads the kind and file ``encode`` uses, as
what the model serves says (:mod:`brdfkit.methods.service`); :func:`decoder_for` finds an
embedding's own, the part of its kind of the ``-m`` value given or the part whose digest
the embedding records among the installed built-ins
(:func:`brdfkit.models.builtin.find_by_digest`). Loaded decoders are kept per process.
Nothing here names a kind: each kind's entry in :data:`brdfkit.embeddings.registry.KINDS` says
what its part is and how it loads, encodes and opens.
"""

from __future__ import annotations

import dataclasses
import functools
import os

import numpy as np

from brdfkit.embeddings.registry import KINDS, get_kind, kind_of_part
from brdfkit.errors import InputError, ModelMismatchError

__all__ = ["Decoder", "load_decoder", "choose_decoder", "decoder_for", "open_embedding", "encode_with"]


@dataclasses.dataclass(frozen=True)
class Decoder:
    """A loaded decoder: its ``kind``, the loaded ``obj`` (a
    :class:`~brdfkit.basis.model.PcaBasis`, a :class:`~brdfkit.hypernet.loaded.LoadedNetwork`,
    a :class:`~brdfkit.residual.model.BasisResidual`), the ``digest`` embeddings name it by,
    its ``path`` and a ``label`` for messages."""

    kind: str
    obj: object
    digest: str
    path: str
    label: str

    @classmethod
    def of_network(cls, net) -> "Decoder":
        """The decoder of a hypernetwork loaded already
        (:class:`~brdfkit.hypernet.loaded.LoadedNetwork`)."""
        return cls(kind_of_part("network").name, net, net.digest, getattr(net, "path", ""), net.short_digest)

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
            raise InputError(f"--size {size}: {self.kind} embeddings of {self.label} hold {shown or 'no'} numbers")


@functools.lru_cache(maxsize=4)
def _loaded(kind: str, path: str, stamp: tuple, device: str, label: str) -> Decoder:
    obj, digest = KINDS[kind].load(path, None if device == "auto" else device)
    return Decoder(kind, obj, digest, path, label or os.path.basename(path))


def load_decoder(kind: str, path: str | os.PathLike, device=None, label: str = "") -> Decoder:
    """The decoder of ``kind`` in the file ``path``, loaded once per process while the file
    keeps its size and time; ``label`` names it in messages (default: the file's name)."""
    from brdfkit.atomic import check_input_file

    path = os.path.abspath(check_input_file(path))
    st = os.stat(path)
    return _loaded(get_kind(kind).name, path, (st.st_size, st.st_mtime_ns), "auto" if device is None else str(device),
                   label)


def choose_decoder(kind: str | None, spec, device=None, size: int | None = None) -> Decoder:
    """The decoder ``brdfkit encode`` uses for ``--kind`` ``kind``, ``-m`` ``spec`` and
    ``--size`` ``size``: the kind and file that what the model serves gives
    (:meth:`brdfkit.methods.service.Service.kind_for` and
    :meth:`~brdfkit.methods.service.Service.path`), loaded.

    ``spec`` ``None`` means the default built-in. With no ``kind``, the first kind of
    :data:`KINDS` the model decodes at ``size`` (so a size one part does not offer falls
    back to the next); a given ``kind`` takes the part of that kind.

    Raises
    ------
    InputError
        No model given and none installed, an unknown name or kind, a kind or size the
        model does not serve (one line saying what it serves).
    """
    from brdfkit.methods.service import serves

    service = serves(spec)
    kind = service.kind_for(kind, size)
    return load_decoder(kind, service.path(KINDS[kind].part), device, service.bundle or "")


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
        from brdfkit.methods.service import serves

        path = serves(spec).path(kind.part)  # a model without that part: one line saying what it serves
    dec = load_decoder(kind.name, path, device)
    if dec.digest != emb.decoder:
        raise ModelMismatchError(f"{what} was made with {emb.kind} decoder {emb.decoder[:12]}, not with "
                                 f"{dec.label} ({dec.digest[:12]}); encode the material again with it")
    return dec


def open_embedding(emb, decoder: Decoder, name: str = ""):
    """The renderable BRDF (``eval_dirs``, ``to_table``) of ``emb`` with its decoder."""
    if decoder.kind != get_kind(emb.kind).name:
        raise ModelMismatchError(f"embedding {name or ''}: a {emb.kind} embedding, not a {decoder.kind} one")
    device = getattr(decoder.obj, "device", None)
    return KINDS[decoder.kind].open(decoder.obj, decoder.digest, emb, name, device)


def encode_with(decoder: Decoder, table: np.ndarray, *, source: str = "", size: int | None = None,
                steps: int | None = None, max_seconds: float | None = None, refine: bool = True):
    """A dense table as an embedding of ``decoder`` (see :func:`brdfkit.api.encode`).

    Raises
    ------
    InputError
        A size the decoder does not offer.
    """
    size = decoder.default_size if size is None else size
    decoder.check_size(size)
    if max_seconds is not None and not KINDS[decoder.kind].wall_clock:
        raise InputError(f"--max-seconds caps a hypernetwork latent's refinement; a {decoder.kind} embedding's is "
                         f"counted in iterations (--steps N)")
    return KINDS[decoder.kind].encode(decoder.obj, decoder.digest, table, source=source, size=size, steps=steps,
                                      max_seconds=max_seconds, refine=refine)
