"""The learnt-prior model: a set encoder that gives a PCA basis fit its prior.

Sparse reconstruction with a linear basis (Nielsen et al. 2015) solves a ridge problem
whose prior says "the mean material": from 40 samples the fit is pulled to it, from 4,000
the samples decide. Here a set encoder in the style of Gokbudak et al. 2024 (per sample
``[H, D, r] -> 128 -> 128 -> latent``, ReLU, mean over the samples) reads the samples'
residuals ``r`` against the plain fit and predicts a better prior *mean* for the basis
coefficients; the coefficients are then solved again in closed form around it. The
model therefore contains the basis fit as a special case (a zero prior mean), and many
samples outweigh whatever the network says.

Closed-form fit (:func:`solve`)
-------------------------------
With the basis's mapped value of a sample ``b = ln((rho w + eps) / (x_ref + eps)) - mean``
(:mod:`brdfkit.basis.model`), per channel::

    min_c  sum_s q_s (A_s c - b_s)^2 + |(c - mu) / sigma|^2,
    q_s = g_s^2 / s2 + 1 / lam,      g_s = cos_i (rho + eps / w) / (1 + rho cos_i)

the evaluation metric's likelihood (``ln(1 + rho cos_i)``, :func:`brdfkit.evaluation.metrics.brdf_log_rmse`,
noise variance ``s2``) linearised around the observed values, plus IPCA's own likelihood
(noise variance ``lam``), and the Gaussian prior of the training coefficients
(standard deviations ``sigma``) centred on ``mu``. ``benchmarks/studies/study_pca.py``
measured this closed form within 0.002 of the iterative fit in the metric's space.

With ``weight = "energy"`` the metric's term is ``g_s / s2`` instead: a residual counts
in proportion to the sample's saturating energy ``rho cos_i / (1 + rho cos_i)`` rather
than its square, so that the bright samples of a glossy lobe outweigh the diffuse body
less (``benchmarks/studies/study_likelihood.py`` ranks the choices by render PSNR).

A learnt spread (``PriorConfig.spread``)
----------------------------------------
The prior's standard deviations are the training coefficients' ``sigma``, the same for
every material and sample count. With ``spread`` the head also predicts a factor on each
(``exp`` of its output, clipped to ``[e^-3, e^3]``; a zero output keeps ``sigma``), per
channel and component: where the samples leave the network sure of a coefficient the
fit is held to its prior mean more tightly, where they do not it is let loose. Trained
through the closed form like the mean. Off by default and in the built-ins: on the
validation split it fitted the training materials better and rendered worse at every N
(``docs/notes/generalisation.md``, Lever 8).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from brdfkit.errors import InputError
from brdfkit.geometry import GRID_SHAPE
from brdfkit.geometry.trilinear import lookup_trilinear
from brdfkit.basis import PcaBasis
from brdfkit.basis.mapping import EPS, NIELSEN

__all__ = ["PriorConfig", "PriorModel", "PriorWeights", "PriorFit", "prior_net", "solve", "likelihood_weights",
           "sample_rows", "N_REF", "SPREAD_LOG_BOUND"]

N_REF = 4000
"""The sample count the network's count feature is scaled by (``ln N / ln N_REF``)."""


@dataclasses.dataclass(frozen=True)
class PriorConfig:
    """Sizes and the fit's constants.

    Attributes
    ----------
    n_components
        ``K``, the basis's components.
    latent_dim, width
        The set encoder's output and hidden widths.
    s2, lam
        Noise variances of the metric's and of IPCA's likelihood in :func:`solve`.
    weight
        ``"metric"`` or ``"energy"``: the metric's term in :func:`solve`.
    spread
        Whether the head also predicts the prior's spread (module docstring); files from
        before the option have none.
    """

    n_components: int = 8
    latent_dim: int = 40
    width: int = 128
    s2: float = 1e-2
    lam: float = 0.1
    weight: str = "metric"
    spread: bool = False

    def __post_init__(self):
        # A model file's config arrives as JSON: refuse what the fit cannot use.
        if self.weight not in ("metric", "energy") or not (self.s2 > 0 and self.lam > 0):
            raise ValueError(f"invalid likelihood: weight {self.weight!r}, s2 {self.s2!r}, lam {self.lam!r}")
        if not isinstance(self.spread, bool):
            raise ValueError(f"invalid spread: {self.spread!r}")

    def record(self) -> dict:
        """The config as a model file records it: without ``spread`` when it is off, so a
        file from before the option is saved again as it was (same digest)."""
        d = dataclasses.asdict(self)
        if not self.spread:
            del d["spread"]
        return d


def _mlp(*sizes):
    import torch

    layers = []
    for a, b in zip(sizes[:-1], sizes[1:]):
        layers += [torch.nn.Linear(a, b), torch.nn.ReLU()]
    return torch.nn.Sequential(*layers[:-1])


SPREAD_LOG_BOUND = 3.0
"""The learnt spread's factor on ``sigma`` lies in ``[e^-3, e^3]``."""


def prior_net(cfg: PriorConfig):
    """The network: ``encoder`` (9 -> width -> width -> latent, mean-pooled) and ``head``
    (latent + 3 K + 1 -> width -> width -> 3 K, or 6 K with ``cfg.spread``), the head's
    last layer zero (an untrained model is the plain basis fit)."""
    import torch

    class PriorNet(torch.nn.Module):
        def __init__(self):
            super().__init__()
            k = cfg.n_components
            self.encoder = _mlp(9, cfg.width, cfg.width, cfg.latent_dim)
            self.head = _mlp(cfg.latent_dim + 3 * k + 1, cfg.width, cfg.width, (6 if cfg.spread else 3) * k)
            with torch.no_grad():
                self.head[-1].weight.zero_()
                self.head[-1].bias.zero_()

        def forward(self, hd, resid, c, sigma, n):
            """The prior from the samples' ``hd (B, S, 6)``, residuals ``(B, S, 3)``,
            plain-fit coefficients ``c (B, 3, K)``, the basis's ``sigma (B, K)`` and the
            sample count ``n``: its mean ``(B, 3, K)`` and standard deviations ``(B, 3,
            K)`` (``sigma`` itself without ``cfg.spread``); also the latent and the raw
            output ``(B, 3, K)`` or ``(B, 6, K)``."""
            z = self.encoder(torch.cat([hd, resid], -1)).mean(1)
            b, k = c.shape[0], c.shape[-1]
            feats = torch.cat([z, (c / sigma[:, None]).reshape(b, -1),
                               torch.full((b, 1), math.log(max(n, 1)) / math.log(N_REF), dtype=z.dtype)], -1)
            raw = self.head(feats).view(b, -1, k)
            sd = sigma[:, None].expand(b, 3, k)
            if cfg.spread:
                sd = sd * torch.exp(raw[:, 3:].clamp(-SPREAD_LOG_BOUND, SPREAD_LOG_BOUND))
            return raw[:, :3] * sigma[:, None], sd, z, raw

    return PriorNet()


def _layer_shapes(cfg: PriorConfig) -> dict:
    """``{name: shape}`` of the network's tensors, as :func:`prior_net`'s ``state_dict``
    names them (``encoder.0.weight`` ...: the linear layers at 0, 2 and 4, ReLUs between)."""
    k = cfg.n_components
    sizes = {"encoder": (9, cfg.width, cfg.width, cfg.latent_dim),
             "head": (cfg.latent_dim + 3 * k + 1, cfg.width, cfg.width, (6 if cfg.spread else 3) * k)}
    shapes = {}
    for part, dims in sizes.items():
        for i, (a, b) in enumerate(zip(dims[:-1], dims[1:])):
            shapes[f"{part}.{2 * i}.weight"], shapes[f"{part}.{2 * i}.bias"] = (b, a), (b,)
    return shapes


class PriorWeights:
    """The network of :func:`prior_net` as float32 NumPy arrays, evaluated in NumPy: what a
    reconstruction needs of it, without torch (a loaded model file holds one; the training
    makes the torch module).

    Parameters
    ----------
    cfg
        :class:`PriorConfig`.
    state
        ``{name: array}`` named as the torch module's ``state_dict``; checked against
        ``cfg`` (:class:`ValueError` naming the first tensor that does not fit).
    """

    def __init__(self, cfg: PriorConfig, state: dict):
        shapes = _layer_shapes(cfg)
        if sorted(state) != sorted(shapes):
            raise ValueError(f"tensors {sorted(set(state) ^ set(shapes))[:3]} do not match the configuration")
        self.cfg = cfg
        self._state = {k: np.ascontiguousarray(state[k], np.float32) for k in shapes}
        bad = next((k for k, a in self._state.items() if a.shape != shapes[k]), None)
        if bad is not None:
            raise ValueError(f"tensor {bad} has shape {self._state[bad].shape}, the configuration {shapes[bad]}")

    @classmethod
    def of(cls, net, cfg: PriorConfig) -> "PriorWeights":
        """``net`` as arrays: itself when it is one, else a torch module's weights now."""
        if isinstance(net, cls):
            return net
        return cls(cfg, {k: v.detach().cpu().float().numpy() for k, v in net.state_dict().items()})

    def state_dict(self) -> dict:
        """``{name: float32 array}``, as the torch module names its tensors."""
        return dict(self._state)

    def _mlp(self, part: str, x: np.ndarray) -> np.ndarray:
        for i in (0, 2, 4):
            x = x @ self._state[f"{part}.{i}.weight"].T + self._state[f"{part}.{i}.bias"]
            if i < 4:
                np.maximum(x, 0, out=x)
        return x

    def __call__(self, hd, resid, c, sigma, n):
        """The torch module's ``forward`` (:func:`prior_net`) in float32 NumPy: ``(mean,
        standard deviations, latent, raw output)``."""
        z = self._mlp("encoder", np.concatenate([hd, resid], -1).astype(np.float32)).mean(1)
        b, k = c.shape[0], c.shape[-1]
        count = np.full((b, 1), math.log(max(n, 1)) / math.log(N_REF), np.float32)
        raw = self._mlp("head", np.concatenate([z, (c / sigma[:, None]).reshape(b, -1), count], -1)).reshape(b, -1, k)
        sd = np.broadcast_to(sigma[:, None], (b, 3, k))
        if self.cfg.spread:
            sd = sd * np.exp(np.clip(raw[:, 3:], -SPREAD_LOG_BOUND, SPREAD_LOG_BOUND))
        return raw[:, :3] * sigma[:, None], sd, z, raw


def solve(tab, rho, w, cos, sigma, s2: float, lam: float, mu=None, weight: str = "metric", mapping=NIELSEN):
    """The closed-form fit of the module docstring, batched: on torch tensors (the
    training) or NumPy arrays (a reconstruction), the same operations in the same dtypes.

    Parameters
    ----------
    tab
        ``(B, S, K + 2)`` ``[x_ref, mean, components]`` of the basis at the samples.
    rho
        ``(B, S, 3)`` BRDF values (1/sr, ``>= 0``).
    w, cos
        ``(B, S)`` the basis's mapping weight (``cos_i cos_o``, ``> 0``, raised to the
        basis's ``w_floor``: :meth:`PcaBasis.weight`) and ``cos_i``.
    sigma
        ``(B, K)`` the prior's standard deviations, or ``(B, 3, K)`` per channel (a
        learnt spread).
    mu
        ``(B, 3, K)`` prior mean, or ``None`` (zero).
    weight
        ``"metric"`` (``g^2``) or ``"energy"`` (``g``), as :class:`PriorConfig` says.
    mapping
        The basis's log mapping (:class:`~brdfkit.basis.mapping.LogMapping`; ``g``
        linearises through its slope ``d rho / d x'``).

    Returns
    -------
    tuple
        Coefficients ``(B, 3, K)`` (float32, solved in float64) and the mapped values
        ``b`` ``(B, S, 3)`` (in the inputs' dtype).
    """
    if type(tab).__module__.startswith("torch"):
        import torch as xp

        f64, f32 = (lambda a: a.double()), (lambda a: a.float())
        b = mapping.to_mapped(rho, w[..., None], tab[..., 0:1]) - tab[..., 1:2]
    else:
        xp = np
        f64, f32 = (lambda a: np.asarray(a, np.float64)), (lambda a: np.asarray(a, np.float32))
        # in the inputs' own dtype, as the torch branch maps (to_mapped's NumPy default is float64)
        b = mapping.to_mapped(rho, w[..., None], tab[..., 0:1], out=np.empty(np.shape(rho), np.asarray(rho).dtype))
        b -= tab[..., 1:2]
    comp = f64(tab[..., 2:])
    q = f64(likelihood_weights(tab, rho, w, cos, s2, lam, weight, mapping))
    sig = f64(sigma) if sigma.ndim == 3 else f64(sigma)[:, None]  # (B, 3 or 1, K)
    lhs = xp.einsum("bck,bcj,bcl->blkj", comp, comp, q)
    prec = 1.0 / sig ** 2
    lhs = lhs + prec[..., None] * xp.eye(comp.shape[-1], dtype=lhs.dtype)  # the prior's diagonal
    rhs = xp.einsum("bck,bcl->blk", comp, q * f64(b))
    if mu is not None:
        rhs = rhs + f64(mu) / sig ** 2
    return f32(xp.linalg.solve(lhs, rhs[..., None])[..., 0]), b


def likelihood_weights(tab, rho, w, cos, s2: float, lam: float, weight: str = "metric", mapping=NIELSEN):
    """``q (B, S, 3)``: each sample's weight in :func:`solve`'s least squares (module
    docstring), in the inputs' dtype, NumPy or torch alike."""
    # the metric's slope through the mapping's: d ln(1 + rho cos) / d x'
    slope = rho + EPS / w[..., None] if not mapping.share else mapping.rho_slope(rho, w[..., None], tab[..., 0:1])
    g = cos[..., None] * slope / (1 + rho * cos[..., None])
    return (g if weight == "energy" else g ** 2) / s2 + 1.0 / lam


@dataclasses.dataclass
class PriorFit:
    """A sample set's fit by the learnt prior (:meth:`PriorModel.fit`), and what a fit
    through more than the basis needs of it (a fit again through a correction of the basis:
    ``benchmarks/studies/corrected_prior.py``).

    Attributes
    ----------
    coefficients
        float64 ``(K, 3)``.
    mean, sd
        The prior's mean and standard deviations of the coefficients, float64 ``(K, 3)``.
    tab, b, q, hd
        At the usable samples: the basis ``(S, K + 2)`` (``[x_ref, mean, components]``),
        the mapped samples less the basis's mean ``(S, 3)``, their weights ``(S, 3)``
        (:func:`likelihood_weights`), their HD vectors ``(S, 6)``.
    count
        The usable samples, ``S``.
    """

    coefficients: np.ndarray
    mean: np.ndarray
    sd: np.ndarray
    tab: np.ndarray
    b: np.ndarray
    q: np.ndarray
    hd: np.ndarray
    count: int


def sample_rows(basis: PcaBasis, samples):
    """The measured (non-NaN) samples a basis cell covers with a non-zero cosine weight, as float64 arrays:
    ``(ok, tab (S, K + 2), w, cos_i, rho, hd (S, 6))``, ``ok`` the mask over the
    samples. The basis is read trilinearly at each sample's angles (exactly at a cell's
    own angles), as :meth:`PcaBasis.coefficients` reads it."""
    from brdfkit.geometry import cos_theta_i

    tab = lookup_trilinear(basis.lookup_table().reshape(GRID_SHAPE + (-1,)), samples.theta_h, samples.theta_d,
                           samples.phi_d).astype(np.float64)
    w = basis.weight(samples.theta_h, samples.theta_d, samples.phi_d)
    rgb = np.asarray(samples.rgb, np.float64)
    ok = np.isfinite(tab).all(1) & (w > 0) & samples.measured()
    cos = np.clip(cos_theta_i(samples.theta_h, samples.theta_d, samples.phi_d)[ok], 0, None)
    rho = np.clip(rgb[ok], 0, None)
    return ok, tab[ok], w[ok], cos, rho, samples.hd()[ok]


@dataclasses.dataclass
class PriorModel:
    """A basis and the network that gives its fit a prior.

    Attributes
    ----------
    basis
        :class:`~brdfkit.basis.PcaBasis` (``K`` components).
    net
        The network: :class:`PriorWeights` (a loaded file's: NumPy, no torch) or the
        torch module of :func:`prior_net` (the training's, in eval mode on the CPU).
    cfg
        :class:`PriorConfig`.
    meta
        Training record (``materials``, ``steps``, ``wall_time_s`` ...).
    digest
        sha256 hex of the weights and the basis (:mod:`brdfkit.prior.prior_file`).
    """

    basis: PcaBasis
    net: object
    cfg: PriorConfig
    meta: dict = dataclasses.field(default_factory=dict)
    digest: str = ""

    def coefficients(self, samples, *, use_prior: bool = True) -> np.ndarray:
        """Basis coefficients ``(K, 3)`` fitted to a sample set (BRDF in 1/sr): the plain
        closed-form fit, then (``use_prior``) the fit again around the network's prior
        mean. In NumPy (:class:`PriorWeights`), whatever :attr:`net` is."""
        return self.fit(samples, use_prior=use_prior).coefficients

    def fit(self, samples, *, use_prior: bool = True) -> PriorFit:
        """:meth:`coefficients` and the terms of their least squares (:class:`PriorFit`)."""
        if len(samples) == 0:
            raise InputError(f"{samples.source or 'samples'}: no samples to fit")
        ok, tab, w, cos, rho, hd = sample_rows(self.basis, samples)
        if not ok.any():
            what = ("no sample has a measured (non-NaN) value" if not samples.measured().any()
                    else "no sample lies on a cell the basis covers above the horizon")
            raise InputError(f"{samples.source or 'samples'}: {what}")
        T = lambda a: np.ascontiguousarray(a, np.float32)[None]  # noqa: E731
        sig = T(self.basis.sigma)
        rows = (T(tab), T(rho), T(w), T(cos))
        c, b = solve(*rows, sig, self.cfg.s2, self.cfg.lam, weight=self.cfg.weight, mapping=self.basis.mapping)
        mu, sd = np.zeros_like(c), np.broadcast_to(sig[:, None], c.shape)
        if use_prior:
            resid = b - np.einsum("bck,blk->bcl", rows[0][..., 2:], c)
            mu, sd, _, _ = PriorWeights.of(self.net, self.cfg)(T(hd), resid, c, sig, int(ok.sum()))
            c, _ = solve(*rows, sd, self.cfg.s2, self.cfg.lam, mu=mu, weight=self.cfg.weight,
                         mapping=self.basis.mapping)
        if not np.isfinite(c).all():
            raise InputError(f"{samples.source or 'samples'}: the fit did not give finite coefficients")
        q = likelihood_weights(*rows, self.cfg.s2, self.cfg.lam, self.cfg.weight, self.basis.mapping)
        f64 = lambda a: np.asarray(a, np.float64)[0]  # noqa: E731
        return PriorFit(f64(c).T, f64(mu).T, f64(sd).T, f64(rows[0]), f64(b), f64(q), np.asarray(hd, np.float32),
                        int(ok.sum()))

    def reconstruct(self, samples, *, use_prior: bool = True) -> np.ndarray:
        """Dense table ``(90, 90, 180, 3)`` (1/sr, ``>= 0``, NaN off the basis cells)."""
        return self.basis.decode(self.coefficients(samples, use_prior=use_prior))
