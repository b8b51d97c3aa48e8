"""Compression of a dense table into an embedding, refined on screen.

The paper (Gokbudak et al. 2024, Sec. 4.2) compresses a material into its latent ``z``
with one pass of the set encoder over all its cells. Issue 21 measured that pass 10 dB
below an 8-component PCA on the reference-scene renders, and a refinement of ``z`` in the
BRDF log metric 3 dB *worse* again on screen. :func:`compress_table` refines ``z`` on
what renders see instead:

1. ``z0``: the encoder's pass over all measured cells (:func:`brdfkit.hypernet.encoding.encode_table`).
2. The table and the hyponet of ``z`` are rendered in the low-resolution reference
   scene of :mod:`brdfkit.render.screen`; the error is the images' mean squared
   difference after the metrics' display encoding (exposure, clip, sRGB). The hyponet is
   evaluated only at the scene's direction pairs: no dense table is decoded.
3. ``z`` descends that error by Adam, within a wall-clock ``budget``; each step renders
   the hyponet from a fixed subset of the pairs (``pairs_per_pixel`` per pixel, drawn
   once in proportion to the table's own integrand, mixed with a uniform share, and
   weighted by ``1 / (K p)``: an unbiased estimate of the full render, exact for the
   table itself).
4. A ``holdout`` share of the pixels is never fitted; their error (full pairs) is checked
   every ``check_every`` steps, and the latent with the lowest held-out error is kept,
   the encoder's own included: refinement is never worse than the encoder pass on the
   held-out pixels, and it stops after ``patience`` checks without a gain.

``docs/render-error.md`` measures the error (rank correlation with 128 px renders on two
scenes), ``docs/model.md`` the error against encode time.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from brdfkit.io.embedding import Embedding
from brdfkit.errors import InputError, require_counts

__all__ = ["DEFAULT_BUDGET", "CompressConfig", "CompressResult", "compress_table"]

DEFAULT_BUDGET = 3.0
"""Seconds of refinement per table by default (``brdfkit encode --budget``)."""


@dataclasses.dataclass(frozen=True)
class CompressConfig:
    """Settings of :func:`compress_table`.

    Attributes
    ----------
    budget
        Wall-clock seconds of the refinement's steps (0: the encoder's pass alone); the
        set-up before them (the table's render and the pair draw) takes about 0.5 s more.
    max_steps
        Most Adam steps, whatever the budget.
    lr
        Adam's learning rate on the latent. Chosen by renders: on the six materials of
        issue 21 (blue-metallic-paint, gold-metallic-paint, teflon, chrome-steel,
        violet-rubber, red-fabric) with the first screen-tuned ``merl-rgl-l40``, a 3 s
        budget and 64 px renders, 0.002 / 0.005 / 0.02 gave 44.58 / 45.39 / 42.64 dB
        (Delta E 0.62 / 0.60 / 0.78; the encoder's pass 36.91 dB, 1.31), at load 3-4.
    pairs_per_pixel
        Pairs drawn per pixel for the fitted render (the full render has about 280).
    uniform_share
        Share of the draw that is uniform over a pixel's pairs rather than in proportion
        to the table's integrand (keeps pairs where the table is dark but a model may not be).
    holdout
        Share of the pixels held out to choose the latent, in ``(0, 1)``.
    check_every, patience
        Steps between held-out checks; checks without a gain before stopping.
    seed
        Draws the pairs and the held-out pixels.
    resolution
        Side in pixels of the render (:data:`brdfkit.render.screen.SCREEN_RESOLUTION`).
    """

    budget: float = DEFAULT_BUDGET
    max_steps: int = 400
    lr: float = 0.005
    pairs_per_pixel: int = 48
    uniform_share: float = 0.25
    holdout: float = 0.2
    check_every: int = 5
    patience: int = 6
    seed: int = 0
    resolution: int = 32

    def __post_init__(self):
        if not (self.budget >= 0.0 and np.isfinite(self.budget)):
            raise InputError(f"refinement budget must be a finite number of seconds >= 0, got {self.budget!r}")
        if not 0.0 < self.holdout < 1.0:
            raise InputError(f"holdout must be in (0, 1), got {self.holdout!r}")
        if not 0.0 <= self.uniform_share <= 1.0:
            raise InputError(f"uniform_share must be in [0, 1], got {self.uniform_share!r}")
        require_counts(self, ("max_steps", "pairs_per_pixel", "check_every", "patience", "resolution"))


@dataclasses.dataclass
class CompressResult:
    """What :func:`compress_table` did.

    Attributes
    ----------
    embedding
        The chosen latent.
    encoder
        The encoder pass's embedding (``z0``).
    steps
        Adam steps taken; ``best_step`` the one kept (0: the encoder's latent).
    heldout
        Held-out display MSE ``(encoder, kept)``.
    seconds
        Wall-clock seconds of the refinement's steps.
    """

    embedding: Embedding
    encoder: Embedding
    steps: int
    best_step: int
    heldout: tuple
    seconds: float


def _draw(screen, target, cfg, fit_pixels, device):
    """Fixed pair subset of the fitted pixels: ``(idx, weight)``, ``K`` pairs per pixel
    drawn in proportion to ``(1 - u) c_k / sum c + u / n`` (``c_k`` the table's integrand
    at the pair, luminance), weighted ``1 / (K p_k)``."""
    import torch

    rng = np.random.default_rng(cfg.seed)
    pix = screen.pix.cpu().numpy()
    c = (target * screen.rw.double()).sum(1).clamp_min(0).cpu().numpy()
    order = np.argsort(pix, kind="stable")
    starts = np.searchsorted(pix[order], np.arange(screen.pixels + 1))
    k = cfg.pairs_per_pixel
    idx, wts = [], []
    for p in fit_pixels:
        members = order[starts[p]:starts[p + 1]]
        if members.size == 0:
            continue
        cm = c[members]
        tot = cm.sum()
        prob = np.full(members.size, 1.0 / members.size)
        if tot > 0:
            prob = (1 - cfg.uniform_share) * cm / tot + cfg.uniform_share * prob
        pick = rng.choice(members.size, size=k, p=prob)
        idx.append(members[pick])
        wts.append(1.0 / (k * prob[pick]))
    idx = torch.from_numpy(np.concatenate(idx)).to(device)
    w = torch.from_numpy(np.concatenate(wts).astype(np.float32)).to(device)
    return idx, w


def compress_table(model, table, config: CompressConfig | None = None, source: str = "",
                   encoder_embedding: Embedding | None = None) -> CompressResult:
    """Compress a dense table into the model's latent, refined on screen (module docstring).

    Parameters
    ----------
    model
        :class:`~brdfkit.hypernet.loaded.NeuralModel`.
    table
        ``(90, 90, 180, 3)`` BRDF in 1/sr, NaN where unmeasured.
    config
        :class:`CompressConfig` (its defaults when ``None``; ``budget = 0`` skips the
        refinement).
    source
        Provenance recorded in the embedding.
    encoder_embedding
        The encoder's pass, when already made.

    Returns
    -------
    CompressResult
    """
    import torch

    from brdfkit.hypernet.encoding import encode_table
    from brdfkit.render.screen import screen, screen_error

    cfg = config or CompressConfig()
    emb0 = encoder_embedding if encoder_embedding is not None else encode_table(model, table, source)
    if cfg.budget <= 0:
        return CompressResult(emb0, emb0, 0, 0, (float("nan"),) * 2, 0.0)
    dev = model.device
    sc = screen(dev, cfg.resolution)
    with torch.no_grad():
        at_pairs = sc.lookup(table)
        target = sc.render_table(table, at_pairs)
    rng = np.random.default_rng(cfg.seed)
    perm = rng.permutation(sc.pixels)
    n_held = max(1, int(round(cfg.holdout * sc.pixels)))
    held_pix = torch.from_numpy(np.sort(perm[:n_held])).to(dev)
    fit_pix = np.sort(perm[n_held:])
    idx, wts = _draw(sc, at_pairs, cfg, fit_pix, dev)
    fit_pix_t = torch.from_numpy(fit_pix).to(dev)
    target_f = target.float()
    held_pairs = torch.isin(sc.pix, held_pix).nonzero().squeeze(1)

    net = model.net
    was = [p.requires_grad for p in net.parameters()]
    for p in net.parameters():
        p.requires_grad_(False)

    def held_error(z):
        with torch.no_grad():
            img = sc.render_hyponet(model, net.hyponet_weights(z), held_pairs)
            return float(screen_error(img, target_f, held_pix))

    try:
        z0 = torch.from_numpy(np.asarray(emb0.latent, np.float32).copy()).to(dev)[None]
        z = z0.clone().requires_grad_(True)
        opt = torch.optim.Adam([z], lr=cfg.lr)
        best = (held_error(z0), 0, z0.clone())  # also makes the reference at the pairs
        first = best[0]
        step = 0
        start = time.perf_counter()  # the budget is the steps': set-up is about 0.5-1 s
        while step < cfg.max_steps and time.perf_counter() - start < cfg.budget:
            loss = screen_error(sc.render_hyponet(model, net.hyponet_weights(z), idx, wts), target_f, fit_pix_t)
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            step += 1
            if step % cfg.check_every == 0:
                err = held_error(z.detach())
                if err < best[0]:
                    best = (err, step, z.detach().clone())
                elif step - best[1] >= cfg.patience * cfg.check_every:
                    break
    finally:
        for p, r in zip(net.parameters(), was):
            p.requires_grad_(r)
    err, best_step, zb = best
    emb = Embedding(zb[0].cpu().numpy().astype(np.float32), emb0.model_fingerprint, emb0.source,
                    emb0.sample_count)
    return CompressResult(emb, emb0, step, best_step, (first, err), time.perf_counter() - start)
