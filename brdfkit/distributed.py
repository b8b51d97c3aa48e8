"""The processes of a training run: the ``torchrun`` process group and stop signals.

Under ``torchrun`` (``WORLD_SIZE > 1``) :class:`ProcessGroup` joins the
``torch.distributed`` group (NCCL on CUDA, Gloo on the CPU) and gives each process its
device (:func:`brdfkit.runtime.resolve_device` with the local rank); alone it is a group of
one and every collective is a no-op. :class:`StopSignals` turns Ctrl-C / SIGTERM into a
request that training honours between steps, so the checkpoint it saves is consistent.
"""

from __future__ import annotations

import os
import signal
import threading

from brdfkit.runtime import resolve_device
from brdfkit.errors import TrainingError

__all__ = ["ProcessGroup", "StopSignals"]


class ProcessGroup:
    """The torch.distributed process group when launched by ``torchrun`` (``WORLD_SIZE > 1``)."""

    def __init__(self, device):
        import datetime

        import torch.distributed as dist

        self.dist = dist
        self.world = int(os.environ.get("WORLD_SIZE", "1"))
        self.rank = int(os.environ.get("RANK", "0"))
        local = int(os.environ.get("LOCAL_RANK", "0"))
        self.device = resolve_device(device, local_rank=local)
        if self.device.type == "cuda":
            import torch

            torch.cuda.set_device(self.device)
        self.owned = False
        if self.world > 1:
            if not dist.is_available():
                raise TrainingError("WORLD_SIZE > 1 but this torch build has no torch.distributed")
            if not dist.is_initialized():
                backend = "nccl" if self.device.type == "cuda" else "gloo"
                dist.init_process_group(backend, timeout=datetime.timedelta(minutes=30))
                self.owned = True
            self.rank, self.world = dist.get_rank(), dist.get_world_size()

    @property
    def active(self) -> bool:
        return self.world > 1

    def sum_(self, t):
        if self.active:
            self.dist.all_reduce(t, op=self.dist.ReduceOp.SUM)
        return t

    def gather_hex(self, hexdigest: str) -> list[str]:
        """Every rank's sha256 hex digest (to check that ranks agree)."""
        if not self.active:
            return [hexdigest]
        import torch

        mine = torch.tensor(list(bytes.fromhex(hexdigest)), dtype=torch.int64, device=self.device)
        out = [torch.empty_like(mine) for _ in range(self.world)]
        self.dist.all_gather(out, mine)
        return [bytes(t.cpu().tolist()).hex() for t in out]

    def barrier(self):
        if self.active:
            self.dist.barrier()

    def close(self):
        if self.owned and self.dist.is_initialized():
            self.dist.destroy_process_group()


class StopSignals:
    """Turns SIGINT / SIGTERM during training into a request honoured between steps (so
    the checkpoint holds a consistent state); a second signal interrupts at once."""

    def __init__(self):
        self.requested = False
        self._old = {}

    def _handler(self, signum, frame):
        if self.requested:
            raise KeyboardInterrupt
        self.requested = True

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                self._old[sig] = signal.signal(sig, self._handler)
        return self

    def __exit__(self, *exc):
        for sig, old in self._old.items():
            signal.signal(sig, old)
        return False
