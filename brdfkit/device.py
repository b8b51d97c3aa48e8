"""The torch device a computation runs on: one rule for the whole library.

``None`` or ``"auto"`` picks CUDA when a GPU is present, else the CPU; ``"cpu"``,
``"cuda"`` and ``"cuda:N"`` (or a ``torch.device``) name one. A CUDA device asked for on a
machine without one is refused with a one-line :class:`~brdfkit.errors.InputError`
rather than failing later inside torch. torch is imported on first use only.
"""

from __future__ import annotations

from .errors import InputError

__all__ = ["resolve_device"]


def resolve_device(device=None, *, local_rank: int | None = None):
    """The ``torch.device`` for a device option.

    Parameters
    ----------
    device
        ``None`` / ``"auto"`` (CUDA when available, else CPU), ``"cpu"``, ``"cuda"``,
        ``"cuda:N"``, or a ``torch.device``.
    local_rank
        Under ``torchrun``: this process's local rank, so that a bare ``"cuda"`` (or
        ``"auto"`` on a GPU machine) gives each process its own GPU,
        ``cuda:(local_rank mod GPUs)``.

    Returns
    -------
    torch.device

    Raises
    ------
    InputError
        CUDA asked for without a CUDA device, or a device that is not CPU or CUDA.
    """
    import torch

    name = "auto" if device is None else str(device)
    if name == "auto":
        name = "cuda" if torch.cuda.is_available() else "cpu"
    if name.startswith("cuda"):
        if not torch.cuda.is_available():
            raise InputError(f"device {name!r}: no CUDA device is available (use --device cpu or auto)")
        if name == "cuda" and local_rank is not None:
            name = f"cuda:{local_rank % torch.cuda.device_count()}"
        try:
            return torch.device(name)
        except RuntimeError:
            raise InputError(f"device {name!r}: not a CUDA device name (cuda or cuda:N)") from None
    if name != "cpu":
        raise InputError(f"device {name!r}: use auto, cpu or cuda")
    return torch.device("cpu")
