"""Test-time refinement: fit an encoded material to its own samples, early-stopped.

The paper's reconstruction (Gokbudak et al. 2024, Sec. 3) is one pass of the set
encoder: the samples are averaged into a latent ``z0`` and decoded. Refinement then
optimises, on the same samples,

* ``latent``: the latent itself, starting from ``z0`` (the decoder unchanged), with a
  tether ``prior_latent * mean((z - z0)^2)`` pulling it towards the encoder's answer;
* ``weights``: after that, the decoded hyponet's own weights ``W`` (6 -> 60 x 4 -> 3),
  with a tether ``prior_weights * sum(|W - W0|^2) / sum(|W0|^2)`` (a weight decay
  towards the decoded weights, not the learnt prior of :mod:`brdfkit.prior`), which
  reaches functions no latent decodes to (``docs/notes/generalisation.md``: the latent space does not contain
  unseen materials).

The data term is the evaluation metric's own (:func:`brdfkit.evaluation.metrics.brdf_log_rmse`):
``mean((ln(1 + rho_hat cos_i) - ln(1 + rho cos_i))^2)`` over the samples and channels,
not the training loss in mapped space. How many Adam steps to take is chosen on held-out
samples of the input: a ``holdout`` share of the samples is set aside, the fit on the
rest is scored on them every ``check_every`` steps, and the step count with the lowest
held-out error (0 included: refinement may be declined) is then run again on all samples.
Fewer than ``min_samples`` samples are not refined (too few to hold any out).
``docs/notes/generalisation.md`` measures it against the encoder alone and the learnt prior.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from brdfkit.io.embedding import Embedding
from brdfkit.errors import InputError, require_counts

__all__ = ["RefineConfig", "RefineResult", "refine"]


@dataclasses.dataclass(frozen=True)
class RefineConfig:
    """Settings of :func:`refine`.

    Attributes
    ----------
    target
        ``"latent"`` or ``"weights"`` (the latent, then the hyponet weights).
    max_steps
        Most Adam steps per stage.
    lr_latent, lr_weights
        Adam learning rates of the two stages.
    prior_latent, prior_weights
        Weights of the tethers (quadratic pulls) towards the encoded latent and the
        decoded hyponet; the names are kept for compatibility: no learnt prior is involved.
    holdout
        Share of the samples held out to choose the step count, in ``(0, 1)``.
    check_every
        Steps between held-out checks.
    patience
        Checks without improvement before a stage stops early.
    min_samples
        Smallest sample count that is refined.
    """

    target: str = "latent"
    max_steps: int = 300
    lr_latent: float = 0.02
    lr_weights: float = 1e-3
    prior_latent: float = 1e-3
    prior_weights: float = 1e-2
    holdout: float = 0.2
    check_every: int = 10
    patience: int = 5
    min_samples: int = 10

    def __post_init__(self):
        if self.target not in ("latent", "weights"):
            raise InputError(f"refine target must be 'latent' or 'weights', got {self.target!r}")
        if not 0.0 < self.holdout < 1.0:
            raise InputError(f"refine holdout must be in (0, 1), got {self.holdout!r}")
        require_counts(self, ("max_steps", "check_every", "patience", "min_samples"), "refine ")


@dataclasses.dataclass
class RefineResult:
    """What :func:`refine` did.

    Attributes
    ----------
    brdf
        :class:`~brdfkit.hypernet.neural_brdf.NeuralBRDF`: the refined material.
    embedding
        Its latent as an :class:`Embedding` (after the latent stage; the weights stage
        changes the hyponet only, so with ``target="weights"`` it does not decode to
        ``brdf``).
    steps
        Steps run on all samples per stage, ``{"latent": k, "weights": k}``; 0: declined.
    heldout
        Held-out metric MSE per stage, ``{stage: (before, after)}``.
    """

    brdf: object
    embedding: Embedding
    steps: dict
    heldout: dict


def _sample_tensors(model, samples, device):
    import torch

    hd = torch.from_numpy(np.asarray(samples.hd(), np.float32)).to(device)
    ref = torch.from_numpy(np.asarray(model.reference_at(samples.theta_h, samples.theta_d, samples.phi_d),
                                      np.float32)).to(device)
    cos_i = samples.cos_i()[:, None]
    with np.errstate(invalid="ignore"):  # NaN (unmeasured) rows stay NaN; refine drops them
        target = np.log1p(np.clip(np.asarray(samples.rgb, np.float64), 0.0, None) * cos_i)
    cos, target = (torch.from_numpy(a.astype(np.float32)).to(device) for a in (cos_i, target))
    return hd, ref, cos, target


def _metric_mse(weights, hd, ref, cos, target):
    """Mean squared error in the metric's space, ``ln(1 + rho cos_i)``."""
    import torch

    from brdfkit.hypernet.mapping import from_mapped
    from brdfkit.hypernet.network import hyponet_forward

    rho = from_mapped(hyponet_forward(weights, hd[None])[0], ref)
    return torch.mean((torch.log1p(rho * cos) - target) ** 2)


def _stage(init, make_weights, tether, lr, data, fit_idx, held_idx, cfg):
    """Choose the step count on held-out samples, then run it on all samples.

    ``init``: list of tensors optimised (copied); ``make_weights(params)`` the hyponet
    weights; ``tether(params)`` the pull towards the start. Returns ``(params, steps, (before, after))``.
    """
    import torch

    def run(idx, steps, held=None):
        params = [p.detach().clone().requires_grad_(True) for p in init]
        opt = torch.optim.Adam(params, lr=lr)
        sub = [t[idx] for t in data]
        scores = []
        for step in range(steps + 1):
            if held is not None and step % cfg.check_every == 0:
                with torch.no_grad():
                    scores.append((float(_metric_mse(make_weights(params), *held)), step))
                best = min(scores)[1]
                if step - best >= cfg.patience * cfg.check_every:
                    break
            if step == steps:
                break
            loss = _metric_mse(make_weights(params), *sub) + tether(params)
            grads = torch.autograd.grad(loss, params)
            for p, g in zip(params, grads):
                p.grad = g
            opt.step()
        return params, scores

    held = [t[held_idx] for t in data]
    _, scores = run(fit_idx, cfg.max_steps, held)
    before = scores[0][0]
    after, steps = min(scores)
    if steps == 0:
        return [p.detach() for p in init], 0, (before, before)
    params, _ = run(slice(None), steps)
    return [p.detach() for p in params], steps, (before, after)


def refine(model, samples, embedding: Embedding | None = None, *, config: RefineConfig | None = None,
           seed: int = 0, name: str = "") -> RefineResult:
    """Refine a hypernetwork's reconstruction on its own samples (module docstring).

    Parameters
    ----------
    model
        :class:`~brdfkit.hypernet.loaded.LoadedNetwork`.
    samples
        :class:`~brdfkit.io.samples.SampleSet`, BRDF in 1/sr; rows with a NaN value are
        unmeasured and left out.
    embedding
        The encoder's embedding of ``samples`` (encoded here when ``None``).
    config
        :class:`RefineConfig` (its defaults when ``None``).
    seed
        Draws the held-out samples.

    Returns
    -------
    RefineResult
        Run on :data:`brdfkit.render.objective.THREADS` torch thread(s), so that
        the same samples give the same result to the bit, whatever the machine's load.
    """
    from brdfkit.render.objective import THREADS
    from brdfkit.runtime import torch_threads

    with torch_threads(THREADS):
        return _refine(model, samples, embedding, config or RefineConfig(), seed, name)


def _refine(model, samples, embedding, cfg: RefineConfig, seed: int, name: str) -> RefineResult:
    """:func:`refine` on the threads it set."""
    import torch

    from brdfkit.hypernet.encoding import encode_samples
    from brdfkit.hypernet.neural_brdf import NeuralBRDF

    emb = embedding if embedding is not None else encode_samples(model, samples, name)
    dev = model.device
    z0 = torch.from_numpy(np.asarray(emb.values, np.float32).copy()).to(dev)[None]
    ok = torch.from_numpy(samples.measured()).to(dev)
    n = int(ok.sum())
    if n < cfg.min_samples:
        return RefineResult(NeuralBRDF.from_embedding(model, emb, name), emb, {"latent": 0}, {})
    data = [t[ok] for t in _sample_tensors(model, samples, dev)]
    perm = np.random.default_rng(seed).permutation(n)
    k = max(1, int(round(cfg.holdout * n)))
    held_idx = torch.from_numpy(np.sort(perm[:k])).to(dev)
    fit_idx = torch.from_numpy(np.sort(perm[k:])).to(dev)
    net = model.net
    was = [p.requires_grad for p in net.parameters()]
    for p in net.parameters():
        p.requires_grad_(False)
    try:
        steps, heldout = {}, {}
        (z,), steps["latent"], heldout["latent"] = _stage(
            [z0], lambda ps: net.hyponet_weights(ps[0]),
            lambda ps: cfg.prior_latent * torch.mean((ps[0] - z0) ** 2),
            cfg.lr_latent, data, fit_idx, held_idx, cfg)
        out_emb = Embedding(z[0].cpu().numpy().astype(np.float32), "hypernet", emb.decoder, emb.source,
                            emb.sample_count)
        # Decoded as `decode` decodes the embedding (the fused kernels), so the two agree.
        brdf = NeuralBRDF.from_embedding(model, out_emb, name)
        if cfg.target == "weights":
            w0 = [t for pair in brdf.weights for t in pair]
            scale = float(sum(torch.sum(t ** 2) for t in w0))

            def pairs(ps):
                return [(ps[2 * i], ps[2 * i + 1]) for i in range(len(ps) // 2)]

            ws, steps["weights"], heldout["weights"] = _stage(
                w0, pairs,
                lambda ps: cfg.prior_weights * sum(torch.sum((p - q) ** 2) for p, q in zip(ps, w0)) / scale,
                cfg.lr_weights, data, fit_idx, held_idx, cfg)
            brdf = NeuralBRDF(model, out_emb, [(w.contiguous(), b.contiguous()) for w, b in pairs(ws)], name)
    finally:
        for p, r in zip(net.parameters(), was):
            p.requires_grad_(r)
    return RefineResult(brdf, out_emb, steps, heldout)
