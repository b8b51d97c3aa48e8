"""Embedding files (``.emb``): one material as a few numbers that decode with one model.

An embedding is a material compressed into ``size`` numbers of some *kind*: the
coefficients of a PCA basis (``"basis"``, :mod:`brdfkit.basis`), the same corrected by a
hypernetwork residual (``"residual"``, :mod:`brdfkit.residual`) or a hypernetwork's latent
(``"hypernet"``, Gokbudak et al. 2024). With the part of a model that made it (its
*decoder*) it decodes into the material's BRDF; the kinds and their decoders are
registered by name in :data:`brdfkit.embeddings.registry.KINDS`. On disk it is a small,
self-describing JSON document (``docs/formats.md``, "Embedding files")::

    {"format": "brdfkit-embedding", "version": 2, "kind": "basis", "size": 39,
     "values": [0.12, -0.5, ...], "decoder": "3f2a...",
     "source": "teflon.binary", "sample_count": 1156550}

``decoder`` is the digest (SHA-256) the decoder is known by (a basis file's bytes, a
network's weights): an embedding decodes only with that decoder, and is how brdfkit finds
it among the built-in models. ``parts`` (optional) holds the digests of every part that
decodes it, by part name, when there is more than one (a residual and the basis it
corrects); ``options`` (optional) its kind's decode options (a residual's ``correction``
weight). Values are written as the shortest decimal that gives back the same float32, so a
write/read round trip is exact. Version 1 files (a ``latent`` with its
``model_fingerprint``, and for basis coefficients a ``basis`` SHA-256) and the kind name
``latent`` (now ``hypernet``) are read as the same embeddings.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import re

import numpy as np

from brdfkit.atomic import atomic_open, check_input_file
from brdfkit.errors import FormatError

__all__ = ["EMBEDDING_FORMAT", "EMBEDDING_VERSION", "Embedding", "write_embedding", "read_embedding",
           "parse_document"]

EMBEDDING_FORMAT = "brdfkit-embedding"
EMBEDDING_VERSION = 2
_READS = (1, 2)
# An embedding of any sensible size is a few kB; refuse to parse anything huge.
_MAX_BYTES = 1 << 20
_F32_MAX = float(np.finfo(np.float32).max)
_HEX64 = re.compile(r"[0-9a-f]{64}\Z")
_KIND = re.compile(r"[a-z][a-z0-9-]*\Z")
# An option is named as a kind is, and a residual's member M > 0 by ".M" after its name
# (brdfkit.residual.model.gains: "correction", "correction.1").
_OPTION = re.compile(r"[a-z][a-z0-9-]*(\.[1-9][0-9]*)?\Z")
_OLD_KINDS = {"latent": "hypernet"}  # names a kind had before, as files may hold them


@dataclasses.dataclass
class Embedding:
    """One material as ``size`` numbers of one kind.

    Attributes
    ----------
    values
        float32 ``(size,)``. For a basis embedding the ``(K, 3)`` coefficients of the
        basis's ``K`` leading components, component-major (``size = 3 K``); for a latent,
        the hypernetwork's latent vector.
    kind
        ``"basis"``, ``"residual"`` or ``"hypernet"`` (:data:`brdfkit.embeddings.registry.KINDS`).
    decoder
        SHA-256 hex digest of the decoder: the bytes of the basis or residual file, or the
        weights of the hypernetwork (:func:`brdfkit.hypernet.network_file.weights_digest`).
    source
        Where the material came from (a file name), for provenance.
    sample_count
        Number of BRDF samples it was made from (0 when not from samples, e.g. an
        interpolation).
    refinement
        How the values were refined on renders after their closed-form or encoder start,
        or ``None`` (not refined): ``{"steps": int, "best_step": int, "stopped": str}``
        (the solver's iterations or steps, the one kept, why it stopped), and, in files
        written since the refinement became one loop for every kind, ``"solver"``
        (``"levenberg-marquardt"``, ``"adam"``; ``"gauss-newton"`` in files
        written before the one solver, the same iterations) and ``"heldout"``, the held-out render errors of
        the start and of each check (display MSE); ``--steps`` of the record replays it.
    parts
        ``{part: digest}`` of every part that decodes it, when more than the decoder
        (a residual's basis), else ``None``.
    options
        ``{name: float}`` decode options of its kind (a residual's ``correction``), or
        ``None``.

    Examples
    --------
    >>> import numpy as np
    >>> emb = Embedding(np.zeros(9), "basis", "ab" * 32, "teflon.binary")
    >>> emb.size, emb.values.dtype
    (9, dtype('float32'))
    """

    values: np.ndarray
    kind: str
    decoder: str
    source: str = ""
    sample_count: int = 0
    refinement: dict | None = None
    parts: dict | None = None
    options: dict | None = None

    def __post_init__(self):
        self.values = np.asarray(self.values, dtype=np.float32).reshape(-1)
        self.kind = _OLD_KINDS.get(self.kind, self.kind)

    @property
    def size(self) -> int:
        """Numbers per material."""
        return int(self.values.shape[0])


def _to_json(emb: Embedding) -> str:
    doc = {
        "format": EMBEDDING_FORMAT,
        "version": EMBEDDING_VERSION,
        "kind": emb.kind,
        "size": emb.size,
        # float32 -> float is exact; json writes the shortest repr of that float64, which
        # reads back to the same float32.
        "values": [float(x) for x in emb.values],
        "decoder": emb.decoder,
        "source": emb.source,
        "sample_count": int(emb.sample_count),
    }
    if emb.refinement is not None:  # absent from files of unrefined embeddings
        doc["refinement"] = dict(emb.refinement)
    if emb.parts:
        doc["parts"] = dict(sorted(emb.parts.items()))
    if emb.options:
        doc["options"] = {k: float(v) for k, v in sorted(emb.options.items())}
    return json.dumps(doc, indent=1) + "\n"


def write_embedding(path: str | os.PathLike, emb: Embedding) -> None:
    """Write an embedding as JSON, atomically, after checking the document with the
    reader's own checks (:func:`parse_document`): a file that is written can be read.

    Raises
    ------
    ValueError
        A document :func:`read_embedding` would refuse (non-finite values, a malformed
        kind, decoder, part or option name...): a bug upstream, not something to save.
    """
    if not np.isfinite(emb.values).all():
        raise ValueError("embedding holds non-finite values")
    text = _to_json(emb)
    try:
        parse_document(json.loads(text), "embedding")
    except FormatError as e:
        raise ValueError(f"refusing to write an embedding that could not be read back: {e.problem}") from None
    with atomic_open(path, "w", encoding="utf-8") as f:
        f.write(text)


def _is_int(x) -> bool:
    return isinstance(x, int) and not isinstance(x, bool)


def read_embedding(path: str | os.PathLike) -> Embedding:
    """Read and validate an ``.emb`` file (version 2, or version 1 as the same embedding).

    Returns
    -------
    Embedding

    Raises
    ------
    FormatError
        Not JSON, not a brdfkit embedding, an unsupported version, values whose count
        differs from ``size``, non-numeric or non-finite values, a missing or malformed
        field. One line naming the file.
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
    return parse_document(doc, path)


def parse_document(doc, path: str = "embedding") -> Embedding:
    """The embedding a parsed ``.emb`` document holds, checked: the one schema of the
    format, which :func:`read_embedding` reads with and :func:`write_embedding` checks
    what it writes with.

    Raises
    ------
    FormatError
        Naming ``path``, as :func:`read_embedding` says.

    Examples
    --------
    >>> doc = {"format": "brdfkit-embedding", "version": 2, "kind": "residual", "size": 3,
    ...        "values": [1, 0, 0], "decoder": "ab" * 32, "options": {"correction.1": 1}}
    >>> parse_document(doc).options
    {'correction.1': 1.0}
    """
    if not isinstance(doc, dict):
        raise FormatError(path, "not an embedding file: JSON is not an object")
    if doc.get("format") != EMBEDDING_FORMAT:
        raise FormatError(path, f"not a brdfkit embedding (format {doc.get('format')!r}, "
                                f"expected {EMBEDDING_FORMAT!r})")
    version = doc.get("version")
    if not _is_int(version) or version not in _READS:
        raise FormatError(path, f"embedding version {version!r} is not supported "
                                f"(this brdfkit reads versions {', '.join(map(str, _READS))})")
    kind, decoder, values = _fields(path, doc) if version == 2 else _fields_v1(path, doc)
    source = doc.get("source", "")
    if not isinstance(source, str):
        raise FormatError(path, "'source' must be a string")
    count = doc.get("sample_count", 0)
    if not _is_int(count) or count < 0:
        raise FormatError(path, f"'sample_count' must be a non-negative integer, not {count!r}")
    return Embedding(np.array(values, dtype=np.float32), kind, decoder, source, count, _refinement(path, doc),
                     _parts(path, doc), _options(path, doc))


def _fields(path, doc) -> tuple[str, str, list]:
    """``(kind, decoder, values)`` of a version 2 document, checked."""
    kind, decoder = doc.get("kind"), doc.get("decoder")
    if not isinstance(kind, str) or not _KIND.match(kind):
        raise FormatError(path, f"'kind' must be an embedding kind such as 'basis' or 'hypernet', not {kind!r}")
    if not isinstance(decoder, str) or not _HEX64.match(decoder):
        raise FormatError(path, "'decoder' must be a SHA-256 hex digest (64 lowercase hex digits)")
    return kind, decoder, _values(path, doc, "values", "size")


def _fields_v1(path, doc) -> tuple[str, str, list]:
    """``(kind, decoder, values)`` of a version 1 document: ``latent`` and its
    ``model_fingerprint``, or with ``basis`` the coefficients of that basis file."""
    values = _values(path, doc, "latent", "latent_dim")
    fp, basis = doc.get("model_fingerprint"), doc.get("basis")
    if not isinstance(fp, str) or not _HEX64.match(fp):
        raise FormatError(path, "'model_fingerprint' must be a SHA-256 hex digest (64 lowercase hex digits)")
    if basis is None:
        return "hypernet", fp, values
    if not (isinstance(basis, str) and _HEX64.match(basis)):
        raise FormatError(path, "'basis' must be the sha256 hex (64 characters) of a PCA basis file")
    if len(values) % 3:
        raise FormatError(path, f"a basis embedding holds 3 coefficients a component, not {len(values)} values")
    return "basis", basis, values


def _values(path, doc, key: str, size_key: str) -> list:
    """The list ``doc[key]`` of ``doc[size_key]`` finite float32 numbers, checked."""
    dim = doc.get(size_key)
    if not _is_int(dim) or dim < 1:
        raise FormatError(path, f"{size_key} must be a positive integer, not {dim!r}")
    values = doc.get(key)
    if not isinstance(values, list):
        raise FormatError(path, f"'{key}' must be a list of numbers")
    if len(values) != dim:
        raise FormatError(path, f"{key} has {len(values)} values but {size_key} is {dim}")
    for i, x in enumerate(values):
        if not (isinstance(x, (int, float)) and not isinstance(x, bool)):
            raise FormatError(path, f"{key}[{i}] is {x!r}, not a number")
        if not math.isfinite(x) or abs(x) > _F32_MAX:
            raise FormatError(path, f"{key}[{i}] is {x!r}, not a finite float32 value")
    return values


def _refinement(path, doc) -> dict | None:
    """The optional ``refinement`` record of an embedding file, checked."""
    rec = doc.get("refinement")
    if rec is None:
        return None
    ok = (isinstance(rec, dict) and _is_int(rec.get("steps")) and _is_int(rec.get("best_step"))
          and isinstance(rec.get("stopped"), str) and 0 <= rec["best_step"] <= rec["steps"])
    if not ok:
        raise FormatError(path, "'refinement' must be {\"steps\": int, \"best_step\": int <= steps, \"stopped\": str}")
    out = {"steps": rec["steps"], "best_step": rec["best_step"], "stopped": rec["stopped"]}
    if "solver" in rec:
        if not isinstance(rec["solver"], str):
            raise FormatError(path, "'refinement' 'solver' must be a name")
        out["solver"] = rec["solver"]
    if "heldout" in rec:
        held = rec["heldout"]
        if not (isinstance(held, list) and all(isinstance(e, (int, float)) and not isinstance(e, bool)
                                               and math.isfinite(e) and e >= 0 for e in held)):
            raise FormatError(path, "'refinement' 'heldout' must be a list of finite errors >= 0")
        out["heldout"] = [float(e) for e in held]
    return out


def _parts(path, doc) -> dict | None:
    """The optional ``parts`` of an embedding file: part name -> digest, checked."""
    parts = doc.get("parts")
    if parts is None:
        return None
    if not (isinstance(parts, dict) and parts and all(isinstance(k, str) and _KIND.match(k) and isinstance(v, str)
                                                      and _HEX64.match(v) for k, v in parts.items())):
        raise FormatError(path, "'parts' must map part names to SHA-256 hex digests (64 lowercase hex digits)")
    return dict(parts)


def _options(path, doc) -> dict | None:
    """The optional ``options`` of an embedding file: name -> finite number, checked."""
    opts = doc.get("options")
    if opts is None:
        return None
    if not (isinstance(opts, dict) and all(isinstance(k, str) and _OPTION.match(k) and isinstance(v, (int, float))
                                           and not isinstance(v, bool) and math.isfinite(v) for k, v in opts.items())):
        raise FormatError(path, "'options' must map option names (such as 'correction' or 'correction.1') "
                                "to finite numbers")
    return {k: float(v) for k, v in opts.items()}
