"""The library interface: load a model, encode, decode, reconstruct from sparse samples,
interpolate, train.

Everything a user does with a trained hypernetwork (Gokbudak et al. 2024) in a few calls::

    import brdfkit
    model = brdfkit.load_model("model.safetensors")     # or a built-in's name
    emb = brdfkit.encode(model, "teflon.binary")        # a MERL table -> 40 numbers
    table = brdfkit.decode(model, emb)                   # -> (90, 90, 180, 3), 1/sr
    table, emb = brdfkit.sparse(model, "samples.csv")    # N measurements -> dense table
    mix = brdfkit.interpolate(emb_a, emb_b, 0.3)         # material editing

Errors about what was passed in are :class:`~brdfkit.errors.InputError` (or its
subclasses ``FormatError`` and ``ModelMismatchError``) with a one-line message.
"""

from __future__ import annotations

import math
import os

import numpy as np

from brdfkit.io.embedding import Embedding
from brdfkit.errors import InputError, ModelMismatchError
from brdfkit.geometry import TABLE_SHAPE

__all__ = ["load_model", "encode", "decode", "sparse", "interpolate", "fit"]


def load_model(path: str | os.PathLike, device=None):
    """Load a hypernetwork model file (``.safetensors``, never pickle), or a built-in
    model by name.

    Parameters
    ----------
    path
        File written by ``brdfkit fit`` / :func:`brdfkit.hypernet.model_file.save_model`, or the
        name of an installed built-in model (``brdfkit models``; ``docs/models.md``: a
        value is a file when it exists, holds a path separator or ends in
        ``.safetensors``), its file checked against the manifest's fingerprint.
    device
        ``torch.device`` or string; ``None``: CUDA when available, else CPU.

    Returns
    -------
    brdfkit.hypernet.loaded.NeuralModel

    Examples
    --------
    >>> from brdfkit.testing.examples import tiny_model
    >>> model = load_model(tiny_model("tiny.safetensors"), device="cpu")  # an untrained model
    >>> model.cfg.latent_dim, len(model.fingerprint)
    (7, 64)
    """
    from brdfkit.models.builtin import resolve_model
    from brdfkit.hypernet.model_file import load_model as _load

    return _load(resolve_model(path), device)


def _load_input(obj, source: str):
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
        if path.lower().endswith(".bsdf"):  # an RGL file, at the MERL grid (brdf_file)
            from brdfkit.brdf_file import read_table
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


def encode(model, samples_or_table, *, source: str = "", refine: bool = True,
           steps: int | None = None, max_seconds: float | None = None, kind: str | None = None) -> Embedding:
    """Encode a material into an embedding.

    A dense table becomes, by default, a *basis embedding* when the model ships a PCA
    basis (the built-ins with a learnt prior): the coefficients of its ``latent_dim // 3``
    leading components, the table's projection refined on screen
    (:mod:`brdfkit.methods.ipca.embedding`; issue 29: it holds for materials outside the
    training set, where the hypernetwork's latent does not). Otherwise (``kind="latent"``,
    or a model without a basis) it is the set encoder's pass over all its measured cells
    (Gokbudak et al. 2024), then, by default, that latent refined on screen for at most
    ``steps`` steps: descended on the render-aligned error and kept only where held-out
    pixels agree (:func:`brdfkit.hypernet.refine_on_screen.compress_table`; never worse
    there than the encoder's pass). Either way the same table gives the same embedding to
    the bit, whatever the machine's load. A sample set is encoded by the encoder's pass
    alone (``brdfkit sparse --method hypernet`` refines on samples).

    Parameters
    ----------
    model
        :class:`~brdfkit.hypernet.loaded.NeuralModel` (from :func:`load_model`).
    samples_or_table
        A :class:`~brdfkit.io.samples.SampleSet` (any ``N >= 1``), a dense table
        ``(90, 90, 180, 3)`` in 1/sr with NaN where unmeasured (all measured cells are
        used), or the path of a MERL ``.binary``, an RGL ``.bsdf`` or a ``.csv`` sample set.
    source
        Provenance recorded in the embedding; defaults to the file name or the sample
        set's source.
    refine
        Refine a table's latent on screen (``False``: the paper's single pass).
    steps
        Most steps of that refinement (default
        :data:`brdfkit.hypernet.refine_on_screen.DEFAULT_STEPS`; 0: none).
    max_seconds
        A wall-clock cap on the refinement of a latent (default none; a capped result
        depends on the machine's speed: its ``refinement`` record says ``"max_seconds"``).
    kind
        ``"basis"``, ``"latent"`` or ``None``: a basis embedding when the model ships a
        basis, else a latent (a sample set always gets a latent).

    Returns
    -------
    Embedding
        float32 latent of the model's size (a basis embedding: ``3 K`` coefficients and
        its basis's sha256), with the model's fingerprint and the number of samples
        averaged.

    Examples
    --------
    >>> from brdfkit.testing.examples import lambertian_table, tiny_model
    >>> model = load_model(tiny_model("tiny.safetensors"), device="cpu")  # no basis: a latent
    >>> emb = encode(model, lambertian_table(), refine=False)  # the encoder's one pass
    >>> emb.latent.shape, emb.sample_count
    ((7,), 1111432)
    >>> from brdfkit.acquisition.sampling import draw_samples
    >>> encode(model, draw_samples(lambertian_table(), 40, seed=0)).sample_count
    40
    """
    from brdfkit.hypernet.encoding import encode_samples
    from brdfkit.methods.embedding import encode_table

    data, name = _load_input(samples_or_table, source)
    if not isinstance(data, np.ndarray):
        if kind == "basis":
            raise InputError(f"{name or 'samples'}: a basis embedding is made from a dense table; a sample set "
                             f"is encoded as a latent")
        if kind not in (None, "latent"):
            raise InputError(f"embedding kind {kind!r}: expected 'basis' or 'latent'")
        return encode_samples(model, data, name)
    return encode_table(model, data, name, refine=refine, steps=steps, max_seconds=max_seconds, kind=kind)


def decode(model, embedding, *, source: str = "") -> np.ndarray:
    """Decode an embedding into a dense table.

    Parameters
    ----------
    model
        The model that made the embedding (else
        :class:`~brdfkit.errors.ModelMismatchError`).
    embedding
        :class:`Embedding` or the path of an ``.emb`` file.
    source
        The name messages give the embedding (default: its path, when given one).

    Returns
    -------
    numpy.ndarray
        float64 ``(90, 90, 180, 3)``, 1/sr, NaN where the model's reference table is
        unmeasured (below the horizon).

    Examples
    --------
    >>> import numpy as np
    >>> from brdfkit.testing.examples import lambertian_table, tiny_model
    >>> model = load_model(tiny_model("tiny.safetensors"), device="cpu")
    >>> table = decode(model, encode(model, lambertian_table(), refine=False))
    >>> table.shape, bool(np.nanmin(table) >= 0)
    ((90, 90, 180, 3), True)
    """
    from brdfkit.methods.embedding import embedding_brdf

    name = source
    if isinstance(embedding, (str, os.PathLike)):
        from brdfkit.io.embedding import read_embedding
        name = source or os.fspath(embedding)
        embedding = read_embedding(embedding)
    return embedding_brdf(model, embedding, name).to_table()


def sparse(model, samples, *, source: str = ""):
    """Reconstruct a dense table from sparse measurements (the paper's main use).

    Parameters
    ----------
    samples
        :class:`~brdfkit.io.samples.SampleSet` or the path of a ``.csv`` sample set.

    Returns
    -------
    tuple
        ``(table, embedding)``: float64 ``(90, 90, 180, 3)`` in 1/sr (NaN below the
        horizon) and the :class:`Embedding` it was decoded from.

    Examples
    --------
    >>> from brdfkit.acquisition.sampling import draw_samples
    >>> from brdfkit.testing.examples import lambertian_table, tiny_model
    >>> model = load_model(tiny_model("tiny.safetensors"), device="cpu")
    >>> table, emb = sparse(model, draw_samples(lambertian_table(), 40, seed=0))
    >>> table.shape, emb.sample_count
    ((90, 90, 180, 3), 40)
    """
    if isinstance(samples, (str, os.PathLike)) and not os.fspath(samples).lower().endswith(".csv"):
        raise InputError(f"{os.fspath(samples)}: sparse reconstruction takes a .csv sample set "
                         f"(make one with `brdfkit sample`)")
    emb = encode(model, samples, source=source)
    return decode(model, emb), emb


def interpolate(a: Embedding, b: Embedding, t: float, allow_extrapolation: bool = False) -> Embedding:
    """Blend two embeddings of the same model: ``(1 - t) a + t b``.

    Computed in float64 and rounded to float32, so ``t = 0`` gives ``a`` and ``t = 1``
    gives ``b`` exactly.

    Raises
    ------
    ModelMismatchError
        The embeddings come from different models (fingerprints or latent sizes differ).
    InputError
        ``t`` not a finite number, or outside ``[0, 1]`` without ``allow_extrapolation``.

    Examples
    --------
    >>> import numpy as np
    >>> a = Embedding(np.zeros(7, np.float32), "f" * 64, "a", 0)
    >>> b = Embedding(np.ones(7, np.float32), "f" * 64, "b", 0)
    >>> interpolate(a, b, 0.25).latent.tolist()
    [0.25, 0.25, 0.25, 0.25, 0.25, 0.25, 0.25]
    >>> interpolate(a, b, 0.0).latent is not a.latent, bool((interpolate(a, b, 1.0).latent == b.latent).all())
    (True, True)
    """
    try:
        t = float(t)
    except (TypeError, ValueError):
        raise InputError(f"t: {t!r} is not a number") from None
    if not math.isfinite(t):
        raise InputError(f"t: {t!r} is not a finite number")
    if not allow_extrapolation and not 0.0 <= t <= 1.0:
        raise InputError(f"t = {t:g} is outside [0, 1]; pass allow_extrapolation=True to extrapolate")
    if a.basis != b.basis:
        raise ModelMismatchError(
            f"cannot interpolate a {'basis embedding' if a.basis else 'latent'} ({a.source or 'a'}) with a "
            f"{'basis embedding' if b.basis else 'latent'} ({b.source or 'b'}): encode both the same way")
    if a.model_fingerprint != b.model_fingerprint or a.latent_dim != b.latent_dim:
        raise ModelMismatchError(
            f"cannot interpolate embeddings of different models: {a.source or 'a'} is from model "
            f"{a.model_fingerprint[:12]} (latent {a.latent_dim}), {b.source or 'b'} from model "
            f"{b.model_fingerprint[:12]} (latent {b.latent_dim})")
    la = a.latent.astype(np.float64)
    lb = b.latent.astype(np.float64)
    latent = ((1.0 - t) * la + t * lb).astype(np.float32)
    if not np.isfinite(latent).all():
        raise InputError(f"t = {t:g} extrapolates beyond float32 range")
    return Embedding(latent, a.model_fingerprint,
                     f"interpolate({a.source or 'a'}, {b.source or 'b'}, t={t:g})", 0, basis=a.basis)


def fit(*args, **kwargs):
    """Train a hypernetwork; see :func:`brdfkit.hypernet.training.loop.fit` (imported on first use)."""
    from brdfkit.hypernet.training.loop import fit as _fit

    return _fit(*args, **kwargs)
