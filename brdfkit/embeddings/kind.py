"""What an embedding kind is: :class:`EmbeddingKind`, one entry of
:data:`brdfkit.embeddings.registry.KINDS`."""

from __future__ import annotations

import dataclasses
import typing
from typing import Callable

__all__ = ["EmbeddingKind", "Offer"]


class Offer(typing.NamedTuple):
    """What a decoder file offers ``encode``, read from its header alone: the ``sizes``
    (numbers per material, ascending), the ``default_size`` and the most ``members`` any
    size has (a residual file may hold several networks a size; other kinds 1)."""

    sizes: tuple
    default_size: int
    members: int = 1


@dataclasses.dataclass(frozen=True)
class EmbeddingKind:
    """One kind of embedding: everything ``encode``, ``decode``, ``render``, ``metrics``,
    ``interpolate``, ``convert`` and the bench need of it.

    Attributes
    ----------
    name, summary
        Registry key (``brdfkit encode --kind``, the ``kind`` of an ``.emb``) and one line
        for help texts.
    part
        The name of the part of a model that decodes it, in the part registry
        (:data:`brdfkit.models.parts.PARTS`): a built-in name resolves to that part's
        file, a file is of this kind when its header says it is that part
        (:func:`brdfkit.models.parts.file_part`), and the decoder loads as that part
        loads (:meth:`load`).
    sizes
        ``sizes(obj) -> sizes``: the numbers per material it offers (ascending).
    default_size
        ``default_size(obj) -> int``.
    encode
        ``encode(obj, digest, table, *, source, size, steps, refine, max_seconds) ->
        Embedding``: a dense table (1/sr, NaN unmeasured) as an embedding.
    open
        ``open(obj, digest, emb, name, device) -> BRDF``: a renderable BRDF
        (``eval_dirs``, ``to_table``), after checking the embedding against the decoder.
    aliases
        Old names of the kind, still read from files and taken by ``--kind``.
    start
        What an embedding of the kind is before any refinement on renders, for messages
        (``"projection"``, ``"encoder pass"``; ``""``: not said).
    torch
        Its decoder runs in torch (the hypernetwork's): a command sizes torch's thread
        pool before loading one, and imports no torch for the other kinds.
    wall_clock
        Its refinement takes a wall-clock cap (``--max-seconds``); a kind whose
        refinement is counted in iterations alone refuses one.
    option_defaults
        ``{name: value}`` of the decode options an embedding of the kind may leave out
        and that are not 0 then (a residual's ``correction``: 1); any other option left
        out is 0 (:meth:`option`).
    offer
        ``offer(path) -> Offer``: what a file of its part offers, from its header alone
        (what :func:`brdfkit.methods.service.serves` lists without loading any weights;
        the loaded file's :attr:`sizes` and :attr:`default_size`, ``tests/test_service.py``).
        ``None``: the file is loaded to ask them (:meth:`offered`).
    """

    name: str
    summary: str
    part: str
    sizes: Callable = dataclasses.field(repr=False)
    default_size: Callable = dataclasses.field(repr=False)
    encode: Callable = dataclasses.field(repr=False)
    open: Callable = dataclasses.field(repr=False)
    aliases: tuple = ()
    start: str = ""
    torch: bool = False
    wall_clock: bool = False
    option_defaults: dict = dataclasses.field(default_factory=dict)
    offer: Callable | None = dataclasses.field(default=None, repr=False)

    def option(self, options: dict | None, name: str) -> float:
        """The value of decode option ``name`` in an embedding's ``options`` (``None``:
        none given), its default when left out.

        Examples
        --------
        >>> k = EmbeddingKind("k", "", "basis", None, None, None, None, option_defaults={"correction": 1.0})
        >>> k.option(None, "correction"), k.option({"correction.1": 1.0}, "correction.1"), k.option({}, "x")
        (1.0, 1.0, 0.0)
        """
        return float((options or {}).get(name, self.option_defaults.get(name, 0.0)))

    def load(self, path, device=None):
        """``(obj, digest)``: the decoder in the file ``path`` and the digest embeddings name
        it by, loaded as its part loads (:meth:`brdfkit.models.parts.Part.load`)."""
        from brdfkit.models.parts import get_part

        return get_part(self.part).load(path, device)

    def offered(self, path) -> Offer:
        """What the file ``path`` of its part offers: :attr:`offer`, else the loaded file's
        :attr:`sizes` and :attr:`default_size`."""
        if self.offer is not None:
            return self.offer(path)
        obj, _ = self.load(path)
        return Offer(tuple(self.sizes(obj)), int(self.default_size(obj)))
