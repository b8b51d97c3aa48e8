"""Model files: one ``.safetensors`` file holding a trained hypernetwork.

A model file (``docs/formats.md``, "Model files") holds, with no pickled Python at all:

* every tensor of ``HyperBRDF.state_dict()`` as float32, named ``net.<state_dict name>``;
* ``rho_ref``: the reference table of the log-relative mapping (Gokbudak et al. 2024,
  eq. 1), float32 ``(90, 90, 180, 3)`` in 1/sr, NaN where no training material is
  measured;
* string metadata: ``format = "brdfkit-model"``, ``version = "1"``, ``config`` (the
  :class:`~brdfkit.model.network.HyperConfig` as JSON), ``fingerprint`` (see
  :func:`weights_fingerprint`), ``mapping`` (JSON, the mapping the model was trained
  with: :func:`brdfkit.mapping.mapping_record`, ``eps = 0.002``) and ``meta`` (JSON:
  training materials, steps, ...). Files written before ``mapping`` was recorded were
  all trained with the paper's mapping, which is assumed when it is absent.

The fingerprint identifies the weights: an embedding records the fingerprint of the model
that made it, and decoding it with another model is refused
(:class:`~brdfkit.errors.ModelMismatchError`). Loading recomputes it, so a file whose
weights were altered or damaged is refused too.
"""

from __future__ import annotations

import hashlib
import json
import os

import numpy as np

from ..atomic import atomic_path
from ..device import resolve_device
from ..errors import FormatError
from ..geometry import TABLE_SHAPE
from ..mapping import mapping_record
from ..tensorfile import check_format, open_safetensors
from .loaded import NeuralModel

__all__ = ["MODEL_FORMAT", "MODEL_VERSION", "save_model", "load_model", "weights_fingerprint"]

MODEL_FORMAT = "brdfkit-model"
MODEL_VERSION = "1"
_PREFIX = "net."
_MERL_HINT = " (-m takes the .safetensors file written by `brdfkit fit`)"


def _unwrap(net):
    """The bare network inside DDP / ``torch.compile`` wrappers (whose state_dict names
    carry a prefix)."""
    while not hasattr(net, "cfg") and (hasattr(net, "module") or hasattr(net, "_orig_mod")):
        net = getattr(net, "module", None) or getattr(net, "_orig_mod")
    return net


def weights_fingerprint(net) -> str:
    """sha256 hex of a network's weights.

    For each name of ``net.state_dict()`` in sorted order: the UTF-8 name, then the
    tensor's float32 bytes (C order, native little-endian). Independent of device and of
    how the tensors are laid out in memory.
    """
    h = hashlib.sha256()
    sd = _unwrap(net).state_dict()
    for name in sorted(sd):
        h.update(name.encode())
        h.update(sd[name].detach().cpu().float().contiguous().numpy().tobytes())
    return h.hexdigest()


def save_model(path: str | os.PathLike, net, rho_ref: np.ndarray, meta: dict | None = None,
               mapping: dict | None = None) -> str:
    """Write a model file atomically.

    Parameters
    ----------
    path
        Output ``.safetensors`` file.
    net
        :class:`~brdfkit.model.network.HyperBRDF` on any device; a DDP (``.module``) or
        ``torch.compile`` (``._orig_mod``) wrapper is unwrapped.
    rho_ref
        ``(90, 90, 180, 3)`` reference table, 1/sr, NaN where unmeasured.
    meta
        JSON-serialisable provenance (training materials, steps, ...).
    mapping
        The mapping the network was trained with; default
        :func:`brdfkit.mapping.mapping_record` (the only one brdfkit trains with).

    Returns
    -------
    str
        The weights fingerprint written into the file.
    """
    import torch
    from safetensors.torch import save_file

    net = _unwrap(net)
    ref = np.ascontiguousarray(rho_ref, dtype=np.float32)
    if ref.shape != TABLE_SHAPE:
        raise ValueError(f"reference table must have shape {TABLE_SHAPE}, not {ref.shape}")
    tensors = {_PREFIX + name: t.detach().cpu().float().contiguous().clone()
               for name, t in net.state_dict().items()}
    tensors["rho_ref"] = torch.from_numpy(ref.copy())
    fingerprint = weights_fingerprint(net)
    metadata = {
        "format": MODEL_FORMAT,
        "version": MODEL_VERSION,
        "config": net.cfg.to_json(),
        "fingerprint": fingerprint,
        "mapping": json.dumps(mapping or mapping_record(), sort_keys=True),
        "meta": json.dumps(meta or {}, sort_keys=True, default=str),
    }
    with atomic_path(path) as tmp:
        save_file(tensors, tmp, metadata=metadata)
    return fingerprint


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


def load_model(path: str | os.PathLike, device=None) -> NeuralModel:
    """Load a model file written by :func:`save_model`; nothing is unpickled.

    Parameters
    ----------
    path
        The ``.safetensors`` file.
    device
        ``torch.device`` or string; ``None``: CUDA when available, else CPU.

    Returns
    -------
    NeuralModel

    Raises
    ------
    FormatError
        Not a safetensors file (a pickle, truncated, other content), another kind of
        safetensors file, an unknown version, a bad config, a mapping other than
        brdfkit's, missing or misshapen tensors, or weights that do not match the
        recorded fingerprint. One line naming the file.
    """
    import torch

    from .network import HyperBRDF, HyperConfig

    path = os.fspath(path)
    with open_safetensors(path, framework="pt", diagnose="brdfkit model file", merl_hint=_MERL_HINT) as f:
        md = check_format(path, f, MODEL_FORMAT, MODEL_VERSION, "brdfkit model file", "model file")
        try:
            cfg = HyperConfig.from_json(md["config"])
            meta = json.loads(md.get("meta") or "{}")
        except (KeyError, TypeError, ValueError) as e:
            raise FormatError(path, f"bad model config in metadata ({e})") from None
        if not isinstance(meta, dict):
            raise FormatError(path, "bad 'meta' in metadata: not a JSON object")
        mapping = _read_mapping(path, md.get("mapping"))
        names = set(f.keys())
        if "rho_ref" not in names:
            raise FormatError(path, "missing tensor 'rho_ref' (the reference table)")
        ref = f.get_tensor("rho_ref")
        state = {n[len(_PREFIX):]: f.get_tensor(n) for n in names if n.startswith(_PREFIX)}
    if tuple(ref.shape) != TABLE_SHAPE:
        raise FormatError(path, f"reference table has shape {tuple(ref.shape)}, expected {TABLE_SHAPE}")
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
    fingerprint = weights_fingerprint(net)
    recorded = md.get("fingerprint")
    if recorded != fingerprint:
        raise FormatError(path, f"weights do not match the recorded fingerprint "
                                f"({str(recorded)[:12]} recorded, {fingerprint[:12]} computed): "
                                f"the file is damaged or was altered")
    dev = resolve_device(device)
    net = net.to(dev).eval()
    for p in net.parameters():
        p.requires_grad_(False)
    return NeuralModel(net=net, cfg=cfg, rho_ref=ref.numpy().astype(np.float32, copy=False),
                       fingerprint=fingerprint, meta=meta, device=dev, path=path, mapping=mapping)
