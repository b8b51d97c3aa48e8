"""What a reconstruction method is: :class:`Method` and the base of its options.

A method module (:mod:`.hypernet`, :mod:`.ipca`, :mod:`.nbrdf`) defines one
``METHOD = Method(...)``; :data:`brdfkit.methods.METHODS` lists them by name.
"""

from __future__ import annotations

import dataclasses
import os
from typing import Callable

from brdfkit.errors import InputError

__all__ = ["Method", "MethodOptions"]


@dataclasses.dataclass(frozen=True)
class MethodOptions:
    """Options of a method's reconstruction; a method subclasses this with its fields
    and their defaults (no fields: the method takes no option)."""

    def quick(self) -> "MethodOptions":
        """The same options made cheap, for an untimed warm-up call (default: as is)."""
        return self


@dataclasses.dataclass(frozen=True)
class Method:
    """One reconstruction method.

    Attributes
    ----------
    name
        Registry key (``--method`` on the command line).
    summary
        One line for help texts.
    model_kind
        What its model file is, for messages; ``""`` for a method that needs no model.
    part
        The part of a model it takes (a name of the part registry
        :data:`brdfkit.models.parts.PARTS`): a built-in's name resolves to that
        part's file, and a model file given to ``--method auto`` runs the method of its
        part; ``None`` for a method that takes no model.
    options
        Its :class:`MethodOptions` subclass (field defaults are the method's defaults).
    load_fn
        ``load_fn(path: str, device) -> model``; ``None`` when it needs no model.
    reconstruct_fn
        ``reconstruct_fn(samples, model, options, *, seed, device) -> (table, embedding
        or None)``: dense float64 ``(90, 90, 180, 3)`` in 1/sr, NaN on the cells it does
        not cover.
    compress_fn
        ``compress_fn(model, table, name) -> table``: the best reconstruction of a full
        table through the model (the compression benchmark); ``None`` when it has none.
    describe_fn
        ``describe_fn(model, path) -> (label, size, materials)``: a label, the code size
        (latent dimension, components) and the training materials' names of a model, for
        the compression benchmark.
    embedding_kind
        The kind of embedding its reconstruction returns beside the table (the kind
        ``brdfkit sparse --emb`` writes, :data:`brdfkit.embeddings.KINDS`); ``None`` for a
        method that makes none (``--emb`` is refused for it in one line).
    bench_option
        The ``brdfkit bench`` option (and ``brdfkit.bench.BenchConfig`` field) that
        names its model file; ``None`` when it needs no model, or takes it by
        ``--model-file METHOD=FILE`` only (a new method needs no new bench field).
    """

    name: str
    summary: str
    model_kind: str
    options: type = MethodOptions
    part: str | None = None
    load_fn: Callable | None = dataclasses.field(default=None, repr=False)
    reconstruct_fn: Callable | None = dataclasses.field(default=None, repr=False)
    compress_fn: Callable | None = dataclasses.field(default=None, repr=False)
    describe_fn: Callable | None = dataclasses.field(default=None, repr=False)
    embedding_kind: str | None = None
    bench_option: str | None = None

    @property
    def needs_model(self) -> bool:
        """Whether :meth:`reconstruct` needs a model file (``-m``)."""
        return self.load_fn is not None

    def load(self, path: str | os.PathLike | None, device=None):
        """Load the method's model file; ``None`` for methods that need none."""
        if not self.needs_model:
            if path is not None:
                raise InputError(f"method {self.name!r} takes no model file, got {os.fspath(path)}")
            return None
        if path is None:
            raise InputError(f"method {self.name!r} needs a {self.model_kind} (-m FILE)")
        return self.load_fn(os.fspath(path), device)

    def make_options(self, **given) -> MethodOptions:
        """The method's options: its defaults, replaced by the ``given`` ones that are
        not ``None``; :class:`InputError` naming any it does not take."""
        names = [f.name for f in dataclasses.fields(self.options)]
        unknown = sorted(set(given) - set(names))
        if unknown:
            takes = f"the option(s) {', '.join(names)}" if names else "no options"
            raise InputError(f"method {self.name!r} takes {takes}, got {', '.join(unknown)}")
        return self.options(**{k: v for k, v in given.items() if v is not None})

    def defaults(self) -> dict:
        """The default options, ``{name: value}``."""
        return dataclasses.asdict(self.options())

    def sparse(self, samples, model=None, *, seed: int = 0, device=None, options=None, **given):
        """``(table, embedding or None)`` from a sample set; see :meth:`reconstruct`."""
        if model is None or isinstance(model, (str, os.PathLike)):
            model = self.load(model, device)
        if options is None:
            options = self.make_options(**given)
        elif given:
            raise InputError(f"method {self.name!r}: give options either as an options object or by name")
        return self.reconstruct_fn(samples, model, options, seed=seed, device=device)

    def reconstruct(self, samples, model=None, *, seed: int = 0, device=None, options=None, **given):
        """Dense table from a sample set.

        Parameters
        ----------
        samples
            :class:`brdfkit.io.samples.SampleSet`, BRDF in 1/sr.
        model
            What :meth:`load` returned, or a path (loaded on the spot); required when
            :attr:`needs_model`, ``None`` otherwise.
        seed
            Drives any randomness (NBRDF's initial weights).
        device
            Torch device (default CUDA when available).
        options, **given
            A :attr:`options` object, or its fields by name (``None``: the default).

        Returns
        -------
        numpy.ndarray
            float64 ``(90, 90, 180, 3)``, 1/sr, ``>= 0``, NaN on the cells it does not
            cover.
        """
        return self.sparse(samples, model, seed=seed, device=device, options=options, **given)[0]
