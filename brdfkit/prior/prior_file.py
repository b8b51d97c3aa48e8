"""The learnt-prior model file (format ``brdfkit-prior``): safetensors, never pickle.

One file holds the network's weights (``net.*``) and its basis, either inside
(``basis.*`` tensors and metadata, as :func:`brdfkit.basis.basis_file.basis_tensors` writes them) or in a
basis file beside it (metadata ``basis_file``, a bare name, and ``basis_digest``, the
sha256 of that file), so that the built-in models trained on one basis ship it once.
Metadata ``config`` is the :class:`~brdfkit.prior.model.PriorConfig` as JSON and
``digest`` the sha256 of the weights, the basis and that config (the likelihood in
it changes what the model reconstructs), checked on loading. Files written before the
config held a likelihood (no ``weight`` in it) carry the digest of the weights and
the basis alone, and are read as they were.
"""

from __future__ import annotations

import hashlib
import json
import os

import numpy as np

from brdfkit.atomic import atomic_path, check_input_file
from brdfkit.io.digest import file_digest
from brdfkit.models.parts import HEADER_DIGEST_KEY
from brdfkit.errors import FormatError, InputError
from brdfkit.basis import basis_tensors, load_basis, read_basis, save_basis, storage_of
from brdfkit.prior.model import PriorConfig, PriorModel, PriorWeights

__all__ = ["PRIOR_FORMAT", "PRIOR_VERSION", "save_prior", "load_prior", "is_prior_file", "pack_prior", "basis_entry"]

PRIOR_FORMAT = "brdfkit-prior"
PRIOR_VERSION = "1"


def _digest(tensors: dict) -> str:
    h = hashlib.sha256()
    for k in sorted(tensors):
        a = np.ascontiguousarray(tensors[k])
        h.update(k.encode() + b"\0" + str(a.dtype).encode() + b"\0" + repr(a.shape).encode())
        h.update(a.tobytes())
    return h.hexdigest()


def _content_digest(net_digest: str, basis_digest: str, config: str) -> str:
    """sha256 hex of the network, the basis and the config JSON; without ``weight`` in
    the config (files from before the likelihood options) of the first two only."""
    legacy = "weight" not in json.loads(config)
    return hashlib.sha256((net_digest + basis_digest + ("" if legacy else "\0" + config)).encode()).hexdigest()


def save_prior(path: str | os.PathLike, model: PriorModel, *, half: bool = False, phi_stride: int = 1,
               int8: bool = False, deflate: bool = False, basis_file: str | None = None) -> str:
    """Write ``model`` atomically; returns its digest.

    Parameters
    ----------
    half, phi_stride, int8, deflate
        How the basis is stored (:func:`~brdfkit.basis.basis_file.basis_tensors`); the network stays float32
        (it is 60k numbers).
    basis_file
        A bare file name: the basis goes into that file beside ``path`` (written when it
        does not exist, else checked to hold the same basis) instead of inside.
    """
    from brdfkit.io.tensorfile import write_safetensors

    path = os.fspath(path)
    net = {f"net.{k}": v for k, v in PriorWeights.of(model.net, model.cfg).state_dict().items()}
    meta = {"format": PRIOR_FORMAT, "version": PRIOR_VERSION,
            "config": json.dumps(model.cfg.record(), sort_keys=True)}
    meta.update({k: json.dumps(v) for k, v in model.meta.items()})
    if basis_file is None:
        btens, bmeta = basis_tensors(model.basis, half=half, phi_stride=phi_stride, int8=int8, deflate=deflate,
                                     prefix="basis.", where=path)
        tensors = {**net, **btens}
        meta.update(bmeta)
        basis_digest = _digest(btens)
    else:
        if os.path.basename(basis_file) != basis_file:
            raise InputError(f"basis_file {basis_file!r}: give a bare file name (it lives beside the model)")
        where = os.path.join(os.path.dirname(os.path.abspath(path)), basis_file)
        if not os.path.exists(where):
            save_basis(where, model.basis, half=half, phi_stride=phi_stride, int8=int8, deflate=deflate)
        else:  # shared with another model: it must be this model's basis as stored
            other = load_basis(where)
            same = (np.array_equal(other.cells, model.basis.cells)
                    and np.array_equal(other.components, model.basis.components))
            if not same and (half or phi_stride != 1):  # the file holds it rounded: compare as stored
                how = dict(half=half, phi_stride=phi_stride, int8=int8, deflate=deflate)
                same = _digest(basis_tensors(other, **how)[0]) == _digest(basis_tensors(model.basis, **how)[0])
            if not same:
                raise InputError(f"{where}: holds another basis than this model's")
        tensors = net
        basis_digest = file_digest(where)
        meta.update(basis_file=basis_file, basis_digest=basis_digest)
    digest = _content_digest(_digest(net), basis_digest, meta["config"])
    meta[HEADER_DIGEST_KEY] = digest
    with atomic_path(path, verify=lambda tmp: load_prior(tmp, "cpu")) as tmp:
        write_safetensors(tmp, tensors, meta)
    return digest


def is_prior_file(path: str | os.PathLike) -> bool:
    """Whether ``path`` is a safetensors file of format ``brdfkit-prior`` (header only)."""
    from brdfkit.io.tensorfile import open_safetensors

    try:
        with open_safetensors(os.fspath(path)) as f:
            return (f.metadata() or {}).get("format") == PRIOR_FORMAT
    except (FormatError, InputError, OSError):  # a missing file or a folder is no prior file
        return False


def basis_entry(path: str | os.PathLike) -> dict:
    """The manifest part of the basis file a learnt prior keeps beside it
    (:mod:`brdfkit.models.builtin`): ``{"basis": {"file": name, "digest": sha256}}``, or
    ``{}`` for a prior that holds its basis inside (header only)."""
    from brdfkit.io.tensorfile import open_safetensors

    with open_safetensors(os.fspath(path)) as f:
        meta = f.metadata() or {}
    return {"basis": {"file": meta["basis_file"], "digest": meta["basis_digest"]}} if "basis_file" in meta else {}


def load_prior(path: str | os.PathLike, device=None) -> PriorModel:
    """Read a learnt-prior model file: its network as :class:`~brdfkit.prior.model.PriorWeights`
    (NumPy, no torch: its work is a few small solves; ``device`` is not used).

    Raises
    ------
    FormatError
        Not such a file, a missing or changed basis file, inconsistent tensors, or
        weights that do not match the recorded digest.
    """
    from brdfkit.io.tensorfile import check_format, open_safetensors

    path = check_input_file(path)
    with open_safetensors(path, diagnose="brdfkit learnt-prior model file") as f:
        meta = check_format(path, f, PRIOR_FORMAT, PRIOR_VERSION, "brdfkit learnt-prior model", "learnt-prior model")
        try:
            cfg = PriorConfig(**json.loads(meta.get("config", "")))
        except (TypeError, ValueError):
            raise FormatError(path, "learnt-prior model metadata 'config' is not a valid configuration") from None
        net_t = {k: f.get_tensor(k) for k in f.keys() if k.startswith("net.")}
        if "basis_file" in meta:
            name = meta["basis_file"]
            if os.path.basename(name) != name:
                raise FormatError(path, f"basis_file {name!r} is not a bare file name")
            where = os.path.join(os.path.dirname(os.path.abspath(path)), name)
            if not os.path.isfile(where):
                raise FormatError(path, f"its basis file {name} is missing beside it")
            basis_digest = file_digest(where)
            if basis_digest != meta.get("basis_digest"):
                raise FormatError(path, f"its basis file {name} is not the one it was saved with (digest differs)")
            basis = load_basis(where)
        else:
            basis = read_basis(f, path, prefix="basis.")
            basis_digest = _digest({k: f.get_tensor(k) for k in f.keys() if k.startswith("basis.")})
    if _content_digest(_digest(net_t), basis_digest, meta["config"]) != meta.get(HEADER_DIGEST_KEY):
        raise FormatError(path, "the weights or the config do not match the recorded digest: "
                                "the file is damaged")
    if basis.n_components != cfg.n_components:
        raise FormatError(path, f"the basis has {basis.n_components} components, the network expects "
                                f"{cfg.n_components}")
    try:
        net = PriorWeights(cfg, {k[4:]: v for k, v in net_t.items()})
    except ValueError:
        raise FormatError(path, "the network's tensors do not match its configuration") from None
    if not all(np.isfinite(a).all() for a in net.state_dict().values()):
        raise FormatError(path, "the network holds non-finite weights")
    record = {}
    for k, v in meta.items():
        if k in ("materials", "steps", "budget", "wall_time_s", "command", "seed", "training"):
            try:
                record[k] = json.loads(v)
            except ValueError:
                record[k] = v
    return PriorModel(basis, net, cfg, record, meta[HEADER_DIGEST_KEY])


def pack_prior(src: str | os.PathLike, dst: str | os.PathLike, basis_file: str) -> str:
    """Re-save a learnt-prior model for shipping with its basis in the shared file
    ``basis_file`` beside ``dst``, stored as the source stores it (so the model is the
    same to the bit). Returns the packed file's digest (for the manifest)."""
    from brdfkit.io.tensorfile import open_safetensors

    model = load_prior(src)
    src = os.fspath(src)
    with open_safetensors(src) as f:
        meta = f.metadata() or {}
    if "basis_file" in meta:
        with open_safetensors(os.path.join(os.path.dirname(os.path.abspath(src)), meta["basis_file"])) as f:
            meta = {f"basis.{k}": v for k, v in (f.metadata() or {}).items()}
    storage = storage_of(meta, "basis.")
    return save_prior(dst, model, basis_file=basis_file, **storage)
