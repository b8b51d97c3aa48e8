"""The hypernetwork BRDF model of Gokbudak et al. 2024 ("Hypernetworks for Generalizable
BRDF Representation", ECCV), in plain PyTorch.

Three parts (paper, Sec. 3 and Fig. 2):

* **Set encoder** ``E``: each sample ``[H (3), D (3), rho' (3)]`` (half and difference
  vectors with ``phi_h = 0``, log-relative mapped RGB) goes through a shared MLP
  ``9 -> 128 -> 128 -> latent`` (ReLU); the latent ``z`` is the mean over the samples, so
  any number of samples in any order gives an embedding (DeepSets, Zaheer et al. 2017).
* **Hypernetwork decoder** ``Psi``: one small MLP per weight tensor of the hyponet,
  ``latent -> hidden -> hidden -> numel``, predicting that tensor from ``z``.
* **Hyponet** ``Phi``: ``6 -> 60 -> 60 -> 60 -> 60 -> 3`` (ReLU), the neural BRDF itself;
  it maps ``(H, D)`` to mapped RGB ``rho'``. Evaluated for a batch of materials at once
  with batched matrix products (``baddbmm``), never a Python loop over materials.

Loss (paper eq. 3): MSE of cosine-weighted mapped values plus ``lambda_w`` times the
mean square of the predicted hyponet weights and ``lambda_z`` times the mean square of
the latent (both 0.1 by default).

Shapes: ``B`` materials, ``N`` samples per material, ``L`` latent size.

Every MLP here is ``Linear, ReLU, ..., Linear`` (no activation after the last layer).
:meth:`SetEncoder.layers` and :meth:`HyperDecoder.tensor_layers` hand out those
``nn.Linear`` layers in order: the fused inference kernels
(:mod:`brdfkit.hypernet.kernels`) are built from them, never from the modules' internal
layout.
"""

from __future__ import annotations

import dataclasses
import json
import math

import torch
from torch import nn

__all__ = ["HyperConfig", "SetEncoder", "HyperDecoder", "HyperBRDF", "hyponet_forward",
           "hyponet_shapes", "hyper_loss", "IN_FEATURES", "OUT_FEATURES"]


@dataclasses.dataclass(frozen=True)
class HyperConfig:
    """Architecture and loss settings; stored as JSON in the network file.

    Attributes
    ----------
    latent_dim
        Size of the embedding ``z`` (40 by default, 7 for compression).
    encoder_hidden
        Widths of the set encoder's hidden layers.
    hypo_hidden, hypo_layers
        Hyponet width and number of hidden layers (60 and 4: ``6 -> 60 x 4 -> 3``).
    decoder_hidden, decoder_layers
        Width and number of hidden layers of each per-tensor decoder MLP.
    lambda_w, lambda_z
        Weights of the hyponet-weight and latent regularisers in the loss.
    pooling
        How the set encoder pools its samples: ``"mean"`` (the paper's) or
        ``"attention"`` (a softmax over a learnt score of each sample's last hidden
        features, Ilse et al. 2018: any count and order still work).
    encoder_dropout
        Dropout after each hidden layer of the set encoder, in training only.
    """

    latent_dim: int = 40
    encoder_hidden: tuple = (128, 128)
    hypo_hidden: int = 60
    hypo_layers: int = 4
    decoder_hidden: int = 128
    decoder_layers: int = 2
    lambda_w: float = 0.1
    lambda_z: float = 0.1
    pooling: str = "mean"
    encoder_dropout: float = 0.0

    # Keys added after models shipped: left out of the JSON at their defaults, so that
    # the configs (and checkpoints) of those models read as they were written.
    _LATER_KEYS = ("pooling", "encoder_dropout")

    def __post_init__(self):
        if self.pooling not in ("mean", "attention"):
            raise ValueError(f"pooling must be 'mean' or 'attention', got {self.pooling!r}")
        if not 0.0 <= float(self.encoder_dropout) < 1.0:
            raise ValueError(f"encoder_dropout must lie in [0, 1), got {self.encoder_dropout!r}")

    def to_json(self) -> str:
        defaults = {f.name: f.default for f in dataclasses.fields(self)}
        d = {k: v for k, v in dataclasses.asdict(self).items() if not (k in self._LATER_KEYS and v == defaults[k])}
        return json.dumps(d, sort_keys=True)

    @classmethod
    def from_json(cls, text: str) -> "HyperConfig":
        d = json.loads(text)
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = set(d) - known
        if unknown:
            raise ValueError(f"unknown model config keys {sorted(unknown)}")
        if "encoder_hidden" in d:
            d["encoder_hidden"] = tuple(d["encoder_hidden"])
        return cls(**d)


IN_FEATURES = 6   # (hx, hy, hz, dx, dy, dz)
OUT_FEATURES = 3  # mapped RGB


def hyponet_shapes(cfg: HyperConfig) -> list[tuple[int, int]]:
    """``(in, out)`` of each hyponet layer, e.g. ``[(6, 60), (60, 60) x 3, (60, 3)]``."""
    widths = [IN_FEATURES] + [cfg.hypo_hidden] * cfg.hypo_layers + [OUT_FEATURES]
    return list(zip(widths[:-1], widths[1:]))


def _mlp(sizes, last_activation=False, dropout=0.0):
    layers = []
    for i, (a, b) in enumerate(zip(sizes[:-1], sizes[1:])):
        layers.append(nn.Linear(a, b))
        if i < len(sizes) - 2 or last_activation:
            layers.append(nn.ReLU())
            if dropout > 0:
                layers.append(nn.Dropout(dropout))
    return nn.Sequential(*layers)


def _linears(seq: nn.Sequential) -> list[nn.Linear]:
    return [m for m in seq if isinstance(m, nn.Linear)]


class SetEncoder(nn.Module):
    """Permutation-invariant encoder: per-sample MLP, then the mean over samples (or,
    with ``pooling="attention"``, a softmax-weighted mean of the last hidden features,
    the weights a learnt linear score of those features; the last layer is affine, so
    it is applied after the pooling)."""

    def __init__(self, cfg: HyperConfig):
        super().__init__()
        sizes = [IN_FEATURES + OUT_FEATURES, *cfg.encoder_hidden, cfg.latent_dim]
        self.net = _mlp(sizes, dropout=cfg.encoder_dropout)
        self.attention = nn.Linear(sizes[-2], 1) if cfg.pooling == "attention" else None

    def forward(self, samples: torch.Tensor) -> torch.Tensor:
        """``samples (B, N, 9)`` -> ``z (B, L)``; any ``N >= 1``."""
        if self.attention is None:
            return self.net(samples).mean(dim=1)
        h = self.net[:-1](samples)
        w = torch.softmax(self.attention(h), dim=1)
        return self.net[-1]((w * h).sum(dim=1))

    def layers(self) -> list[nn.Linear]:
        """The per-sample MLP's layers in order, a ReLU after each but the last."""
        return _linears(self.net)


class HyperDecoder(nn.Module):
    """One MLP per hyponet weight tensor, each predicting that tensor from ``z``.

    The last layer of each MLP starts with small weights and a bias drawn like a
    Kaiming-initialised hyponet (He et al. 2015), so an untrained model already predicts a
    well-scaled ReLU network whose weights the latent perturbs (the "bias init" of
    hypernetworks; Chang et al. 2020 discuss why a plain init fails).
    """

    def __init__(self, cfg: HyperConfig):
        super().__init__()
        self.shapes = hyponet_shapes(cfg)
        self.weight_nets = nn.ModuleList()
        self.bias_nets = nn.ModuleList()
        hidden = [cfg.decoder_hidden] * cfg.decoder_layers
        for fan_in, fan_out in self.shapes:
            for nets, numel in ((self.weight_nets, fan_in * fan_out), (self.bias_nets, fan_out)):
                net = _mlp([cfg.latent_dim, *hidden, numel])
                last = net[-1]
                with torch.no_grad():
                    last.weight.mul_(0.1)
                    bound = math.sqrt(6.0 / fan_in) if nets is self.weight_nets else 1.0 / math.sqrt(fan_in)
                    last.bias.uniform_(-bound, bound)
                nets.append(net)

    def tensor_layers(self) -> list[list[nn.Linear]]:
        """The layers of each per-tensor MLP, in hyponet order ``W_0, b_0, W_1, b_1, ...``
        (weights as ``(in, out)`` row-major, biases ``(out,)``); in each MLP a ReLU
        follows every layer but the last."""
        return [_linears(n) for pair in zip(self.weight_nets, self.bias_nets) for n in pair]

    def forward(self, z: torch.Tensor) -> list[tuple[torch.Tensor, torch.Tensor]]:
        """``z (B, L)`` -> ``[(W (B, in, out), b (B, 1, out)), ...]`` per hyponet layer."""
        out = []
        for (fan_in, fan_out), wn, bn in zip(self.shapes, self.weight_nets, self.bias_nets):
            out.append((wn(z).view(-1, fan_in, fan_out), bn(z).view(-1, 1, fan_out)))
        return out


def hyponet_forward(weights: list[tuple[torch.Tensor, torch.Tensor]], x: torch.Tensor) -> torch.Tensor:
    """Evaluate the hyponets of ``B`` materials.

    Parameters
    ----------
    weights
        From :class:`HyperDecoder`: per layer ``W (B, in, out)`` and ``b (B, 1, out)``.
    x
        ``(B, N, 6)`` HD vectors (``N`` may differ from the context size).

    Returns
    -------
    torch.Tensor
        ``(B, N, 3)`` mapped RGB ``rho'``.
    """
    h = x
    last = len(weights) - 1
    for i, (w, b) in enumerate(weights):
        h = torch.baddbmm(b, h, w)
        if i < last:
            h = torch.relu(h)
    return h


class HyperBRDF(nn.Module):
    """Set encoder + hypernetwork decoder; the hyponet is :func:`hyponet_forward`."""

    def __init__(self, cfg: HyperConfig | None = None):
        super().__init__()
        self.cfg = cfg or HyperConfig()
        self.encoder = SetEncoder(self.cfg)
        self.decoder = HyperDecoder(self.cfg)

    def encode(self, hd: torch.Tensor, mapped: torch.Tensor) -> torch.Tensor:
        """Context samples -> latent. ``hd (B, N, 6)``, ``mapped (B, N, 3)`` -> ``(B, L)``."""
        return self.encoder(torch.cat([hd, mapped], dim=-1))

    def hyponet_weights(self, z: torch.Tensor):
        """Latent ``(B, L)`` -> hyponet weights (see :func:`hyponet_forward`)."""
        return self.decoder(z)

    def forward(self, ctx_hd, ctx_mapped, query_hd):
        """Encode a context set and predict mapped values at query directions.

        Returns ``(prediction (B, Nq, 3), weights, z)``.
        """
        z = self.encode(ctx_hd, ctx_mapped)
        weights = self.hyponet_weights(z)
        return hyponet_forward(weights, query_hd), weights, z


def hyper_loss(pred, target, cos_i, weights, z, cfg: HyperConfig):
    """Paper eq. (3): cosine-weighted MSE plus weight and latent regularisers.

    Parameters
    ----------
    pred, target
        ``(B, N, 3)`` mapped values.
    cos_i
        ``(B, N)`` ``cos(theta_i)``, clamped to ``>= 0``.

    Returns
    -------
    tuple
        ``(total, mse)`` scalars (``mse`` for reporting).
    """
    c = cos_i.unsqueeze(-1)
    mse = torch.mean((c * pred - c * target) ** 2)
    w2 = torch.stack([torch.mean(w ** 2) + torch.mean(b ** 2) for w, b in weights]).mean()
    z2 = torch.mean(z ** 2)
    return mse + cfg.lambda_w * w2 + cfg.lambda_z * z2, mse
