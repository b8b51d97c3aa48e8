"""What ``brdfkit bench`` runs: :class:`BenchConfig` and the seed of each draw."""

from __future__ import annotations

import dataclasses
import os

from brdfkit.atomic import check_input_file
from brdfkit.errors import InputError
from brdfkit.acquisition.protocol import SAMPLINGS, draw_seed

__all__ = ["BenchConfig", "DEFAULT_N", "DEFAULT_METHODS", "DEFAULT_RESOLUTION", "METRICS", "sample_seed",
           "default_methods", "basis_components", "compression_entry"]

DEFAULT_N = (40, 160, 400, 2000, 4000)
DEFAULT_METHODS = ("hypernet", "ipca", "nbrdf")
"""The methods run when none are named and no learnt prior is at hand (:func:`default_methods`)."""
DEFAULT_RESOLUTION = 128
"""Render size for the image metrics: 128 x 128 keeps a reference-scene render near a
second of CPU time per reconstruction (the scene's own 256 takes four times as long)."""


METRICS = ("psnr", "delta_e", "ssim", "log_rmse")


@dataclasses.dataclass
class BenchConfig:
    """What to run (the options of ``brdfkit bench``).

    Attributes
    ----------
    output
        Output folder.
    data, test_list
        Folder of MERL tables for the sparse benchmark and an optional file of material
        names (one a line, ``#`` comments) selecting the test materials; ``data=None``
        skips the sparse benchmark.
    model, ipca
        Hypernetwork model and PCA basis files (needed by the methods that use them).
    models
        Model files of any method by name, ``{method: path}`` (``--model-file
        NAME=FILE``); a method's ``bench_option`` field (``model``, ``ipca``) is used
        when it has no entry here (``prior`` has none: ``--model-file prior=FILE``).

    Every model file may be given as a built-in model's name instead (``-m
    merl80-l40``): :meth:`resolved` replaces it by the file of the part that method takes
    (the hypernetwork, the PCA basis, the learnt prior).
    n, seeds, first_seed, methods
        Sample counts, number of draws per (material, N) (seeds ``first_seed ..
        first_seed + seeds - 1``; a later run with other seeds can be merged, see
        :func:`merge_results`), methods (``None``: :func:`default_methods`, the learnt
        prior first when ``model`` names a built-in that has one; :meth:`resolved`
        fills them in).
    sampling, plan_model, plan_design
        The samplings every (material, N, seed) is run with (:data:`brdfkit.acquisition.protocol.SAMPLINGS`:
        ``uniform``, ``planned``); for ``planned``, the fit to plan for (a built-in's learnt
        prior, a learnt-prior or basis file; default: ``ipca``'s basis) and the design (:data:`brdfkit.acquisition.designs.DESIGNS`).
    compression_models, compression_data
        What to test on encode -> decode of every table in ``compression_data`` (plus the
        PCA basis, when ``ipca`` is given): ``MODEL[:KIND[-SIZE]]`` entries
        (:func:`compression_entry`: ``merl80-l40``, ``merl80-l40:basis-21``,
        ``merl80-l40:hypernet``, a basis or hypernetwork file), each encoded as ``brdfkit
        encode -m MODEL --kind KIND --size SIZE`` does; ``basis-K`` names the ``ipca``
        basis's ``K`` leading components (its projection, ``3 K`` numbers; ``pca-K``
        before).
    scenes
        The suite scenes the image metrics are taken in (:mod:`brdfkit.render.scene_suite`);
        with more than one, ``psnr``, ``delta_e`` and ``ssim`` are their means and each
        record holds every scene's under ``scenes``.
    resolution
        Render size (pixels square) for the image metrics.
    jobs, threads
        Worker processes (one material at a time each) and torch threads per process
        (default: torch's own choice with one process, ``cpu_count // jobs`` otherwise).
    device
        Torch device (``None``: CUDA when present).
    options
        Method options, ``{method: {option: value}}`` (options not given, or ``None``:
        the method's defaults; the fields of its options dataclass, see
        :mod:`brdfkit.methods`).
    group_by_prefix
        Also summarise per material family, the family being the name up to its first
        ``-`` (e.g. ``merl-`` / ``rgl-`` prefixed file names).
    cache
        Folder of cached reference renders (default ``output/cache``).
    """

    output: str
    data: str | None = None
    test_list: str | None = None
    model: str | None = None
    ipca: str | None = None
    models: dict = dataclasses.field(default_factory=dict)
    n: tuple = DEFAULT_N
    seeds: int = 3
    first_seed: int = 0
    methods: tuple | None = None
    sampling: tuple = ("uniform",)
    plan_model: str | None = None
    plan_design: str = "render"
    compression_models: tuple = ()
    compression_data: str | None = None
    scenes: tuple = ("reference",)
    resolution: int = DEFAULT_RESOLUTION
    jobs: int = 1
    threads: int | None = None
    device: str | None = None
    options: dict = dataclasses.field(default_factory=dict)
    group_by_prefix: bool = False
    cache: str | None = None
    command: str = ""

    def model_file(self, method: str) -> str | None:
        """The model file of a method: :attr:`models`, else the field its
        ``bench_option`` names."""
        from brdfkit.methods import get_method

        option = get_method(method).bench_option
        return self.models.get(method) or (getattr(self, option) if option else None)

    def plan_basis(self) -> str | None:
        """The PCA basis planned samples are planned for: :attr:`plan_model`, else the
        ``ipca`` method's basis."""
        return self.plan_model or self.model_file("ipca")

    def resolved(self) -> "BenchConfig":
        """This configuration with its default methods filled in
        (:meth:`with_default_methods`) and the built-in names among its model files replaced by
        the files (:func:`brdfkit.methods.choice.resolve_for`: each method's part of
        the built-in, checked against the manifest); paths stay as given. :func:`run_bench`
        runs and records the resolved one.

        Raises
        ------
        InputError
            An unknown name, or a built-in without the part a method takes.
        """
        from brdfkit.methods import METHODS
        from brdfkit.methods.choice import resolve_for

        cfg = self.with_default_methods()
        fields = {m.bench_option: name for name, m in METHODS.items() if m.bench_option}
        return dataclasses.replace(
            cfg, **{f: resolve_for(name, getattr(cfg, f)) for f, name in fields.items() if getattr(cfg, f)},
            models={m: resolve_for(m, p) if p else p for m, p in cfg.models.items()},
            plan_model=_plan_file(cfg.plan_model) if cfg.plan_model else None,
            compression_models=tuple(_basis_spelling(p) if basis_components(p) else _resolve_compressor(p, cfg.device)
                                     for p in cfg.compression_models))

    def recorded(self, resolved: "BenchConfig") -> tuple[dict, dict]:
        """What ``bench.json`` records of a run of this configuration (as given, its
        default methods filled in) that ran as ``resolved`` (:meth:`resolved`): ``(config,
        parts)``. ``config`` is ``resolved`` with each built-in named as it was given
        (``merl80-l40``, not the file it resolved to, which lies elsewhere on every machine;
        a compression entry ``merl80-l40:residual-39``, the kind and size that ran); a path
        stays as given. ``parts`` is ``{built-in: {part: digest}}`` of the parts those
        names resolved to, by the digests their manifest records: what made the figures."""
        from brdfkit.models.builtin import installed_bundles, is_path_spec

        bundles = {b.name: b for b in installed_bundles()}
        parts: dict = {}

        def named(given, ran):
            if given is None or is_path_spec(given) or given not in bundles:
                return ran
            real = os.path.realpath(ran)
            for part, p in bundles[given].parts.items():
                if os.path.realpath(p.path) == real:
                    parts.setdefault(given, {})[part] = p.digest
            return given

        def entry(given, ran):  # a compression entry MODEL[:KIND[-SIZE]] as MODEL:KIND-SIZE
            if basis_components(given):
                return ran
            path, sep, what = ran.rpartition(":")
            return f"{named(compression_entry(given)[0], path)}{sep}{what}"

        from brdfkit.methods import METHODS

        fields = {m.bench_option for m in METHODS.values() if m.bench_option}
        out = dataclasses.replace(
            resolved, **{f: named(getattr(self, f), getattr(resolved, f)) for f in fields if getattr(resolved, f)},
            models={m: named(self.models.get(m), p) if p else p for m, p in resolved.models.items()},
            plan_model=named(self.plan_model, resolved.plan_model) if resolved.plan_model else None,
            compression_models=tuple(entry(g, r) for g, r in zip(self.compression_models, resolved.compression_models)))
        return dataclasses.asdict(out), dict(sorted(parts.items()))

    def with_default_methods(self) -> "BenchConfig":
        """This configuration with ``methods=None`` replaced by :func:`default_methods`
        (and, when that adds the learnt prior of the built-in ``-m``, ``models["prior"]``
        and, unless given, ``ipca`` the built-in's name); itself when methods are given."""
        if self.methods is not None:
            return self
        methods, prior = default_methods(self.model, self.models.get("prior"))
        models = {**self.models, "prior": prior} if prior else self.models
        # A built-in -m with a learnt prior ships its PCA basis: the default ipca needs
        # no --ipca then (the basis the prior is fitted with, as `--ipca NAME` takes it).
        ipca = self.ipca or (self.model if prior and prior == self.model else None)
        return dataclasses.replace(self, methods=methods, models=models, ipca=ipca)

    def compressors(self) -> list:
        """The compression benchmark's entries: ``("embedding", (path, kind, size))`` for
        each ``MODEL:KIND-SIZE`` of :attr:`compression_models` (resolved,
        :func:`compression_entry`), ``("basis", K)`` for its ``basis-K`` entries, then
        ``("method", (method, model file))`` for every method that can compress and whose
        model file is given (the PCA basis, a learnt prior: the projection on their basis)."""
        from brdfkit.methods import METHODS

        if not self.compression_models:
            return []
        named = [("basis", basis_components(p)) if basis_components(p) else ("embedding", compression_entry(p))
                 for p in self.compression_models]
        return named + [("method", (m, self.model_file(name))) for name, m in METHODS.items()
                        if m.compress_fn is not None and self.model_file(name)]

    def method_options(self, method: str):
        """The options object of a method: its defaults and :attr:`options`."""
        from brdfkit.methods import get_method

        return get_method(method).make_options(**self.options.get(method, {}))

    def seed_list(self) -> list[int]:
        return list(range(self.first_seed, self.first_seed + self.seeds))

    def validate(self) -> None:
        """:class:`InputError` for a configuration that cannot run."""
        from brdfkit.methods import get_method

        if self.methods is None:
            return self.with_default_methods().validate()
        if self.data is None and not self.compression_models:
            raise InputError("nothing to run: give --data (sparse benchmark) and/or "
                             "--compression-models with --compression-data")
        if self.data is not None:
            if not self.methods:
                raise InputError("--methods: no method given")
            for m in self.methods:
                get_method(m)
            if len(set(self.methods)) != len(self.methods):
                raise InputError(f"--methods: a method is named twice ({','.join(self.methods)})")
            if not self.n or any(int(k) < 1 for k in self.n):
                raise InputError(f"--n: sample counts must be positive integers, got {self.n}")
            if self.seeds < 1:
                raise InputError(f"--seeds must be at least 1, got {self.seeds}")
            if self.first_seed < 0:
                raise InputError(f"--first-seed must be at least 0, got {self.first_seed}")
            if not self.sampling:
                raise InputError("--sampling: no sampling given")
            for s in self.sampling:
                if s not in SAMPLINGS:
                    raise InputError(f"--sampling: unknown sampling {s!r}; known: {', '.join(SAMPLINGS)}")
            if len(set(self.sampling)) != len(self.sampling):
                raise InputError(f"--sampling: a sampling is named twice ({','.join(self.sampling)})")
            if "planned" in self.sampling:
                from brdfkit.acquisition.designs import DESIGNS

                if not self.plan_basis():
                    raise InputError("--sampling planned needs the PCA basis to plan for: --plan-model NAME|FILE "
                                     "(or --ipca, whose basis it takes)")
                if self.plan_design not in DESIGNS:
                    raise InputError(f"--plan-design: unknown design {self.plan_design!r}; known: "
                                     f"{', '.join(DESIGNS)}")
            for m in self.methods:
                method = get_method(m)
                if method.needs_model and not self.model_file(m):
                    flag = f"--{method.bench_option} FILE" if method.bench_option else f"--model-file {m}=FILE"
                    raise InputError(f"method {m!r} needs {flag} ({method.model_kind})")
        for m in self.models:
            if not get_method(m).needs_model:
                raise InputError(f"--model-file: method {m!r} takes no model file")
        for m, opts in self.options.items():
            get_method(m).make_options(**opts)
        if any(basis_components(p) for p in self.compression_models) and not self.ipca:
            raise InputError("--compression-models basis-K takes the K leading components of --ipca BASIS: give --ipca")
        from brdfkit.render.scene_suite import scene_names

        if tuple(scene_names(",".join(self.scenes))) != tuple(self.scenes):
            raise InputError(f"--scenes: {','.join(self.scenes)} names a scene twice")
        if self.compression_models and not self.compression_data:
            raise InputError("--compression-models needs --compression-data DIR")
        if self.compression_data and not self.compression_models:
            raise InputError("--compression-data needs --compression-models")
        if self.resolution < 7:
            raise InputError(f"--resolution must be at least 7 (the SSIM window), got {self.resolution}")
        if self.jobs < 1:
            raise InputError(f"--jobs must be at least 1, got {self.jobs}")
        if self.threads is not None and self.threads < 1:
            raise InputError(f"--threads must be at least 1, got {self.threads}")
        models = [compression_entry(p)[0] for p in self.compression_models if not basis_components(p)]
        for f in [self.model, self.ipca, self.plan_model, self.test_list, *models, *self.models.values()]:
            if f:
                check_input_file(f)
        for d in (self.data, self.compression_data):
            if d is not None and not os.path.isdir(d):
                raise InputError(f"{d}: not a folder of MERL tables")



def compression_entry(spec) -> tuple[str, str | None, int | None]:
    """A ``--compression-models`` entry ``MODEL[:KIND[-SIZE]]`` as ``(model, kind, size)``
    (``None`` where not given: ``brdfkit encode``'s default).

    Examples
    --------
    >>> compression_entry("merl80-l40"), compression_entry("merl80-l40:basis-21")
    (('merl80-l40', None, None), ('merl80-l40', 'basis', 21))
    >>> compression_entry("m.safetensors:hypernet")
    ('m.safetensors', 'hypernet', None)
    """
    from brdfkit.embeddings import get_kind

    text = str(spec)
    model, sep, what = text.rpartition(":")
    if not sep or not model or os.sep in what:
        return text, None, None
    kind, dash, size = what.partition("-")
    get_kind(kind)
    if dash and not (size.isdigit() and int(size) > 0):
        raise InputError(f"--compression-models {text}: expected MODEL:KIND-SIZE with SIZE a whole number > 0")
    return model, kind, int(size) if dash else None


def _resolve_compressor(spec, device=None) -> str:
    """``PATH:KIND-SIZE`` of a ``--compression-models`` entry: the decoder file, kind and
    size ``brdfkit encode`` would use."""
    from brdfkit.embeddings import choose_decoder

    model, kind, size = compression_entry(spec)
    dec = choose_decoder(kind, model, "cpu", size)
    size = size or dec.default_size
    dec.check_size(size)
    return f"{dec.path}:{dec.kind}-{size}"


def basis_components(spec) -> int | None:
    """``K`` of a ``--compression-models`` entry ``basis-K`` (the projection onto the
    ``K`` leading components of the ``ipca`` basis; ``pca-K``, its old spelling, too),
    else ``None`` (``basis-merl.safetensors`` is a file); :class:`InputError` for
    ``basis-0`` and for ``pca-`` without a positive whole number.

    Examples
    --------
    >>> basis_components("basis-13"), basis_components("pca-13"), basis_components("merl80-l40:basis-21")
    (13, 13, None)
    """
    text = str(spec)
    prefix = next((p for p in ("basis-", "pca-") if text.startswith(p)), None)
    if prefix is None:
        return None
    k = text[len(prefix):]
    if prefix == "basis-" and not (k.isascii() and k.isdigit()):
        return None  # a model's name or file
    if not (k.isascii() and k.isdigit()) or int(k) < 1:
        raise InputError(f"--compression-models {text}: {prefix}K takes a whole number of components K >= 1")
    return int(k)


def _basis_spelling(spec) -> str:
    """A ``basis-K`` entry as it is; ``pca-K`` as ``basis-K``, with a note on stderr."""
    text = str(spec)
    if text.startswith("pca-"):
        from brdfkit.console import console

        console().print(f"note: {text} is now basis-{text[4:]}", soft_wrap=True, highlight=False)
        return f"basis-{text[4:]}"
    return text


def default_methods(model: str | None, prior: str | None = None) -> tuple[tuple, str | None]:
    """The methods ``brdfkit bench`` runs when ``--methods`` is not given, and the
    learnt prior they use.

    The learnt prior is ``brdfkit sparse``'s default method
    (:func:`brdfkit.methods.choice.choose`, ``--method auto``), so it leads the list
    whenever there is one to run: ``prior`` (``--model-file prior=...``) when given, else
    that of the built-in ``model`` names (``-m merl80-l40``) when ``choose`` picks it.
    A model *file* given as ``-m`` is the hypernetwork's and adds nothing.

    Returns
    -------
    tuple
        ``(methods, prior)``: ``("prior",) + DEFAULT_METHODS`` and the prior's model
        file or built-in name, or :data:`DEFAULT_METHODS` and ``None``.

    Raises
    ------
    InputError
        ``model`` is neither a file nor an installed built-in.
    """
    if not prior and model:
        from brdfkit.methods.choice import AUTO, choose
        from brdfkit.models.builtin import is_path_spec

        if not is_path_spec(model) and choose(AUTO, model).method == "prior":
            prior = model
    return (("prior",) + DEFAULT_METHODS, prior) if prior else (DEFAULT_METHODS, None)


def sample_seed(seed: int, n: int, name: str) -> int:
    """Seed of the uniform draw of ``n`` samples of material ``name`` for repetition
    ``seed``: :func:`brdfkit.acquisition.protocol.draw_seed`, the protocol ``brdfkit bench`` and
    ``benchmarks/eval_sparse.py`` share."""
    return draw_seed(seed, n, name)



def _plan_file(spec: str) -> str:
    """The file ``--plan-model`` names: a built-in's learnt prior (its basis and the
    likelihood the plan is for, :func:`brdfkit.acquisition.planning.plan_target`), a path (a PCA
    basis or a learnt prior) as it is."""
    from brdfkit.methods.choice import resolve_for
    from brdfkit.models.builtin import is_path_spec

    return os.fspath(spec) if is_path_spec(spec) else resolve_for("prior", spec)
