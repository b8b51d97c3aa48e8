"""Network files: one ``.safetensors`` file holding a trained hypernetwork.

A network file (``docs/formats.md``) holds, with no pickled Python at all:

* every tensor of ``HyperBRDF.state_dict()`` as float32 (or float16, ``half``), named
  ``net.<state_dict name>``;
* the reference table of the log-relative mapping (Gokbudak et al. 2024, eq. 1), in 1/sr,
  NaN where no training material is measured: in version 1 ``rho_ref``, dense float32
  ``(90, 90, 180, 3)``; in version 2 its measured cells only, in the file or in a shared
  reference file beside it (:mod:`brdfkit.hypernet.network_storage`);
* string metadata: ``format = "brdfkit-model"``, ``version = "1"`` or ``"2"``, ``config`` (the
  :class:`~brdfkit.hypernet.network.HyperConfig` as JSON), ``fingerprint`` (the
  weights' digest, :func:`weights_digest`; the key's name kept since format 1), ``mapping`` (JSON, the mapping the model was trained
  with: :func:`brdfkit.hypernet.mapping.mapping_record`, ``eps = 0.002``), ``meta`` (JSON:
  training materials, steps, ...) and, in version 2, ``reference`` (JSON: how the
  reference is stored and its digest). Files written before ``mapping`` was recorded
  were all trained with the paper's mapping, which is assumed when it is absent.

The digest identifies the weights: an embedding records the digest of the model
that made it, and decoding it with another model is refused
(:class:`~brdfkit.errors.ModelMismatchError`). Loading recomputes it, so a file whose
weights were altered or damaged is refused too.
"""

from __future__ import annotations

import hashlib
import json
import os

import numpy as np

from brdfkit.atomic import atomic_path
from brdfkit.runtime import resolve_device
from brdfkit.errors import FormatError
from brdfkit.geometry import TABLE_SHAPE
from brdfkit.hypernet.mapping import mapping_record
from brdfkit.io.tensorfile import check_format, open_safetensors
from brdfkit.models.parts import HEADER_DIGEST_KEY
from brdfkit.hypernet import network_storage as storage
from brdfkit.hypernet.loaded import LoadedNetwork

__all__ = ["MODEL_FORMAT", "MODEL_VERSION", "MODEL_VERSIONS", "save_network", "load_network", "read_latent_dim",
           "weights_digest", "state_digest"]

MODEL_FORMAT = "brdfkit-model"
# "1": dense float32 reference (what a plain save_network still writes, readable by every
# brdfkit); "2": compact or shared reference, float16 or float32 (save_network(compact=True)).
MODEL_VERSION = "2"
MODEL_VERSIONS = ("1", "2")
_PREFIX = "net."
_MERL_HINT = " (-m takes the .safetensors file written by `brdfkit fit`)"


def _unwrap(net):
    """The bare network inside DDP / ``torch.compile`` wrappers (whose state_dict names
    carry a prefix)."""
    while not hasattr(net, "cfg") and (hasattr(net, "module") or hasattr(net, "_orig_mod")):
        net = getattr(net, "module", None) or getattr(net, "_orig_mod")
    return net


def weights_digest(net) -> str:
    """sha256 hex of a network's weights: :func:`state_digest` of its state dict."""
    return state_digest(_unwrap(net).state_dict())


def state_digest(state: dict) -> str:
    """sha256 hex of a state dict.

    For each name in sorted order: the UTF-8 name, then the tensor's values as float32
    bytes (C order, native little-endian). Independent of device and of how the tensors
    are laid out in memory; a float16 tensor is hashed as the float32 it loads as, so a
    half-precision file has the digest of the network it loads into.
    """
    h = hashlib.sha256()
    for name in sorted(state):
        h.update(name.encode())
        h.update(state[name].detach().cpu().float().contiguous().numpy().tobytes())
    return h.hexdigest()


def save_network(path: str | os.PathLike, net, rho_ref: np.ndarray, meta: dict | None = None,
               mapping: dict | None = None, *, compact: bool = False, half: bool = False,
               reference_file: str | None = None) -> str:
    """Write a network file atomically.

    Parameters
    ----------
    path
        Output ``.safetensors`` file.
    net
        :class:`~brdfkit.hypernet.network.HyperBRDF` on any device; a DDP (``.module``) or
        ``torch.compile`` (``._orig_mod``) wrapper is unwrapped.
    rho_ref
        ``(90, 90, 180, 3)`` reference table, 1/sr, NaN where unmeasured.
    meta
        JSON-serialisable provenance (training materials, steps, ...).
    mapping
        The mapping the network was trained with; default
        :func:`brdfkit.hypernet.mapping.mapping_record` (the only one brdfkit trains with).
    compact
        Store the reference at its measured cells only (version 2 file; the default
        network's file shrinks from 24.4 to 20.5 MB). ``False``: the version 1 layout.
    half
        Store weights and reference as float16 (implies ``compact``; 10.3 MB). They load
        back as float32; the digest is that of the rounded weights, as loaded, so it
        differs from ``weights_digest(net)`` unless the weights were float16 values
        already, and saving the loaded model again (half or not) keeps it.
    reference_file
        A bare file name: keep the reference in this shared file beside ``path`` instead
        (implies ``compact``). Written when absent; when present it must hold the same
        reference, stored at the same precision: models share one when they were trained
        against the same reference table, whatever their materials (the median of the
        same materials, or one model's table given to the others, ``brdfkit fit -O
        reference=MODEL``, ``docs/training.md``).

    Returns
    -------
    str
        The weights digest written into the file.

    Raises
    ------
    ValueError
        A reference table of another shape; with ``half``, a value beyond float16's
        range; a ``reference_file`` that is a path, or that exists and holds another
        reference.
    """
    import torch
    from brdfkit.io.tensorfile import write_safetensors

    net = _unwrap(net)
    ref = np.ascontiguousarray(rho_ref, dtype=np.float32)
    if ref.shape != TABLE_SHAPE:
        raise ValueError(f"reference table must have shape {TABLE_SHAPE}, not {ref.shape}")
    state = {name: t.detach().cpu().float().contiguous().clone() for name, t in net.state_dict().items()}
    if half:
        state = storage.half_state(state)
    # Of the weights as load_network will see them (float16 rounded, back to float32): an
    # embedding made with the loaded model must name this file.
    net_digest = state_digest(state)
    tensors = {_PREFIX + name: t for name, t in state.items()}
    metadata = {
        "format": MODEL_FORMAT,
        "version": "1",
        "config": net.cfg.to_json(),
        HEADER_DIGEST_KEY: net_digest,
        "mapping": json.dumps(mapping or mapping_record(), sort_keys=True),
        "meta": json.dumps(meta or {}, sort_keys=True, default=str),
    }
    if not (compact or half or reference_file is not None):
        tensors["rho_ref"] = torch.from_numpy(ref.copy())
    else:
        mask, values = storage.pack_reference(ref, half)
        digest = storage.reference_digest(mask, values)
        if reference_file is None:
            tensors[storage.MASK] = torch.from_numpy(mask)
            tensors[storage.VALUES] = torch.from_numpy(values)
        else:
            _share_reference(path, reference_file, mask, values, digest, (meta or {}).get("materials") or ())
        metadata["version"] = "2"
        metadata["reference"] = storage.reference_record("cells" if reference_file is None else "file",
                                                         values, digest, reference_file)
    with atomic_path(path, verify=lambda tmp: load_network(tmp, "cpu")) as tmp:
        write_safetensors(tmp, tensors, metadata)
    return net_digest


def _share_reference(path, name: str, mask, values, digest: str, materials) -> None:
    """Write the shared reference file ``name`` beside ``path``, or check that the one
    there holds this reference."""
    if not name or os.path.basename(name) != name or name in (".", "..") or "/" in name or "\\" in name:
        raise ValueError(f"reference_file {name!r}: give a bare file name (it lives beside the model)")
    shared = os.path.join(os.path.dirname(os.path.abspath(os.fspath(path))), name)
    if os.path.exists(shared):
        if storage.read_shared_reference(shared)[2] != digest:
            raise ValueError(f"{shared} holds another reference table (models sharing one must be trained "
                             "against the same reference, e.g. with `brdfkit fit -O reference=MODEL`, "
                             "and saved with the same precision)")
        return
    storage.write_shared_reference(shared, mask, values, [str(m) for m in materials])


def _check_config_sizes(cfg, n_tensors: int, n_values: int) -> None:
    """Raise ``ValueError`` unless every size in ``cfg`` could fit a file of ``n_tensors``
    tensors holding ``n_values`` numbers: each layer adds a tensor, each width a weight."""
    def count(name, v, low, high):
        if isinstance(v, bool) or not isinstance(v, int):
            raise ValueError(f"{name} = {v!r} is not a whole number")
        if not low <= v <= high:
            raise ValueError(f"{name} = {v!r} does not fit the {n_tensors} tensors of "
                             f"{n_values} values in the file")

    hidden = cfg.encoder_hidden
    if not isinstance(hidden, tuple):
        raise ValueError(f"encoder_hidden = {hidden!r} is not a list of widths")
    count("len(encoder_hidden)", len(hidden), 0, n_tensors)
    count("hypo_layers", cfg.hypo_layers, 0, n_tensors)
    count("decoder_layers", cfg.decoder_layers, 0, n_tensors)
    for name, v in (("latent_dim", cfg.latent_dim), ("hypo_hidden", cfg.hypo_hidden),
                    ("decoder_hidden", cfg.decoder_hidden), *(("encoder_hidden", w) for w in hidden)):
        count(name, v, 1, n_values)


def _read_mapping(path: str, text) -> dict:
    """The ``mapping`` metadata entry, checked against the mapping brdfkit computes: a
    model decodes correctly only with the mapping it was trained with."""
    ours = mapping_record()
    if text is None:  # written before the entry existed: always the paper's mapping
        return ours
    try:
        rec = json.loads(text)
    except ValueError:
        raise FormatError(path, "bad 'mapping' in metadata: not JSON") from None
    eps = rec.get("eps") if isinstance(rec, dict) else None
    if isinstance(eps, bool) or not isinstance(eps, (int, float)) or not isinstance(rec.get("name"), str):
        raise FormatError(path, "bad 'mapping' in metadata: not an object with a name and a numeric eps")
    if rec["name"] != ours["name"] or eps != ours["eps"]:
        raise FormatError(path, f"the model was trained with the {rec['name']!r} mapping with eps = {eps:g}; "
                                f"this brdfkit maps with {ours['name']!r}, eps = {ours['eps']:g}")
    return rec


def _numpy(path: str, f, name: str) -> np.ndarray:
    t = f.get_tensor(name)
    try:
        return t.numpy()
    except TypeError:  # bfloat16 and the like: no NumPy dtype, and never written by brdfkit
        raise FormatError(path, f"tensor {name} is {t.dtype}, expected float16 or float32") from None


def _read_reference(path: str, f, md: dict, names: set) -> np.ndarray:
    """The reference table of an open network file: float32 ``(90, 90, 180, 3)``."""
    if md["version"] == "1":
        if "rho_ref" not in names:
            raise FormatError(path, "missing tensor 'rho_ref' (the reference table)")
        ref = _numpy(path, f, "rho_ref")
        if tuple(ref.shape) != TABLE_SHAPE:
            raise FormatError(path, f"reference table has shape {tuple(ref.shape)}, expected {TABLE_SHAPE}")
        return ref.astype(np.float32, copy=False)
    rec = storage.parse_reference_record(path, md.get("reference"))
    if rec["storage"] == "cells":
        for name in (storage.MASK, storage.VALUES):
            if name not in names:
                raise FormatError(path, f"missing tensor {name!r} (the reference table)")
        where, mask, values = path, _numpy(path, f, storage.MASK), _numpy(path, f, storage.VALUES)
        digest = storage.reference_digest(mask, values)
    else:
        where = os.path.join(os.path.dirname(path), rec["file"])
        if not os.path.isfile(where):
            raise FormatError(path, f"its shared reference table {rec['file']} is missing (it must lie "
                                    "beside the model file)")
        mask, values, digest = storage.read_shared_reference(where)
    if digest != rec["digest"]:
        raise FormatError(where, f"reference table does not match the digest recorded in {path}: the file "
                                 "is damaged, or is another model's")
    return storage.unpack_reference(where, mask, values)


def read_latent_dim(path: str | os.PathLike) -> int:
    """The latent size of a network file, from its header alone (its config's
    ``latent_dim``; no tensor is read, no torch imported), the file's format checked as
    :func:`load_network` checks it (the same one-line errors).

    Raises
    ------
    FormatError
        As :func:`load_network` for the header, or a config without a positive
        ``latent_dim``.
    """
    path = os.fspath(path)
    with open_safetensors(path, framework="numpy", diagnose="brdfkit model file", merl_hint=_MERL_HINT) as f:
        version = (f.metadata() or {}).get("version")
        md = check_format(path, f, MODEL_FORMAT, version if version in MODEL_VERSIONS else "1 or 2",
                          "brdfkit model file", "model file")
    try:
        latent = json.loads(md["config"])["latent_dim"]
    except (KeyError, TypeError, ValueError) as e:
        raise FormatError(path, f"bad model config in metadata ({e})") from None
    if isinstance(latent, bool) or not isinstance(latent, int) or latent < 1:
        raise FormatError(path, f"bad model config in metadata (latent_dim {latent!r})")
    return latent


def load_network(path: str | os.PathLike, device=None) -> LoadedNetwork:
    """Load a network file written by :func:`save_network`; nothing is unpickled.

    Parameters
    ----------
    path
        The ``.safetensors`` file.
    device
        ``torch.device`` or string; ``None``: CUDA when available, else CPU.

    Returns
    -------
    LoadedNetwork

    Raises
    ------
    FormatError
        Not a safetensors file (a pickle, truncated, other content), another kind of
        safetensors file, an unknown version, a bad config, a mapping other than
        brdfkit's, missing or misshapen tensors, weights that do not match the recorded
        digest, or a reference table (in the file or a shared file beside it) that
        is missing or does not match its recorded digest. One line naming the file.
    """
    import torch

    from brdfkit.hypernet.network import HyperBRDF, HyperConfig

    path = os.fspath(path)
    with open_safetensors(path, framework="pt", diagnose="brdfkit model file", merl_hint=_MERL_HINT) as f:
        version = (f.metadata() or {}).get("version")
        md = check_format(path, f, MODEL_FORMAT, version if version in MODEL_VERSIONS else "1 or 2",
                          "brdfkit model file", "model file")
        try:
            cfg = HyperConfig.from_json(md["config"])
            meta = json.loads(md.get("meta") or "{}")
        except (KeyError, TypeError, ValueError) as e:
            raise FormatError(path, f"bad model config in metadata ({e})") from None
        if not isinstance(meta, dict):
            raise FormatError(path, "bad 'meta' in metadata: not a JSON object")
        mapping = _read_mapping(path, md.get("mapping"))
        names = set(f.keys())
        ref = _read_reference(path, f, md, names)
        state = {n[len(_PREFIX):]: f.get_tensor(n) for n in names if n.startswith(_PREFIX)}
    # The config is checked against the file's own tensors before any network is built:
    # sizes bounded by them, then the shapes from a build on torch's "meta" device (no
    # memory). A crafted config (latent_dim = 10^7) took 37 s and 4.7 GB before being
    # refused, and decoder_hidden = 20000 x 30 layers exhausted memory (docs/stability.md).
    try:
        _check_config_sizes(cfg, len(state), sum(t.numel() for t in state.values()))
        with torch.device("meta"):
            expected = HyperBRDF(cfg).state_dict()
    except (TypeError, ValueError, RuntimeError) as e:
        raise FormatError(path, f"model config cannot be built ({e})") from None
    missing = sorted(set(expected) - set(state))
    extra = sorted(set(state) - set(expected))
    if missing or extra:
        what = f"missing tensor(s) {', '.join(missing[:3])}" if missing else \
            f"unexpected tensor(s) {', '.join(extra[:3])}"
        more = len(missing or extra) - 3
        raise FormatError(path, f"{what}{f' and {more} more' if more > 0 else ''} for its config")
    for name, t in expected.items():
        if tuple(state[name].shape) != tuple(t.shape):
            raise FormatError(path, f"tensor {_PREFIX}{name} has shape {tuple(state[name].shape)}, "
                                    f"the config needs {tuple(t.shape)}")
    try:
        net = HyperBRDF(cfg)
    except (TypeError, ValueError, RuntimeError) as e:
        raise FormatError(path, f"model config cannot be built ({e})") from None
    net.load_state_dict({k: v.float() for k, v in state.items()})
    digest = weights_digest(net)
    recorded = md.get(HEADER_DIGEST_KEY)
    if recorded != digest:
        raise FormatError(path, f"weights do not match the recorded digest "
                                f"({str(recorded)[:12]} recorded, {digest[:12]} computed): "
                                f"the file is damaged or was altered")
    dev = resolve_device(device)
    net = net.to(dev).eval()
    for p in net.parameters():
        p.requires_grad_(False)
    return LoadedNetwork(net=net, cfg=cfg, rho_ref=ref,
                       digest=digest, meta=meta, device=dev, path=path, mapping=mapping)
