"""Embedding files (``.emb``): one material as the latent vector of a model.

An embedding is the set encoder's output ``z`` for one material (Gokbudak et al. 2024,
Sec. 3): with the model that made it, it decodes into the material's neural BRDF. On disk
it is a small, self-describing JSON document (``docs/formats.md``, "Embedding files")::

    {"format": "brdfkit-embedding", "version": 1, "latent_dim": 40,
     "latent": [0.12, -0.5, ...], "model_fingerprint": "3f2a...",
     "source": "teflon.binary", "sample_count": 1156550}

Latent values are written as the shortest decimal that gives back the same float32, so a
write/read round trip is exact. The file names the model (its weights fingerprint): an
embedding decodes only with that model (:func:`check_compatible`).
"""

from __future__ import annotations

import dataclasses
import json
import math
import os

import numpy as np

from brdfkit.atomic import atomic_open, check_input_file
from brdfkit.errors import FormatError, ModelMismatchError

__all__ = ["EMBEDDING_FORMAT", "EMBEDDING_VERSION", "Embedding", "write_embedding",
           "read_embedding", "check_compatible"]

EMBEDDING_FORMAT = "brdfkit-embedding"
EMBEDDING_VERSION = 1
# An embedding of any sensible latent size is a few kB; refuse to parse anything huge.
_MAX_BYTES = 1 << 20
_F32_MAX = float(np.finfo(np.float32).max)


@dataclasses.dataclass
class Embedding:
    """One material as a model's latent vector.

    Attributes
    ----------
    latent
        float32 ``(L,)``.
    model_fingerprint
        sha256 hex of the weights of the model that made it
        (:func:`brdfkit.hypernet.model_file.weights_fingerprint`).
    source
        Where the material came from (a file name), for provenance.
    sample_count
        Number of BRDF samples the encoder averaged over (0 when not from samples, e.g.
        an interpolation).
    refinement
        How the latent was refined after the encoder's pass, or ``None`` (not refined):
        ``{"steps": int, "best_step": int, "stopped": str}``
        (:class:`brdfkit.hypernet.refine_on_screen.CompressResult`); ``--steps`` of the
        record replays it.
    basis
        ``None`` for a hypernetwork latent; else the sha256 hex of the PCA basis file
        whose coefficients the latent holds (a *basis embedding*,
        :mod:`brdfkit.methods.ipca.embedding`: ``K`` components times 3 channels,
        component-major, ``latent_dim = 3 K``), the basis the model named by
        ``model_fingerprint`` ships with.
    """

    latent: np.ndarray
    model_fingerprint: str
    source: str = ""
    sample_count: int = 0
    refinement: dict | None = None
    basis: str | None = None

    def __post_init__(self):
        self.latent = np.asarray(self.latent, dtype=np.float32).reshape(-1)

    @property
    def latent_dim(self) -> int:
        return int(self.latent.shape[0])


def _to_json(emb: Embedding) -> str:
    doc = {
        "format": EMBEDDING_FORMAT,
        "version": EMBEDDING_VERSION,
        "latent_dim": emb.latent_dim,
        # float32 -> float is exact; json writes the shortest repr of that float64, which
        # reads back to the same float32.
        "latent": [float(x) for x in emb.latent],
        "model_fingerprint": emb.model_fingerprint,
        "source": emb.source,
        "sample_count": int(emb.sample_count),
    }
    if emb.refinement is not None:  # absent from files of unrefined latents, as before
        doc["refinement"] = dict(emb.refinement)
    if emb.basis is not None:  # absent from hypernetwork latents, as before
        doc["basis"] = emb.basis
    return json.dumps(doc, indent=1) + "\n"


def write_embedding(path: str | os.PathLike, emb: Embedding) -> None:
    """Write an embedding as JSON, atomically.

    Raises
    ------
    ValueError
        Non-finite latent values (a bug upstream, not something to save).
    """
    if not np.isfinite(emb.latent).all():
        raise ValueError("embedding holds non-finite values")
    text = _to_json(emb)
    with atomic_open(path, "w", encoding="utf-8") as f:
        f.write(text)


def _is_int(x) -> bool:
    return isinstance(x, int) and not isinstance(x, bool)


def read_embedding(path: str | os.PathLike) -> Embedding:
    """Read and validate an ``.emb`` file.

    Returns
    -------
    Embedding

    Raises
    ------
    FormatError
        Not JSON, not a brdfkit embedding, an unsupported version, a latent whose length
        differs from ``latent_dim``, non-numeric or non-finite values, a missing or
        malformed field. One line naming the file.
    """
    path = check_input_file(path)
    size = os.path.getsize(path)
    if size > _MAX_BYTES:
        raise FormatError(path, f"not an embedding file: {size} bytes (an embedding is a few kB of JSON)")
    with open(path, "rb") as f:
        raw = f.read()
    try:
        doc = json.loads(raw.decode("utf-8-sig"))
    except (UnicodeDecodeError, ValueError) as e:
        raise FormatError(path, f"not an embedding file: not JSON text ({str(e).splitlines()[0]})") from None
    if not isinstance(doc, dict):
        raise FormatError(path, "not an embedding file: JSON is not an object")
    if doc.get("format") != EMBEDDING_FORMAT:
        raise FormatError(path, f"not a brdfkit embedding (format {doc.get('format')!r}, "
                                f"expected {EMBEDDING_FORMAT!r})")
    version = doc.get("version")
    if version != EMBEDDING_VERSION or not _is_int(version):
        raise FormatError(path, f"embedding version {version!r} is not supported "
                                f"(this brdfkit reads version {EMBEDDING_VERSION})")
    dim = doc.get("latent_dim")
    if not _is_int(dim) or dim < 1:
        raise FormatError(path, f"latent_dim must be a positive integer, not {dim!r}")
    latent = doc.get("latent")
    if not isinstance(latent, list):
        raise FormatError(path, "'latent' must be a list of numbers")
    if len(latent) != dim:
        raise FormatError(path, f"latent has {len(latent)} values but latent_dim is {dim}")
    for i, x in enumerate(latent):
        if not (isinstance(x, (int, float)) and not isinstance(x, bool)):
            raise FormatError(path, f"latent[{i}] is {x!r}, not a number")
        if not math.isfinite(x) or abs(x) > _F32_MAX:
            raise FormatError(path, f"latent[{i}] is {x!r}, not a finite float32 value")
    fp = doc.get("model_fingerprint")
    if not isinstance(fp, str) or not fp:
        raise FormatError(path, "'model_fingerprint' must be a non-empty string")
    source = doc.get("source", "")
    if not isinstance(source, str):
        raise FormatError(path, "'source' must be a string")
    count = doc.get("sample_count", 0)
    if not _is_int(count) or count < 0:
        raise FormatError(path, f"'sample_count' must be a non-negative integer, not {count!r}")
    basis = doc.get("basis")
    if basis is not None and not (isinstance(basis, str) and len(basis) == 64
                                  and all(ch in "0123456789abcdef" for ch in basis)):
        raise FormatError(path, "'basis' must be the sha256 hex (64 characters) of a PCA basis file")
    if basis is not None and dim % 3:
        raise FormatError(path, f"a basis embedding holds 3 coefficients a component, not {dim} values")
    return Embedding(np.array(latent, dtype=np.float32), fp, source, count, _refinement(path, doc), basis)


def _refinement(path, doc) -> dict | None:
    """The optional ``refinement`` record of an embedding file, checked."""
    rec = doc.get("refinement")
    if rec is None:
        return None
    ok = (isinstance(rec, dict) and _is_int(rec.get("steps")) and _is_int(rec.get("best_step"))
          and isinstance(rec.get("stopped"), str) and 0 <= rec["best_step"] <= rec["steps"])
    if not ok:
        raise FormatError(path, "'refinement' must be {\"steps\": int, \"best_step\": int <= steps, \"stopped\": str}")
    return {"steps": rec["steps"], "best_step": rec["best_step"], "stopped": rec["stopped"]}


def check_compatible(emb: Embedding, model, name: str = "") -> None:
    """Refuse an embedding made by a different model.

    Parameters
    ----------
    emb
        The embedding.
    model
        A :class:`brdfkit.hypernet.loaded.NeuralModel`.
    name
        How to call the embedding in the message (its file name), optional.

    Raises
    ------
    ModelMismatchError
        Fingerprints or latent sizes differ; the message names both fingerprints (short)
        and both latent sizes.
    """
    model_dim = int(model.cfg.latent_dim)
    # A basis embedding's size is the basis's (3 K), checked against the basis when decoded.
    if emb.model_fingerprint == model.fingerprint and (emb.latent_dim == model_dim or emb.basis is not None):
        return
    what = f"embedding {name}" if name else "embedding"
    where = f"{os.path.basename(model.path)}, " if getattr(model, "path", "") else ""
    raise ModelMismatchError(
        f"{what} was made by model {emb.model_fingerprint[:12]} (latent {emb.latent_dim}), "
        f"not by the given model {model.fingerprint[:12]} ({where}latent {model_dim}); "
        f"encode the material again with this model")
