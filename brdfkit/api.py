"""The library interface: encode, decode, reconstruct from sparse samples, interpolate,
train, each the same job, with the same defaults and the same bytes, as the command of its
name::

    import brdfkit
    emb = brdfkit.encode("teflon.binary")                # a MERL table -> 39 numbers
    emb21 = brdfkit.encode("teflon.binary", size=21)     # or 21
    table = brdfkit.decode(emb)                          # -> (90, 90, 180, 3), 1/sr
    table, _ = brdfkit.sparse("samples.csv")             # N measurements -> dense table
    mix = brdfkit.interpolate(emb_a, emb_b, 0.3)         # material editing

``model`` is ``None`` (the default built-in, or for an embedding the built-in part whose
digest it records), a built-in's name, a file, or an object already loaded
(:func:`load_model` for a hypernetwork).

Errors about what was passed in are :class:`~brdfkit.errors.InputError` (or its
subclasses ``FormatError`` and ``ModelMismatchError``) with a one-line message.
"""

from __future__ import annotations

import os

import numpy as np

from brdfkit.io.embedding import Embedding
from brdfkit.errors import InputError, ModelMismatchError
from brdfkit.geometry import TABLE_SHAPE

__all__ = ["load_model", "encode", "decode", "sparse", "interpolate", "fit"]


def load_model(path: str | os.PathLike, device=None):
    """Load a hypernetwork's network file (``.safetensors``, never pickle), or a built-in
    model by name.

    Parameters
    ----------
    path
        File written by ``brdfkit fit`` / :func:`brdfkit.hypernet.network_file.save_network`, or the
        name of an installed built-in model (``brdfkit models``; ``docs/models.md``: a
        value is a file when it exists, holds a path separator or ends in
        ``.safetensors``), its file checked against the manifest's digest.
    device
        ``torch.device`` or string; ``None``: CUDA when available, else CPU.

    Returns
    -------
    brdfkit.hypernet.loaded.LoadedNetwork

    Examples
    --------
    >>> from brdfkit.testing.examples import tiny_model
    >>> model = load_model(tiny_model("tiny.safetensors"), device="cpu")  # an untrained model
    >>> model.cfg.latent_dim, len(model.digest)
    (7, 64)
    """
    from brdfkit.models.builtin import resolve_network
    from brdfkit.hypernet.network_file import load_network

    return load_network(resolve_network(path), device)


def load_input(obj, source: str = ""):
    """A ``SampleSet`` or a dense table from what :func:`encode` accepts, and a source
    name for provenance."""
    from brdfkit.io.samples import SampleSet

    if isinstance(obj, SampleSet):
        return obj, source or obj.source
    if isinstance(obj, (str, os.PathLike)):
        path = os.fspath(obj)
        name = source or os.path.basename(path)
        if path.lower().endswith(".csv"):
            from brdfkit.io.samples import read_samples
            return read_samples(path), name
        if path.lower().endswith(".bsdf"):  # an RGL file, at the MERL grid (brdfkit.files.brdf_file)
            from brdfkit.files.brdf_file import read_table
            return read_table(path), name
        from brdfkit.io.merl import read_merl
        return read_merl(path), name
    if isinstance(obj, np.ndarray) or hasattr(obj, "__array__"):
        arr = np.asarray(obj, dtype=np.float64)
        if arr.shape != TABLE_SHAPE:
            raise InputError(f"{source or 'table'}: shape {arr.shape}, expected a dense table "
                             f"{TABLE_SHAPE} or a SampleSet")
        return arr, source
    raise InputError(f"cannot encode a {type(obj).__name__}: pass a SampleSet, a {TABLE_SHAPE} "
                     f"table, or the path of a .binary or .csv file")


def _decoder(kind: str | None, model, device, size: int | None = None):
    """The :class:`~brdfkit.embeddings.decoders.Decoder` ``encode`` uses: ``model`` a name, a path
    or ``None`` (:func:`~brdfkit.embeddings.choose_decoder`), a decoder as it is, or a
    loaded hypernetwork (for an installed built-in's network, the decoder its name gives
    for ``kind`` and ``size``; else the network itself)."""
    from brdfkit.embeddings import Decoder, choose_decoder, get_kind, kind_of_part

    if model is None or isinstance(model, (str, os.PathLike)):
        return choose_decoder(kind, model, device, size)
    if isinstance(model, Decoder):
        if kind is not None and get_kind(kind).name != model.kind:
            raise InputError(f"--kind {kind}: the given decoder is a {model.kind} one")
        return model
    from brdfkit.models.parts import part_of

    part = part_of(model)
    if part is None or part.name != "network":
        raise InputError(f"model: expected a name, a path, a Decoder or a loaded hypernetwork, not a "
                         f"{part.label if part else type(model).__name__}")
    from brdfkit.models.builtin import installed_bundles

    own = kind_of_part("network").name
    entry = next((m for m in installed_bundles() if m.part("network") and m.parts["network"].digest == model.digest),
                 None)
    if entry is not None and (kind is None or get_kind(kind).name != own):
        return choose_decoder(kind, entry.name, device, size)
    if kind is not None and get_kind(kind).name != own:
        raise InputError(f"model {model.digest[:12]} is a hypernetwork of no installed built-in: it encodes {own} "
                         f"embeddings only")
    return Decoder.of_network(model)


def encode(data, model=None, *, kind: str | None = None, size: int | None = None, steps: int | None = None,
           refine: bool = True, max_seconds: float | None = None, source: str = "", device=None) -> Embedding:
    """Encode a material into an embedding (``brdfkit encode``).

    A dense table becomes, with no ``kind``, an embedding of the first kind of
    :data:`brdfkit.embeddings.registry.KINDS` whose part the model ships and whose decoder offers
    ``size``: a built-in with a basis residual (``merl80-l40``) makes a *residual
    embedding* at the sizes its residual offers (the basis's coefficients and the weight of
    the hypernetwork's correction, chosen per material; :mod:`brdfkit.residual.encoding`),
    a built-in with a PCA basis, the default model (``merl-rgl-l40``) among them, a *basis
    embedding* (the coefficients of the basis's leading components, the table's
    projection refined on renders of the objective scenes; :mod:`brdfkit.basis.coefficients`),
    and a built-in with a hypernetwork alone (``merl-rgl-l7``) the hypernetwork's latent;
    a file makes the kind of the part it is. The basis and residual kinds hold for
    materials outside the training set, where a hypernetwork's latent does not. With
    ``kind="hypernet"`` it is the latent: the set encoder's pass over all measured cells
    (Gokbudak et al. 2024), refined on the same renders
    (:func:`brdfkit.hypernet.refine_on_screen.compress_table`). Either way the same table
    gives the same embedding to the bit, whatever the machine's load. A sample set is
    encoded by the hypernetwork's encoder pass alone (``brdfkit sparse`` reconstructs
    from samples).

    Parameters
    ----------
    data
        A dense table ``(90, 90, 180, 3)`` in 1/sr with NaN where unmeasured (all measured
        cells are used), a :class:`~brdfkit.io.samples.SampleSet` (any ``N >= 1``), or the
        path of a MERL ``.binary``, an RGL ``.bsdf`` or a ``.csv`` sample set.
    model
        A built-in's name, a basis, basis-residual or hypernetwork file, a loaded
        hypernetwork (:func:`load_model`), a :class:`~brdfkit.embeddings.decoders.Decoder`, or
        ``None``: the default built-in.
    kind
        ``"basis"``, ``"residual"``, ``"hypernet"`` or ``None`` (module text above;
        :data:`brdfkit.embeddings.registry.KINDS`).
    size
        Numbers per material (a basis or residual embedding: ``3 K``, default 39, a
        residual the sizes its file offers; a latent: the model's latent size).
    steps
        Most refinement steps (``None``: the kind's default; 0: none).
    refine
        ``False``: no refinement (the projection, or the paper's single encoder pass).
    max_seconds
        A wall-clock cap on a latent's refinement (default none; a capped result depends
        on the machine's speed: its ``refinement`` record says ``"max_seconds"``).
    source
        Provenance recorded in the embedding; defaults to the file name or the sample
        set's source.
    device
        Torch device of a model loaded here (default: CUDA when available, else CPU).

    Returns
    -------
    Embedding
        ``size`` float32 values of its kind, the decoder's digest, the number of samples
        it was made from.

    Examples
    --------
    >>> from brdfkit.testing.examples import lambertian_table, tiny_basis_file, tiny_model
    >>> emb = encode(lambertian_table(), tiny_basis_file("tiny-basis.safetensors"), size=6, steps=0)
    >>> emb.kind, emb.size
    ('basis', 6)
    >>> model = load_model(tiny_model("tiny.safetensors"), device="cpu")  # no basis: a latent
    >>> emb = encode(lambertian_table(), model, refine=False)  # the encoder's one pass
    >>> emb.kind, emb.size, emb.sample_count
    ('hypernet', 7, 1111432)
    >>> from brdfkit.acquisition.sampling import draw_samples
    >>> encode(draw_samples(lambertian_table(), 40, seed=0), model).sample_count
    40
    """
    from brdfkit.embeddings import encode_with

    data, name = load_input(data, source)
    if not isinstance(data, np.ndarray):
        from brdfkit.embeddings import get_kind, kind_of_part

        own = kind_of_part("network").name
        if kind is not None and get_kind(kind).name != own:
            raise InputError(f"{name or 'samples'}: a {kind} embedding is made from a dense table; a sample set is "
                             f"encoded as a hypernetwork latent")
        dec = _decoder(own, model, device)
        from brdfkit.hypernet.encoding import encode_samples

        return encode_samples(dec.obj, data, name)
    return encode_with(_decoder(kind, model, device, size), data, source=name, size=size, steps=steps,
                       max_seconds=max_seconds, refine=refine)


def decode(embedding, model=None, *, source: str = "", device=None) -> np.ndarray:
    """Decode an embedding into a dense table (``brdfkit decode``).

    Parameters
    ----------
    embedding
        :class:`Embedding` or the path of an ``.emb`` file.
    model
        The decoder that made it: a built-in's name, a file, a loaded hypernetwork or a
        :class:`~brdfkit.embeddings.decoders.Decoder`; ``None``: the installed built-in part
        whose digest the embedding records (another decoder:
        :class:`~brdfkit.errors.ModelMismatchError`).
    source
        The name messages give the embedding (default: its path, when given one).
    device
        Torch device of a model loaded here.

    Returns
    -------
    numpy.ndarray
        float64 ``(90, 90, 180, 3)``, 1/sr, NaN where unmeasured (below the horizon).

    Examples
    --------
    >>> import numpy as np
    >>> from brdfkit.testing.examples import lambertian_table, tiny_basis_file
    >>> basis = tiny_basis_file("tiny-basis.safetensors")
    >>> table = decode(encode(lambertian_table(), basis, size=6, steps=0), basis)
    >>> table.shape, bool(np.nanmin(table) >= 0)
    ((90, 90, 180, 3), True)
    """
    from brdfkit.embeddings import Decoder, decoder_for, open_embedding

    name = source
    if isinstance(embedding, (str, os.PathLike)):
        from brdfkit.io.embedding import read_embedding

        name = source or os.fspath(embedding)
        embedding = read_embedding(embedding)
    if model is not None and not isinstance(model, (str, os.PathLike, Decoder)):
        model = _decoder(embedding.kind, model, device)
    dec = model if isinstance(model, Decoder) else decoder_for(embedding, model, device, name)
    return open_embedding(embedding, dec, name).to_table()


def _method_of(model) -> str:
    """The reconstruction method of a loaded model: the one that takes its part (by its
    class, :func:`brdfkit.models.parts.part_of`)."""
    from brdfkit.models.parts import part_of
    from brdfkit.methods.choice import method_of_part

    part = part_of(model)
    if part is None:
        raise InputError(f"model: expected a name, a path or a loaded model, not a {type(model).__name__}")
    return method_of_part(part.name, "model")


def sparse(samples, model=None, *, method: str = "auto", seed: int = 0, device=None, **options):
    """Reconstruct a dense table from sparse measurements (``brdfkit sparse``): the same
    method, model and bytes as the command line.

    Parameters
    ----------
    samples
        :class:`~brdfkit.io.samples.SampleSet` or the path of a ``.csv`` sample set.
    model
        A built-in's name or a model file; ``None``: the default built-in
        (:func:`brdfkit.methods.choice.choose`, as what the model serves says:
        :func:`brdfkit.methods.service.serves`); or a model loaded already (a
        hypernetwork, a :class:`~brdfkit.basis.model.PcaBasis`, a learnt prior).
    method
        ``"auto"`` (the model's own: a built-in's learnt prior when it has one, else its
        hypernetwork, else its basis; a file's by its part) or a name of
        :data:`brdfkit.methods.METHODS` the model serves.
    seed
        Drives any randomness of the method.
    options
        The method's options by name (:class:`brdfkit.methods.Method`).

    Returns
    -------
    tuple
        ``(table, embedding)``: float64 ``(90, 90, 180, 3)`` in 1/sr (NaN below the
        horizon) and the :class:`Embedding` it was decoded from, or ``None`` for a method
        that makes none (the learnt prior, IPCA, NBRDF).

    Examples
    --------
    >>> from brdfkit.acquisition.sampling import draw_samples
    >>> from brdfkit.testing.examples import lambertian_table, tiny_basis_file
    >>> basis = tiny_basis_file("tiny-basis.safetensors")
    >>> table, emb = sparse(draw_samples(lambertian_table(), 40, seed=0), basis, method="ipca")
    >>> table.shape, emb is None
    ((90, 90, 180, 3), True)
    """
    from brdfkit.methods import METHODS
    from brdfkit.methods.choice import choose

    if isinstance(samples, (str, os.PathLike)):
        if not os.fspath(samples).lower().endswith(".csv"):
            raise InputError(f"{os.fspath(samples)}: sparse reconstruction takes a .csv sample set "
                             f"(make one with `brdfkit sample`)")
        from brdfkit.io.samples import read_samples

        samples = read_samples(samples)
    if model is not None and not isinstance(model, (str, os.PathLike)):  # loaded already
        m = METHODS[_method_of(model) if method == "auto" else method]
        return m.sparse(samples, model, seed=seed, device=device, options=m.make_options(**options))
    choice = choose(method, model)
    m = METHODS[choice.method]
    if m.needs_model and choice.path is None:
        raise InputError(f"method {choice.method!r} needs a {m.model_kind} (-m); no default built-in is installed")
    return m.sparse(samples, choice.path, seed=seed, device=device, options=m.make_options(**options))


def interpolate(a: Embedding, b: Embedding, t: float, allow_extrapolation: bool = False) -> Embedding:
    """Blend two embeddings of the same kind, decoders and size: ``(1 - t) a + t b``
    (``brdfkit interpolate``; :func:`brdfkit.embeddings.blend.interpolate`).

    Examples
    --------
    >>> import numpy as np
    >>> dark = Embedding(np.zeros(3, np.float32), "basis", "f" * 64, "dark")
    >>> light = Embedding(np.full(3, 2.0, np.float32), "basis", "f" * 64, "light")
    >>> mid = interpolate(dark, light, 0.5)
    >>> mid.kind, mid.decoder == dark.decoder, mid.values.tolist()
    ('basis', True, [1.0, 1.0, 1.0])
    """
    from brdfkit.embeddings.blend import interpolate as blend

    return blend(a, b, t, allow_extrapolation)


def fit(data, output, method: str = "hypernet", **options) -> str:
    """Train one part of a model from MERL tables (``brdfkit fit``): ``method`` names what
    (:data:`brdfkit.training.FITTERS`: ``hypernet``, ``basis``, ``prior``, ``residual``),
    ``options`` its options by name (``exclude``, ``steps``, ``seed``, ...). Returns
    ``output``."""
    from brdfkit.training import get_fitter

    return get_fitter(method).fit(data, output, **options)
