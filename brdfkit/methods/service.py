"""What a model serves: the one answer to "what does this ``-m`` value give?".

A *model* (what ``-m`` takes) is a built-in's name or a file (``docs/models.md``).
:func:`serves` resolves it once and says what it serves, as a :class:`Service`: its parts'
files, the embedding kinds it decodes (:data:`brdfkit.embeddings.registry.KINDS`) at which
sizes and with how many residual members, and the sparse-reconstruction methods it runs
(:data:`brdfkit.methods.METHODS`). Everything that takes a model asks it, so that a route
that is listed is a route that runs: ``brdfkit models`` lists each built-in's service
(:func:`installed_services`), ``brdfkit encode`` takes its kind and file from it
(:meth:`Service.kind_for`, :meth:`Service.path`; :func:`brdfkit.embeddings.choose_decoder`),
``decode`` the file of an embedding's kind, ``sparse`` its method
(:meth:`Service.method_for`; :func:`brdfkit.methods.choice.choose`), and each refusal says
what the model does serve.

What it reads is the headers alone (:attr:`brdfkit.embeddings.kind.EmbeddingKind.offer`):
no weights are loaded and no torch imported to say what a model serves.

==================== ==========================================================================
a model's ...        comes from
==================== ==========================================================================
``files``            a built-in: its manifest's parts (:mod:`brdfkit.models.builtin`); a file:
                     the part its header names (:func:`brdfkit.models.parts.file_part`)
``kinds``, sizes     each kind of ``KINDS`` whose part it has, and what that file offers
``methods``          each method of ``METHODS`` whose part it has, ``--method auto``'s first:
                     the learnt prior, then the hypernetwork (:data:`AUTO_ORDER`)
==================== ==========================================================================

May import: what :mod:`brdfkit.methods` may, and :mod:`brdfkit.embeddings`' registry (the
same layer).
"""

from __future__ import annotations

import dataclasses
import functools
import os

from brdfkit.errors import InputError

__all__ = ["AUTO", "AUTO_ORDER", "Service", "serves", "default_service", "installed_services"]

AUTO = "auto"
"""The ``--method`` value that lets the model pick its method (:attr:`Service.default_method`)."""

AUTO_ORDER = ("prior", "hypernet")
"""The methods ``--method auto`` prefers, in order, before the others of ``METHODS``: the
learnt prior reconstructs sparse samples better than the paper's decoder
(``docs/notes/generalisation.md``), and the hypernetwork is the paper's method."""


@dataclasses.dataclass(frozen=True)
class Service:
    """What one model serves.

    Attributes
    ----------
    label
        The model as the user named it: a built-in's name, a file's path as given, or
        ``"NAME, the default built-in"``.
    bundle
        The built-in's name, or ``None`` for a file.
    files
        ``{part: path}`` in the part registry's order (:data:`brdfkit.models.parts.PARTS`):
        a built-in's parts as its manifest names them (checked against its digests when
        used, :meth:`path`), a file's one part. ``{}`` for a file whose header names no
        part (not safetensors, a pickle, a table, ...): each job then hands the file to
        the loader of the part it takes, which says what it is in one line.
    methods
        The sparse-reconstruction methods it runs (``sparse --method``), those whose part
        it has, ``--method auto``'s first. A method that takes no model (``nbrdf``) is
        served by none: it runs without ``-m``.

    And, read from its files' headers when first asked (:attr:`offers`; no weights
    loaded, no torch imported):

    kinds
        ``{kind: sizes}``: each embedding kind it decodes (``encode --kind``), in
        ``encode``'s order of preference (:data:`brdfkit.embeddings.registry.KINDS`), with
        the sizes (numbers per material, ascending) its file offers; a kind whose file
        offers no size is not served.
    default_kind
        The kind ``encode`` makes with no ``--kind`` and no ``--size`` (the first of
        :attr:`kinds`), or ``None``.
    default_sizes
        ``{kind: size}``: the size ``encode`` makes of each kind with no ``--size``.
    members
        ``{kind: members}``: the most decoders any size of the kind has (a residual file
        may hold several networks a size, among which ``encode`` chooses per material; 1
        for the others).
    """

    label: str
    bundle: str | None
    files: dict
    methods: tuple

    @functools.cached_property
    def offers(self) -> dict:
        """``{kind: Offer}`` (:class:`brdfkit.embeddings.kind.Offer`) of each kind it decodes,
        read from its files' headers when first asked (a sparse reconstruction reads none)."""
        from brdfkit.embeddings.registry import KINDS

        offers = {k.name: k.offered(self.files[k.part]) for k in KINDS.values() if k.part in self.files}
        return {k: o for k, o in offers.items() if o.sizes}

    # The four below are documented in the class's text: a docstring would document them twice.
    @property
    def kinds(self) -> dict:
        return {k: tuple(o.sizes) for k, o in self.offers.items()}

    @property
    def default_kind(self) -> str | None:
        return next(iter(self.offers), None)

    @property
    def default_sizes(self) -> dict:
        return {k: o.default_size for k, o in self.offers.items()}

    @property
    def members(self) -> dict:
        return {k: o.members for k, o in self.offers.items()}

    @property
    def name(self) -> str:
        """Its short name in messages and decoders' labels: the built-in's, or the file's
        name without its folder."""
        return self.bundle or os.path.basename(self.label)

    @property
    def default_method(self) -> str | None:
        """The method ``sparse --method auto`` runs (the first of :attr:`methods`), or ``None``."""
        return self.methods[0] if self.methods else None

    def summary(self) -> str:
        """What it serves in one line (for ``brdfkit models`` and the refusals).

        Examples
        --------
        >>> from brdfkit.testing.examples import tiny_basis_file
        >>> serves(tiny_basis_file("tiny-basis.safetensors", components=3)).summary()
        'basis embeddings of 3, 6, 9 numbers; sparse --method ipca'
        """
        kinds = "; ".join(f"{k} embeddings of {_shown(s)} numbers" for k, s in self.kinds.items())
        methods = f"sparse --method {', '.join(self.methods)}" if self.methods else ""
        return "; ".join(x for x in (kinds, methods) if x) or "nothing brdfkit runs"

    def refusal(self, what: str) -> InputError:
        """The one-line :class:`InputError` of a route it does not serve: ``what`` it is
        not, and what it serves."""
        from brdfkit.errors import BrdfkitError

        try:
            return InputError(f"{what}; it serves {self.summary()}")
        except BrdfkitError:  # a file whose header its own format refuses: the refusal alone
            return InputError(what)

    def path(self, part: str) -> str:
        """The file of its part ``part``: a built-in's checked against its manifest's
        digest (:func:`brdfkit.models.builtin.resolve_part`), a file as it is.

        Raises
        ------
        InputError
            A model without that part (naming the built-ins that have one, or what the
            file is).
        FormatError
            A built-in's file that is not the one its manifest records.
        """
        from brdfkit.models.builtin import resolve_part
        from brdfkit.models.parts import get_part

        if self.bundle is not None:
            if part in self.files:
                return resolve_part(self.bundle, part)
            try:
                resolve_part(self.bundle, part)
            except InputError as e:  # its words: the built-ins that have the part
                raise self.refusal(str(e)) from None
        if not self.files or part in self.files:
            return self.label
        own = get_part(next(iter(self.files))).label
        raise self.refusal(f"{self.label}: a {own} file, not a {get_part(part).label}")

    def kind_for(self, kind: str | None = None, size: int | None = None) -> str:
        """The kind ``encode --kind KIND --size SIZE`` makes with it: ``kind`` when it
        serves it (at ``size``), else, with no ``kind``, the first it serves at ``size``
        (at its default size, with no ``size``).

        Raises
        ------
        InputError
            An unknown kind, a kind or size it does not serve (one line listing what it
            serves).
        """
        from brdfkit.embeddings.registry import KINDS, get_kind, kind_of_part

        if kind is not None:
            kind = get_kind(kind).name
        if not self.files:  # a file no header names: its loader says what it is
            return kind or kind_of_part(next(iter(self.files), "network")).name
        if kind is None:
            if not self.kinds:
                raise self.refusal(f"{self.label} decodes no embedding")
            kind = next((k for k, sizes in self.kinds.items() if size is None or size in sizes), None)
            if kind is None and len(self.kinds) > 1:
                raise self.refusal(f"--size {size}: {self.name} makes no embedding of {size} numbers")
            kind = kind or next(iter(self.kinds))  # its one kind's size refusal below
        part = KINDS[kind].part
        if kind not in self.kinds:
            if self.bundle is not None and part not in self.files:
                self.path(part)  # refused, naming the built-ins with the part
            if self.bundle is None and part not in self.files:
                raise self.refusal(f"{self.label}: a {next(iter(self.files))} file, not the {part} a {kind} "
                                   f"embedding needs (--kind {kind})")
            raise self.refusal(f"--kind {kind}: {self.label} decodes no {kind} embedding")
        if size is not None and size not in self.kinds[kind]:
            raise self.refusal(f"--size {size}: {kind} embeddings of {self.name} hold {_shown(self.kinds[kind])} "
                               f"numbers")
        return kind

    def method_for(self, method: str = AUTO) -> str:
        """The method ``sparse --method METHOD`` runs with it: its default for
        :data:`AUTO`, else ``method`` when it serves it.

        Raises
        ------
        InputError
            An unknown method, one it does not serve, or one that takes no model (one line).
        """
        from brdfkit.methods import get_method
        from brdfkit.models.parts import get_part

        if method == AUTO:
            if not self.files:
                return "hypernet"  # a file no header names: the hypernetwork's loader says what it is
            if self.default_method is None:
                own = get_part(next(iter(self.files))).label if self.bundle is None else "built-in"
                raise self.refusal(f"{self.label}: a {own} {'model' if self.bundle else 'file'}, which no "
                                   f"sparse-reconstruction method takes (a {own} decodes embeddings: `brdfkit "
                                   f"encode -m`)")
            return self.default_method
        m = get_method(method)
        if m.part is None:
            raise InputError(f"method {m.name!r} takes no model file, got {self.label}")
        if self.files and m.name not in self.methods:
            if self.bundle is not None:
                self.path(m.part)  # refused, naming the built-ins with the part
            own = get_part(next(iter(self.files))).label
            raise self.refusal(f"{self.label}: a {own} file, not the {get_part(m.part).label} --method {m.name} "
                               f"takes")
        return m.name

    def to_json(self) -> dict:
        """A JSON object of it (``brdfkit models --json``'s ``serves``)."""
        return {"kinds": {k: list(s) for k, s in self.kinds.items()}, "default_kind": self.default_kind,
                "default_sizes": dict(self.default_sizes), "members": dict(self.members),
                "methods": list(self.methods), "default_method": self.default_method}


def _shown(sizes) -> str:
    """Sizes for a message: all of them, or the first two and the last of a long run."""
    sizes = list(sizes)
    return f"{sizes[0]}, {sizes[1]}, ... {sizes[-1]}" if len(sizes) > 3 else ", ".join(map(str, sizes))


def _methods(parts) -> tuple:
    """The methods of ``METHODS`` that take one of ``parts``, :data:`AUTO_ORDER`'s first."""
    from brdfkit.methods import METHODS

    order = [m for m in AUTO_ORDER if m in METHODS] + [m for m in METHODS if m not in AUTO_ORDER]
    return tuple(m for m in order if METHODS[m].part in parts)


def _service(label: str, bundle: str | None, files: dict) -> Service:
    """The service of ``files`` (``{part: path}``)."""
    return Service(label, bundle, dict(files), _methods(files))


def _of_file(path: str) -> Service:
    from brdfkit.errors import FormatError
    from brdfkit.io.tensorfile import open_safetensors
    from brdfkit.models.parts import part_of_format

    try:
        with open_safetensors(path) as f:
            part = part_of_format((f.metadata() or {}).get("format"))
    except (FormatError, InputError, OSError):
        part = None
    return _service(path, None, {} if part is None else {part.name: path})


def _of_bundle(bundle, label: str) -> Service:
    from brdfkit.models.parts import PARTS

    return _service(label, bundle.name, {p: bundle.parts[p].path for p in PARTS if p in bundle.parts})


def serves(model: str | os.PathLike | None = None) -> Service:
    """What the model ``model`` serves: a built-in's name, a file (a value that exists,
    holds a path separator or ends with ``.safetensors``), or ``None``, the default
    built-in.

    Raises
    ------
    InputError
        No model given and no default built-in installed; neither a file nor an installed
        built-in (listing the built-ins).
    FormatError
        A part's file whose header its format refuses.

    Examples
    --------
    >>> from brdfkit.testing.examples import tiny_basis_file
    >>> s = serves(tiny_basis_file("tiny-basis.safetensors", components=4))
    >>> s.kinds, s.default_kind, s.default_sizes, s.methods, s.bundle
    ({'basis': (3, 6, 9, 12)}, 'basis', {'basis': 12}, ('ipca',), None)
    """
    from brdfkit.models.builtin import find_bundle, is_path_spec

    if model is None:
        found = default_service()
        if found is None:
            raise InputError("no model given: pass -m NAME or -m FILE, or set BRDFKIT_MODEL (no default built-in "
                             "model is installed; `brdfkit models` lists the built-in ones)")
        return found
    spec = os.fspath(model)
    if is_path_spec(spec):
        return _of_file(spec)
    return _of_bundle(find_bundle(spec), spec)


def default_service() -> Service | None:
    """What the default built-in serves (its :attr:`~Service.label` says it is the
    default), or ``None`` when none is installed."""
    from brdfkit.models.builtin import default_bundle

    found = default_bundle()
    return None if found is None else _of_bundle(found, f"{found.name}, the default built-in")


def installed_services() -> list[Service]:
    """What each installed built-in serves, in the manifest's order (the route matrix of
    ``tests/test_routes_*.py`` and ``brdfkit models`` list these)."""
    from brdfkit.models.builtin import installed_bundles

    return [_of_bundle(b, b.name) for b in installed_bundles()]
