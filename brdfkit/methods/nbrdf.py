"""The NBRDF baseline of Sztrajman, Rainer, Ritschel and Weyrich 2021, "Neural BRDF
Representation and Importance Sampling" (Computer Graphics Forum): one small MLP per
material, here fitted to the given sparse samples only, as the hypernetwork paper
(Gokbudak et al. 2024) compares it in the sparse setting.

Network (as published, and as the networks behind the reference proxies, ``docs/data.md``)::

    (hx, hy, hz, dx, dy, dz) -> 21 -> 21 -> 3,   ReLU, ReLU,   rho = max(exp(x) - 1, 0)

so the last layer predicts ``ln(1 + rho)`` per RGB channel, ``rho`` in 1/sr. The input is
the half and difference unit vectors with ``phi_h = 0`` (:func:`brdfkit.geometry.hd_vectors`).

Loss: NBRDF's mean absolute logarithmic error on cosine-weighted values::

    mean | ln(1 + rho_target cos_i) - ln(1 + rho_pred cos_i) |

over the samples and the three channels (``cos_i`` clamped at 0). Adam at a fixed
learning rate, full batch (mini-batches of :data:`BATCH` beyond that size, in a seeded
order), at most ``steps`` steps with early stopping: training ends when the loss over
all samples has not improved by a relative ``1e-4`` for ``patience`` steps, and the
best weights seen are kept. The initial weights and the batch order come from ``seed``
alone, so the same samples, seed and device give the same network.
"""

from __future__ import annotations

import copy
import dataclasses
import time

import numpy as np

from brdfkit.runtime import resolve_device
from brdfkit.errors import InputError
from brdfkit.geometry import GRID_SHAPE, N_CELLS, grid_hd, valid_cells
from brdfkit.runtime import torch_threads
from brdfkit.methods.method import Method, MethodOptions

__all__ = ["NbrdfModel", "NbrdfOptions", "fit_nbrdf", "METHOD", "DEFAULT_STEPS", "DEFAULT_LR",
           "DEFAULT_PATIENCE", "BATCH", "HIDDEN"]

HIDDEN = 21
DEFAULT_STEPS = 5000
DEFAULT_LR = 1e-3
DEFAULT_PATIENCE = 500
BATCH = 16384
_CHECK_EVERY = 10
# exp() of the last layer is capped here (rho < 1e13 1/sr) so that a network driven far
# outside its samples stays finite in float32 instead of overflowing to inf.
_MAX_LOG = 30.0


def _make_net(seed: int):
    import torch
    from torch import nn

    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(seed)
        return nn.Sequential(nn.Linear(6, HIDDEN), nn.ReLU(), nn.Linear(HIDDEN, HIDDEN), nn.ReLU(),
                             nn.Linear(HIDDEN, 3))


def _rho(net, hd):
    import torch

    return torch.clamp(torch.expm1(torch.clamp(net(hd), max=_MAX_LOG)), min=0.0)


class NbrdfModel:
    """One fitted NBRDF network.

    Attributes
    ----------
    net
        ``torch.nn.Sequential`` ``6 -> 21 -> 21 -> 3`` in eval mode.
    device
        ``torch.device`` the network lives on.
    steps
        Optimiser steps taken before the budget or early stopping ended training.
    loss
        Best training loss (mean absolute log error of cosine-weighted values).
    seconds
        Wall-clock fitting time.
    """

    def __init__(self, net, device, steps: int = 0, loss: float = float("nan"), seconds: float = 0.0):
        self.net = net.eval()
        self.device = device
        self.steps = steps
        self.loss = loss
        self.seconds = seconds

    def eval_hd(self, hd):
        """BRDF at HD vectors.

        Parameters
        ----------
        hd
            ``(N, 6)`` half and difference unit vectors (``phi_h = 0``), a NumPy array
            or a torch tensor.

        Returns
        -------
        array or tensor
            ``(N, 3)`` RGB BRDF in 1/sr, ``>= 0``; a NumPy float64 array for NumPy input,
            a tensor (on the model's device) for tensor input.
        """
        import torch

        is_np = not isinstance(hd, torch.Tensor)
        x = torch.as_tensor(np.asarray(hd, np.float32) if is_np else hd, dtype=torch.float32,
                            device=self.device)
        with torch.no_grad():
            out = _rho(self.net, x)
        return out.cpu().numpy().astype(np.float64) if is_np else out

    def to_table(self, block: int = 1 << 18) -> np.ndarray:
        """Dense MERL table: float64 ``(90, 90, 180, 3)``, 1/sr, NaN on the cells where
        either direction is below the horizon (the cells MERL never measures)."""
        import torch

        cells, hd = valid_cells(), grid_hd()
        out = np.full((N_CELLS, 3), np.nan)
        with torch.no_grad():
            for s in range(0, cells.size, block):
                x = torch.from_numpy(hd[cells[s:s + block]]).to(self.device)
                out[cells[s:s + block]] = _rho(self.net, x).cpu().numpy()
        return out.reshape(GRID_SHAPE + (3,))

    def reconstruct(self, samples=None) -> np.ndarray:
        """The dense table (the samples were used at fitting time); for the common
        interface of :mod:`brdfkit.methods`."""
        return self.to_table()


def fit_nbrdf(samples, steps: int = DEFAULT_STEPS, seed: int = 0, lr: float = DEFAULT_LR,
              patience: int = DEFAULT_PATIENCE, device=None) -> NbrdfModel:
    """Fit one NBRDF network to a sample set.

    Parameters
    ----------
    samples
        :class:`brdfkit.io.samples.SampleSet`, BRDF values in 1/sr.
    steps
        Most optimiser steps (Adam).
    seed
        Seed of the initial weights and of the mini-batch order.
    lr
        Adam learning rate.
    patience
        Early stop after this many steps without a relative improvement of ``1e-4``.
    device
        Torch device; default CUDA when available, else CPU.

    Returns
    -------
    NbrdfModel
    """
    if len(samples) == 0:
        raise InputError(f"{samples.source or 'samples'}: no samples to fit")
    if steps < 1:
        raise InputError(f"number of NBRDF training steps must be at least 1, got {steps}")
    if not (lr > 0 and np.isfinite(lr)):
        raise InputError(f"NBRDF learning rate must be a positive number, got {lr}")
    dev = resolve_device(device)
    # The network's matrices (N x 21) are far too small for intra-op parallelism: more
    # OpenMP threads only add synchronisation, and on a busy machine their spin-waits
    # dominate (measured: 500 steps at N = 4000 took 2.5 s with 1 thread and 22.6 s with 2
    # at load average 12 on 2 cores, /tmp scripts of the development session).
    with torch_threads(1 if dev.type == "cpu" else None):
        return _fit(samples, steps, int(seed), float(lr), int(patience), dev)


def _fit(samples, steps, seed, lr, patience, dev) -> NbrdfModel:
    import torch

    t0 = time.perf_counter()
    net = _make_net(seed).to(dev)
    hd = torch.as_tensor(samples.hd(), dtype=torch.float32, device=dev)
    cos = torch.as_tensor(samples.cos_i(), dtype=torch.float32, device=dev)[:, None]
    target = torch.log1p(torch.as_tensor(np.clip(samples.rgb, 0.0, None), dtype=torch.float32,
                                         device=dev) * cos)
    n = hd.shape[0]

    def loss_of(idx=None):
        h, c, t = (hd, cos, target) if idx is None else (hd[idx], cos[idx], target[idx])
        return (torch.log1p(_rho(net, h) * c) - t).abs().mean()

    opt = torch.optim.Adam(net.parameters(), lr=lr)
    gen = torch.Generator(device="cpu").manual_seed(seed)
    perm, pos = None, n
    best, best_state, best_step, step = float("inf"), copy.deepcopy(net.state_dict()), 0, 0
    net.train()
    for step in range(1, steps + 1):
        if n <= BATCH:
            loss = loss_of()
        else:
            if pos + BATCH > n:
                perm, pos = torch.randperm(n, generator=gen).to(dev), 0
            loss = loss_of(perm[pos:pos + BATCH])
            pos += BATCH
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        if step % _CHECK_EVERY == 0 or step == steps:
            with torch.no_grad():
                current = float(loss_of())
            if current < best * (1 - 1e-4):
                best, best_step = current, step
                best_state = copy.deepcopy(net.state_dict())
            elif step - best_step >= patience:
                break
    net.load_state_dict(best_state)
    if not np.isfinite(best):
        raise InputError(f"{samples.source or 'samples'}: NBRDF fit diverged (non-finite loss)")
    return NbrdfModel(net, dev, step, best, time.perf_counter() - t0)


@dataclasses.dataclass(frozen=True)
class NbrdfOptions(MethodOptions):
    """The options of :func:`fit_nbrdf`: most steps, Adam learning rate, patience."""

    steps: int = DEFAULT_STEPS
    lr: float = DEFAULT_LR
    patience: int = DEFAULT_PATIENCE

    def __post_init__(self):
        if not (isinstance(self.steps, int) and self.steps >= 1):
            raise InputError(f"nbrdf option steps must be an integer >= 1, got {self.steps!r}")
        if not (isinstance(self.lr, (int, float)) and self.lr > 0 and np.isfinite(self.lr)):
            raise InputError(f"nbrdf option lr must be a positive number, got {self.lr!r}")

    def quick(self) -> "NbrdfOptions":
        return dataclasses.replace(self, steps=min(20, self.steps))


def _reconstruct(samples, model, options, *, seed, device):
    fitted = fit_nbrdf(samples, steps=options.steps, seed=seed, lr=options.lr, patience=options.patience,
                       device=device)
    return fitted.to_table(), None


METHOD = Method("nbrdf", "one small MLP fitted to the samples alone (Sztrajman et al. 2021)", "",
                options=NbrdfOptions, reconstruct_fn=_reconstruct)
