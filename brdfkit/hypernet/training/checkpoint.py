"""Training checkpoints: ``<model>.ckpt``, brdfkit's own resumable training state.

A checkpoint is written with ``torch.save`` (atomically: temporary file, then rename) and
read back with ``torch.load(weights_only=True)``, which restores only tensors and plain
containers and never runs pickled code. It holds:

* ``format = "brdfkit-checkpoint"``, ``version``;
* ``step`` (steps done), ``elapsed`` (training seconds so far, over all runs),
  ``skipped`` (steps skipped for a non-finite loss), ``loss_ema``, ``resumed_from``
  (the step each earlier ``--resume`` started from, oldest first; recorded in the
  model's ``meta.resumed_from_steps``);
* ``net`` (the model's ``state_dict``) and ``optimizer`` (Adam's ``state_dict``);
* the identity of the run, checked on resume: ``config`` (HyperConfig JSON), ``options``
  (the sampling and optimiser settings, JSON), ``materials``, ``data_digest``, ``seed``,
  ``world_size``, ``reference_from`` (the weights digest of the model whose
  reference table the run trains against, ``fit(reference=...)``; ``None``: the median
  of the training materials; absent in checkpoints from before that option, read as
  ``None``; :meth:`brdfkit.hypernet.training.dataset.GivenReference.check_resumable`).

There is no random-generator state to save: the batch sampler re-seeds from
``(seed, rank, step)`` at every step (:class:`brdfkit.hypernet.training.dataset.BatchSampler`), so the
step counter is the whole state of the randomness.
"""

from __future__ import annotations

import os

from brdfkit.atomic import atomic_path
from brdfkit.errors import FormatError, InputError

__all__ = ["CHECKPOINT_FORMAT", "CHECKPOINT_VERSION", "checkpoint_path", "save_checkpoint",
           "load_checkpoint", "check_resumable"]

CHECKPOINT_FORMAT = "brdfkit-checkpoint"
CHECKPOINT_VERSION = 1


def checkpoint_path(output: str | os.PathLike) -> str:
    """The checkpoint beside a model output: ``<output>.ckpt``."""
    return os.fspath(output) + ".ckpt"


def save_checkpoint(path: str | os.PathLike, state: dict) -> None:
    """Write ``state`` (see the module docstring) atomically."""
    import torch

    state = dict(state, format=CHECKPOINT_FORMAT, version=CHECKPOINT_VERSION)
    with atomic_path(path) as tmp:
        torch.save(state, tmp)


def load_checkpoint(path: str | os.PathLike, device="cpu") -> dict:
    """Read a checkpoint written by :func:`save_checkpoint`; nothing is unpickled beyond
    tensors and plain containers (``weights_only=True``).

    Raises
    ------
    InputError
        No such file.
    FormatError
        Not a brdfkit checkpoint, damaged, or another version.
    """
    import pickle
    import zipfile

    import torch

    path = os.fspath(path)
    if not os.path.exists(path):
        raise InputError(f"{path}: no checkpoint to resume from (run without --resume to start afresh)")
    try:
        state = torch.load(path, map_location=device, weights_only=True)
    except (pickle.UnpicklingError, zipfile.BadZipFile, RuntimeError, EOFError, ValueError,
            AttributeError, TypeError) as e:
        first = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        raise FormatError(path, f"not a readable brdfkit checkpoint ({first[:200]})") from None
    if not isinstance(state, dict) or state.get("format") != CHECKPOINT_FORMAT:
        raise FormatError(path, "not a brdfkit checkpoint")
    if state.get("version") != CHECKPOINT_VERSION:
        raise FormatError(path, f"checkpoint version {state.get('version')!r} is not supported "
                                f"(this brdfkit writes version {CHECKPOINT_VERSION})")
    missing = [k for k in ("step", "net", "optimizer", "config", "options", "materials",
                           "data_digest", "seed") if k not in state]
    if missing:
        raise FormatError(path, f"checkpoint lacks {', '.join(missing)}")
    return state


def check_resumable(path: str, state: dict, *, config: str, options: str, materials: list,
                    seed: int, data_digest: str | None = None) -> None:
    """Refuse to resume a checkpoint made for another run, saying what differs.

    ``data_digest=None`` skips the content check, so that everything else can be checked
    before the (slow) reading of the data.

    Raises
    ------
    InputError
        Naming the checkpoint and the first difference (materials, their content, model
        configuration, training options or seed).
    """
    hint = "; train afresh without --resume, or give the same data and options"
    if list(state["materials"]) != list(materials):
        old, new = set(state["materials"]), set(materials)
        parts = []
        if new - old:
            parts.append(f"new: {', '.join(sorted(new - old)[:4])}")
        if old - new:
            parts.append(f"missing: {', '.join(sorted(old - new)[:4])}")
        detail = "; ".join(parts) or "same names, different order"
        raise InputError(f"{path}: checkpoint was trained on other materials "
                         f"({len(old)} then, {len(new)} now; {detail}){hint}")
    if data_digest is not None and state["data_digest"] != data_digest:
        raise InputError(f"{path}: checkpoint was trained on files with the same names but "
                         f"different content (the reference table differs){hint}")
    if state["config"] != config:
        raise InputError(f"{path}: checkpoint has another model configuration "
                         f"({state['config']} vs {config}){hint}")
    if state["options"] != options:
        raise InputError(f"{path}: checkpoint has other training options "
                         f"({state['options']} vs {options}){hint}")
    if int(state["seed"]) != int(seed):
        raise InputError(f"{path}: checkpoint was trained with seed {state['seed']}, not {seed}{hint}")
