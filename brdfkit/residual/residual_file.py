"""The basis-residual file (format ``brdfkit-residual``): safetensors, never pickle.

Tensors: each network's (:class:`~brdfkit.residual.network.ResidualNet`'s names, prefixed
``net<i>.``), float32, float16 or, for the hypernetwork's head (nearly all its weights),
int8 with a float32 scale per row (:func:`brdfkit.basis.storage.quantize`; tensor
``net<i>.head.weight.scale``). Metadata: ``format``, ``version``, ``configs`` (JSON: the
networks' :class:`~brdfkit.residual.network.ResidualConfig`), ``storage`` (``float32``,
``float16`` or ``int8``), ``basis_digest`` (the SHA-256 of the basis file it corrects),
``basis_file`` (that file's name, looked for beside this one), ``offered`` (JSON: the sizes
``encode`` offers it at) and ``meta`` (JSON: the training record). The file's own SHA-256
is the digest embeddings name it by.
"""

from __future__ import annotations

import json
import os

import numpy as np

from brdfkit.atomic import atomic_path, check_input_file
from brdfkit.errors import FormatError, InputError
from brdfkit.residual.model import BasisResidual, components_of, offered_sizes
from brdfkit.residual.network import LEFT_FIELDS, ResidualConfig, hyponet_shapes

__all__ = ["RESIDUAL_FORMAT", "RESIDUAL_VERSION", "STORAGES", "save_residual", "load_residual", "read_networks",
           "read_header", "read_offer"]

RESIDUAL_FORMAT = "brdfkit-residual"
RESIDUAL_VERSION = "1"
STORAGES = ("float32", "float16", "int8")
"""How a file stores its tensors; int8 quantizes the heads (the built-ins: 0.1 MB a network)."""
_HEX = set("0123456789abcdef")
_QUANTIZED = "head.weight"


def _as_numpy(v) -> np.ndarray:
    return np.asarray(v.detach().cpu() if hasattr(v, "detach") else v, dtype=np.float32)


def _store(i: int, state: dict, storage: str) -> dict:
    from brdfkit.basis.storage import quantize

    out = {}
    for k, v in state.items():
        a = np.ascontiguousarray(_as_numpy(v))
        if storage == "int8" and k == _QUANTIZED:
            q, scale = quantize(a)
            out[f"net{i}.{k}"], out[f"net{i}.{k}.scale"] = q, scale
        elif storage in ("float16", "int8"):
            if float(np.abs(a).max(initial=0.0)) > 6e4:
                raise ValueError(f"residual weight {k} is beyond float16's range")
            out[f"net{i}.{k}"] = a.astype(np.float16)
        else:
            out[f"net{i}.{k}"] = a
    return out


def save_residual(path: str | os.PathLike, nets: list, *, basis_digest: str, basis_file: str = "", offered=(),
                  meta: dict | None = None, storage: str = "float32") -> None:
    """Write a residual file atomically.

    Parameters
    ----------
    nets
        ``[(ResidualConfig, state)]``, state the network's tensors by name (NumPy arrays or
        torch tensors).
    basis_digest, basis_file
        The SHA-256 of the basis it corrects, and the name of that file (beside this one).
    offered
        The sizes ``encode`` offers it at (``()``: all it serves).
    storage
        One of :data:`STORAGES`.
    """
    from brdfkit.io.tensorfile import write_safetensors

    if storage not in STORAGES:
        raise ValueError(f"residual storage {storage!r}: one of {', '.join(STORAGES)}")
    tensors = {}
    for i, (_, state) in enumerate(nets):
        tensors.update(_store(i, state, storage))
    header = {"format": RESIDUAL_FORMAT, "version": RESIDUAL_VERSION, "storage": storage,
              "configs": json.dumps([json.loads(cfg.to_json()) for cfg, _ in nets]),
              "basis_digest": basis_digest, "basis_file": os.path.basename(basis_file),
              "offered": json.dumps(sorted(int(s) for s in offered)),
              "meta": json.dumps(meta or {}, sort_keys=True, default=str)}
    with atomic_path(path, verify=read_networks) as tmp:
        write_safetensors(tmp, tensors, header)


def read_header(path: str | os.PathLike) -> dict:
    """The header of a residual file, checked (:class:`FormatError` otherwise)."""
    from brdfkit.io.tensorfile import open_safetensors

    path = check_input_file(path)
    with open_safetensors(path, framework="numpy", diagnose="brdfkit residual file") as f:
        meta = dict(f.metadata() or {})
    if meta.get("format") != RESIDUAL_FORMAT:
        raise FormatError(path, f"not a basis-residual file (format {meta.get('format')!r}, "
                                f"expected {RESIDUAL_FORMAT!r})")
    if meta.get("version") != RESIDUAL_VERSION:
        raise FormatError(path, f"residual file version {meta.get('version')!r} is not supported "
                                f"(this brdfkit reads version {RESIDUAL_VERSION})")
    digest = meta.get("basis_digest", "")
    if len(digest) != 64 or set(digest) - _HEX:
        raise FormatError(path, "'basis_digest' must be a SHA-256 hex digest")
    return meta


def _configs(path: str, meta: dict) -> list:
    """The networks' configs a header records, checked: a network of sparse fits (a config
    field of :data:`~brdfkit.residual.network.LEFT_FIELDS`) is refused in one line."""
    try:
        raw = json.loads(meta.get("configs", ""))
        left = sorted({k for d in raw if isinstance(d, dict) for k in d if k in LEFT_FIELDS and d[k]})
        if not left:
            cfgs = [ResidualConfig(**{k: v for k, v in d.items() if k not in LEFT_FIELDS}) for d in raw]
    except (ValueError, TypeError) as e:
        raise FormatError(path, f"bad residual header ({e})") from None
    if left:
        raise FormatError(path, f"holds a network of sparse fits ({', '.join(left)}: brdfkit fit --method correction), "
                                f"which brdfkit no longer reads (it left on 2026-12-01: docs/notes/generalisation.md); "
                                f"use a residual of `brdfkit fit --method residual`")
    if not cfgs:
        raise FormatError(path, "a residual file holds at least one network")
    return cfgs


def _basis_file(path: str, meta: dict) -> str:
    """The basis file the residual corrects: the one its header names beside it, else the
    installed built-in part of its digest."""
    from brdfkit.io.digest import cached_file_digest

    want = meta["basis_digest"]
    beside = os.path.join(os.path.dirname(os.path.abspath(path)), meta.get("basis_file") or "")
    if meta.get("basis_file") and os.path.isfile(beside) and cached_file_digest(beside) == want:
        return beside
    from brdfkit.models.builtin import find_by_digest

    found = find_by_digest(want)
    if found is None:
        raise InputError(f"{path}: the basis it corrects ({meta.get('basis_file') or want[:12]}) is neither beside "
                         f"it nor an installed built-in's")
    return found


def _find_basis(path: str, meta: dict, basis):
    """The basis the residual corrects: ``basis`` (``(PcaBasis, digest)``) if given, else
    loaded from :func:`_basis_file`."""
    from brdfkit.basis.basis_file import load_basis

    if basis is not None:
        obj, digest = basis
        if digest != meta["basis_digest"]:
            raise InputError(f"{path}: corrects basis {meta['basis_digest'][:12]}, not the given basis {digest[:12]}")
        return obj
    return load_basis(_basis_file(path, meta))


def read_offer(path: str | os.PathLike) -> tuple[tuple, int]:
    """``(sizes, members)`` a residual file offers ``encode``, from its header and its
    basis's alone (no weights loaded): the sizes :meth:`BasisResidual.sizes` gives once it
    is loaded, and the most members (:class:`~brdfkit.residual.network.ResidualConfig`)
    any of them has.

    Raises
    ------
    FormatError, InputError
        As :func:`load_residual`.
    """
    from brdfkit.basis.basis_file import read_components

    path = os.fspath(path)
    meta = read_header(path)
    cfgs = _configs(path, meta)
    try:
        offered = tuple(int(s) for s in json.loads(meta.get("offered", "[]")))
    except (ValueError, TypeError) as e:
        raise FormatError(path, f"bad residual header ({e})") from None
    sizes = offered_sizes(components_of(cfgs, read_components(_basis_file(path, meta))), offered)
    members = max((len({c.member for c in cfgs if c.k_min <= s // 3 <= c.k_max}) for s in sizes), default=0)
    return sizes, members


def load_residual(path: str | os.PathLike, basis=None) -> BasisResidual:
    """Read a residual file and the basis it corrects (``basis``: ``(PcaBasis, digest)``
    already loaded; default: found by its digest beside it or among the built-ins).
    Nothing is unpickled, and no torch is imported.

    Raises
    ------
    FormatError
        Not a residual file, another version, a bad config or tensors the configs do
        not give.
    InputError
        The basis it corrects is not found, or is not the given one.
    """
    path = os.fspath(path)
    meta, nets, offered, record = read_networks(path)
    return BasisResidual(_find_basis(path, meta, basis), meta["basis_digest"], nets, offered, record)


def read_networks(path: str | os.PathLike) -> tuple[dict, list, tuple, dict]:
    """``(header, [(ResidualConfig, state)], offered sizes, meta record)`` of a residual
    file, every tensor checked against its network's config: the file's schema, without
    the basis it corrects (what :func:`save_residual` reads back before it writes).

    Raises
    ------
    FormatError
        As :func:`load_residual`.
    """
    from brdfkit.io.tensorfile import open_safetensors

    path = os.fspath(path)
    meta = read_header(path)
    cfgs = _configs(path, meta)
    try:
        offered = tuple(int(s) for s in json.loads(meta.get("offered", "[]")))
        record = json.loads(meta.get("meta", "{}"))
    except (ValueError, TypeError) as e:
        raise FormatError(path, f"bad residual header ({e})") from None
    with open_safetensors(path, framework="numpy", diagnose="brdfkit residual file") as f:
        raw = {k: f.get_tensor(k) for k in f.keys()}
    nets = [(cfg, _net_state(path, raw, i, cfg)) for i, cfg in enumerate(cfgs)]
    extra = sorted(k for k in raw if not k.startswith(tuple(f"net{i}." for i in range(len(cfgs)))))
    if extra:
        raise FormatError(path, f"tensors {extra[:3]} belong to no network of the file")
    return meta, nets, offered, record


def _net_state(path: str, raw: dict, i: int, cfg: ResidualConfig) -> dict:
    """Network ``i``'s tensors as float32, dequantized, checked against its config."""
    from brdfkit.basis.storage import dequantize

    total = sum(int(np.prod(s)) for s in hyponet_shapes(cfg.width))
    want = {"body.0.weight": (cfg.hidden, cfg.inputs), "body.0.bias": (cfg.hidden,),
            "body.2.weight": (cfg.hidden, cfg.hidden), "body.2.bias": (cfg.hidden,),
            "head.weight": (total, cfg.hidden), "head.bias": (total,),
            **{f"base.{j}": s for j, s in enumerate(hyponet_shapes(cfg.width))}}
    state = {}
    for k, shape in want.items():
        name = f"net{i}.{k}"
        if name not in raw:
            raise FormatError(path, f"tensor {name} is missing: the residual config needs it")
        a = raw[name]
        if a.dtype == np.int8 and f"{name}.scale" in raw:
            a = dequantize(a, raw[f"{name}.scale"])
        a = np.asarray(a, np.float32)
        if tuple(a.shape) != tuple(shape) or not np.isfinite(a).all():
            raise FormatError(path, f"tensor {name} has shape {tuple(a.shape)} or non-finite values; the "
                                    f"config needs {tuple(shape)}")
        state[k] = a
    return state
