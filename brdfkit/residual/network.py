"""The residual's hypernetwork: a basis embedding's coefficients in, a small hyponet's
weights out (the paper's idea, Gokbudak et al. 2024, conditioned on the basis's
coefficients instead of a learnt latent).

For one colour channel of a material, the input is its ``K`` coefficients in training
standard deviations (``c_k / sigma_k``), padded with zeros to ``k_max`` and followed by a
mask of ``K`` ones (so one network serves every size ``K <= k_max``):
``z = [c_1/s_1 ... c_K/s_K, 0 ... 0, 1 ... 1, 0 ... 0]``, ``2 k_max`` numbers. A body
``2 k_max -> hidden -> hidden`` (ReLU) and a linear head give the change of the hyponet's
weights from a learnt base; the hyponet ``6 -> width -> width -> 1`` (ReLU) maps a cell's
Rusinkiewicz HD vector (:func:`brdfkit.geometry.hd_vectors`) to the correction of that
channel's mapped value. The head's rows of the last layer start at zero and so does the
last layer's base: an untrained network corrects nothing, and the model *is* the basis.

:class:`ResidualNet` is the torch module that training fits; :func:`hyponet_weights` and
:func:`evaluate` are the same forward pass in NumPy, which ``encode``, ``decode``,
``render`` and ``metrics`` use so that they load no torch, and
:func:`evaluate_with_jacobian` adds its derivative in the coefficients (forward mode), what
an encoder's Levenberg-Marquardt fit through the correction needs
(:func:`brdfkit.residual.encoding.fit_through`).
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np

__all__ = ["ResidualConfig", "ResidualNet", "hyponet_shapes", "net_input", "hyponet_weights", "evaluate",
           "evaluate_with_jacobian", "LEFT_FIELDS"]

LEFT_FIELDS = ("count", "latent")
"""Config fields of the networks of sparse fits (``brdfkit fit --method correction``: a
sample count, a set encoder's latent), which left brdfkit on 2026-12-01
(``docs/notes/generalisation.md``, "What left the product"): a file whose network has one
is refused in one line (:mod:`brdfkit.residual.residual_file`)."""


@dataclasses.dataclass(frozen=True)
class ResidualConfig:
    """The network's shape.

    Attributes
    ----------
    k_min, k_max
        The numbers of components ``K`` it serves (embeddings of ``3 k_min`` to
        ``3 k_max`` numbers); its input has ``2 k_max`` numbers.
    width
        The hyponet's hidden width.
    hidden
        The hypernetwork body's width.
    member
        Which of the networks that serve the same sizes this is (0, 1, ...): a file may hold
        several *members* a size, and ``encode`` keeps per material the one that renders the
        objective scenes best (``docs/notes/compression.md``).
    """

    k_min: int = 1
    k_max: int = 30
    width: int = 32
    hidden: int = 64
    member: int = 0

    def __post_init__(self):
        for name in ("k_min", "k_max", "width", "hidden"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise ValueError(f"residual config: {name} must be a positive whole number, not {v!r}")
        if isinstance(self.member, bool) or not isinstance(self.member, int) or self.member < 0:
            raise ValueError(f"residual config: member must be a whole number >= 0, not {self.member!r}")
        if self.k_min > self.k_max:
            raise ValueError(f"residual config: k_min {self.k_min} > k_max {self.k_max}")

    @property
    def inputs(self) -> int:
        """The network's input size, ``2 k_max``."""
        return 2 * self.k_max

    def to_json(self) -> str:
        d = dataclasses.asdict(self)
        if not d["member"]:  # files from before members read and write as they were
            del d["member"]
        return json.dumps(d, sort_keys=True)

    @classmethod
    def from_json(cls, text: str) -> "ResidualConfig":
        d = json.loads(text)
        if not isinstance(d, dict) or set(d) - {f.name for f in dataclasses.fields(cls)}:
            raise ValueError(f"not a residual config: {text[:80]!r}")
        return cls(**d)


def hyponet_shapes(width: int) -> list:
    """The hyponet's tensors in order: ``w1 (6, W), b1 (W,), w2 (W, W), b2 (W,), w3 (W, 1),
    b3 (1,)``."""
    return [(6, width), (width,), (width, width), (width,), (width, 1), (1,)]


def net_input(c_norm: np.ndarray, k_max: int) -> np.ndarray:
    """The input ``(B, 2 k_max)`` float32 of coefficients in training standard deviations
    ``(B, K)``: padded to ``k_max``, the mask of the ``K`` given after them.

    Examples
    --------
    >>> net_input(np.array([[1.0, 2.0]]), 3).tolist()
    [[1.0, 2.0, 0.0, 1.0, 1.0, 0.0]]
    """
    c_norm = np.asarray(c_norm, np.float32)
    b, k = c_norm.shape
    z = np.zeros((b, 2 * k_max), np.float32)
    z[:, :k] = c_norm
    z[:, k_max:k_max + k] = 1.0
    return z


def _relu(x):
    return np.maximum(x, 0.0, out=x)


def hyponet_weights(state: dict, cfg: ResidualConfig, z: np.ndarray) -> list:
    """The hyponet's tensors (:func:`hyponet_shapes`, each with a leading ``B``) for inputs
    ``z (B, 2 k_max)``, from a state dict of NumPy arrays (:class:`ResidualNet`'s names):
    the same numbers as the torch module's, in float32."""
    h = _relu(z @ state["body.0.weight"].T + state["body.0.bias"])
    h = _relu(h @ state["body.2.weight"].T + state["body.2.bias"])
    flat = h @ state["head.weight"].T + state["head.bias"]
    out, at = [], 0
    for i, shape in enumerate(hyponet_shapes(cfg.width)):
        n = int(np.prod(shape))
        out.append(state[f"base.{i}"][None] + flat[:, at:at + n].reshape((-1,) + shape))
        at += n
    return out


def evaluate(weights: list, hd: np.ndarray, row: int, chunk: int = 16384) -> np.ndarray:
    """The hyponet of row ``row`` of ``weights`` at HD vectors ``hd (N, 6)``: ``(N,)``
    float32 mapped corrections (``chunk`` cells at a time: the hidden layers' arrays stay
    in cache)."""
    w1, b1, w2, b2, w3, b3 = (w[row] for w in weights)
    out = np.empty(hd.shape[0], np.float32)
    for s in range(0, hd.shape[0], chunk):
        h = _relu(hd[s:s + chunk] @ w1 + b1)
        h = _relu(h @ w2 + b2)
        out[s:s + chunk] = (h @ w3)[:, 0] + b3[0]
    return out


def evaluate_with_jacobian(state: dict, cfg: ResidualConfig, c_norm: np.ndarray, hd: np.ndarray):
    """The correction of one channel at HD vectors ``hd (N, 6)`` and its derivative in
    that channel's normalised coefficients ``c_norm (K,)`` (``c_k / sigma_k``), by forward
    mode through :func:`hyponet_weights` and :func:`evaluate` (float32, the ``K``
    directions at once).

    Returns
    -------
    value : numpy.ndarray
        float32 ``(N,)``, :func:`evaluate`'s.
    jacobian : numpy.ndarray
        float32 ``(N, K)``.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> cfg = ResidualConfig(k_max=3, width=4, hidden=5)
    >>> state = {"body.0.weight": rng.normal(size=(5, 6)), "body.0.bias": rng.normal(size=5),
    ...          "body.2.weight": rng.normal(size=(5, 5)), "body.2.bias": rng.normal(size=5),
    ...          "head.weight": rng.normal(size=(53, 5)), "head.bias": rng.normal(size=53)}
    >>> state.update({f"base.{i}": rng.normal(size=s) for i, s in enumerate(hyponet_shapes(4))})
    >>> state = {k: (0.3 * v).astype(np.float32) for k, v in state.items()}
    >>> hd, c, step = rng.normal(size=(7, 6)).astype(np.float32), np.array([0.3, -0.2]), np.array([1e-2, 0.0])
    >>> value, jac = evaluate_with_jacobian(state, cfg, c, hd)
    >>> (plus, _), (minus, _) = (evaluate_with_jacobian(state, cfg, c + s * step, hd) for s in (1, -1))
    >>> bool(np.allclose((plus - minus) / 2e-2, jac[:, 0], rtol=1e-2, atol=1e-3))
    True
    """
    k = int(np.asarray(c_norm).shape[0])
    z = net_input(np.asarray(c_norm)[None], cfg.k_max)[0]
    w0, b0 = state["body.0.weight"], state["body.0.bias"]
    a1 = w0 @ z + b0
    m1 = (a1 > 0).astype(np.float32)
    h1, d1 = a1 * m1, m1[:, None] * w0[:, :k]  # (H,), (H, K)
    w2, b2 = state["body.2.weight"], state["body.2.bias"]
    a2 = w2 @ h1 + b2
    m2 = (a2 > 0).astype(np.float32)
    h2, d2 = a2 * m2, m2[:, None] * (w2 @ d1)
    flat, dflat = state["head.weight"] @ h2 + state["head.bias"], state["head.weight"] @ d2  # (F,), (F, K)
    tensors, at = [], 0
    for i, shape in enumerate(hyponet_shapes(cfg.width)):
        n = int(np.prod(shape))
        tensors.append((state[f"base.{i}"] + flat[at:at + n].reshape(shape), dflat[at:at + n].reshape(shape + (k,))))
        at += n
    # Tangents laid out (N, K, W): each layer's product one matrix product for all K.
    (v1, t1), (c1, u1), (v2, t2), (c2, u2), (v3, t3), (c3, u3) = (
        (v, np.moveaxis(t, -1, 0)) for v, t in tensors)  # t: (K, ...shape)
    hd = np.asarray(hd, np.float32)
    n, width = hd.shape[0], cfg.width
    a = hd @ v1 + c1  # (N, W)
    da = (hd @ np.moveaxis(t1, 0, 1).reshape(6, -1)).reshape(n, k, width) + u1  # (N, K, W)
    mask = a > 0
    h = np.where(mask, a, 0)
    da *= mask[:, None, :]
    b = h @ v2 + c2
    db = (h @ np.moveaxis(t2, 0, 1).reshape(width, -1)).reshape(n, k, width) + u2
    db += (da.reshape(-1, width) @ v2).reshape(n, k, width)
    mask = b > 0
    g = np.where(mask, b, 0)
    db *= mask[:, None, :]
    value = (g @ v3)[:, 0] + c3[0]
    jac = (db.reshape(-1, width) @ v3).reshape(n, k) + g @ t3[:, :, 0].T + u3[:, 0]
    return value.astype(np.float32), jac.astype(np.float32)


def ResidualNet(cfg: ResidualConfig):
    """The torch module of the network (made on call: torch is imported only here).

    ``forward(z, hd)``: ``z (B, cfg.inputs)`` inputs (:func:`net_input`), ``hd`` the HD
    vectors ``(B, C, 6)`` (per row) or ``(C, 6)`` (shared); returns the corrections
    ``(B, C)``.
    """
    import torch

    class _ResidualNet(torch.nn.Module):
        def __init__(self):
            super().__init__()
            self.cfg = cfg
            shapes = hyponet_shapes(cfg.width)
            self.sizes = [int(np.prod(s)) for s in shapes]
            self.body = torch.nn.Sequential(torch.nn.Linear(cfg.inputs, cfg.hidden), torch.nn.ReLU(),
                                            torch.nn.Linear(cfg.hidden, cfg.hidden), torch.nn.ReLU())
            self.head = torch.nn.Linear(cfg.hidden, sum(self.sizes))
            base = []
            for shape in shapes:
                p = torch.zeros(shape)
                if len(shape) == 2 and shape[1] != 1:
                    torch.nn.init.kaiming_uniform_(p.T, a=5 ** 0.5)
                base.append(torch.nn.Parameter(p))
            self.base = torch.nn.ParameterList(base)
            with torch.no_grad():
                self.head.weight.mul_(0.1)
                self.head.bias.zero_()
                self.head.weight[sum(self.sizes[:4]):].zero_()  # the last layer's change starts at 0

        def weights(self, z):
            flat = self.head(self.body(z))
            out, at = [], 0
            for base, n in zip(self.base, self.sizes):
                out.append(base + flat[:, at:at + n].reshape((-1,) + tuple(base.shape)))
                at += n
            return out

        def forward(self, z, hd):
            w1, b1, w2, b2, w3, b3 = self.weights(z)
            if hd.dim() == 2:
                h = torch.relu(torch.einsum("cd,bdh->bch", hd, w1) + b1[:, None])
            else:
                h = torch.relu(torch.bmm(hd, w1) + b1[:, None])
            h = torch.relu(torch.bmm(h, w2) + b2[:, None])
            return (torch.bmm(h, w3) + b3[:, None])[..., 0]

    return _ResidualNet()
