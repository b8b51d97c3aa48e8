"""Compression of a dense table into an embedding, refined on screen.

The paper (Gokbudak et al. 2024, Sec. 4.2) compresses a material into its latent ``z``
with one pass of the set encoder over all its cells. Issue 21 measured that pass 10 dB
below an 8-component PCA on the reference-scene renders, and a refinement of ``z`` in the
BRDF log metric 3 dB *worse* again on screen. :func:`compress_table` refines ``z`` on
what renders see instead:

1. ``z0``: the encoder's pass over all measured cells (:func:`brdfkit.hypernet.encoding.encode_table`).
2. The table and the hyponet of ``z`` are rendered in low-resolution objective scenes of
   the suite (:data:`OBJECTIVE`, :mod:`brdfkit.render.screen`, never a scene the results
   judge by: issue 28); the error is the images' mean squared difference after the
   metrics' display encoding (exposure, clip, sRGB). The hyponet is evaluated only at the
   scenes' direction pairs: no dense table is decoded. Until issue 28 it was the reference
   scene, the one the results were judged in.
3. ``z`` descends that error by Adam, for at most ``steps`` steps; each step renders
   the hyponet from a fixed subset of the pairs (``pairs_per_pixel`` per pixel, drawn
   once in proportion to the table's own integrand, mixed with a uniform share, and
   weighted by ``1 / (K p)``: an unbiased estimate of the full render, exact for the
   table itself).
4. A ``holdout`` share of the pixels is never fitted; their error (full pairs) is checked
   every ``check_every`` steps, and the latent with the lowest held-out error is kept,
   the encoder's own included: refinement is never worse than the encoder pass on the
   held-out pixels, and it stops after ``patience`` checks without a gain.

The budget is counted in steps, never in seconds, and the whole compression runs on
:data:`THREADS` torch thread(s) whatever the caller's setting: the same table, model and
version give the same latent to the bit, however loaded the machine is (a wall-clock cap,
``max_seconds``, is only applied when asked for, and the result says when it cut).

``docs/render-error.md`` measures the error (rank correlation with 128 px renders on two
scenes), ``docs/model.md`` the error against encode time.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from brdfkit.io.embedding import Embedding
from brdfkit.errors import InputError, require_counts

__all__ = ["DEFAULT_STEPS", "OBJECTIVE", "THREADS", "CompressConfig", "CompressResult", "compress_table",
           "draw_pairs"]

DEFAULT_STEPS = 40
"""Most Adam steps of the refinement per table by default (``brdfkit encode --steps``).
Measured in the scene suite (``benchmarks/encode_budget.py``, 5 in-sample MERL proxies,
64 px, the six judged scenes' mean; ``docs/compression.md``): with the objective scenes,
0 / 20 / 40 / 80 steps gave 40.73 / 46.29 / 47.30 / 47.80 dB in 1.1 / 5.1 / 6.7 / 11.5 s
an encode on one thread at load 2 (record ``2026-11-26-encode-steps-objective.json``)."""

OBJECTIVE = ("studio-0", "studio-1", "studio-2", "studio-3")
"""The scenes the refinement descends: four of the suite's objective scenes, none of them
judged. Chosen by ``benchmarks/studies/study_error.py --judges suite``
(``docs/render-error.md``): over 10 test materials and 120 reconstructions, their
render-aligned error ranks reconstructions as the five held-out scenes' mean does with
Spearman 0.966 (PSNR) / 0.959 (Delta E), the reference scene's own 0.930 / 0.908, the
BRDF log RMSE 0.647 / 0.638."""

THREADS = 1
"""Torch threads of a compression, fixed so that its result does not depend on the
thread count a loaded machine would pick (two threads and one give other bits in the
refinement's reductions)."""


@dataclasses.dataclass(frozen=True)
class CompressConfig:
    """Settings of :func:`compress_table`.

    Attributes
    ----------
    steps
        Most Adam steps (0: the encoder's pass alone); fewer when the held-out error
        stops improving (``patience``).
    max_seconds
        A wall-clock cap on the steps, or ``None`` (the default: none). A run it cuts
        depends on the machine's speed and load; the result says so (``stopped``).
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
    scenes
        The scenes the refinement descends (:data:`OBJECTIVE`): objective scenes of the
        suite, never a judged one (:mod:`brdfkit.render.scene_suite`).
    """

    steps: int = DEFAULT_STEPS
    max_seconds: float | None = None
    lr: float = 0.005
    pairs_per_pixel: int = 48
    uniform_share: float = 0.25
    holdout: float = 0.2
    check_every: int = 5
    patience: int = 6
    seed: int = 0
    resolution: int = 32
    scenes: tuple = OBJECTIVE

    def __post_init__(self):
        if not (isinstance(self.steps, int) and not isinstance(self.steps, bool) and self.steps >= 0):
            raise InputError(f"refinement steps must be a whole number >= 0, got {self.steps!r}")
        if self.max_seconds is not None and not (self.max_seconds > 0.0 and np.isfinite(self.max_seconds)):
            raise InputError(f"max_seconds must be a finite number of seconds > 0, got {self.max_seconds!r}")
        if not 0.0 < self.holdout < 1.0:
            raise InputError(f"holdout must be in (0, 1), got {self.holdout!r}")
        if not 0.0 <= self.uniform_share <= 1.0:
            raise InputError(f"uniform_share must be in [0, 1], got {self.uniform_share!r}")
        require_counts(self, ("pairs_per_pixel", "check_every", "patience", "resolution"))
        from brdfkit.render.scene_suite import require_objective

        require_objective(self.scenes, "refinement scenes")


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
    stopped
        Why the steps ended: ``"steps"`` (all of them ran), ``"converged"`` (the
        held-out error stopped improving), ``"max_seconds"`` (cut by the wall-clock cap:
        not reproducible) or ``"encoder"`` (no refinement).
    """

    embedding: Embedding
    encoder: Embedding
    steps: int
    best_step: int
    heldout: tuple
    seconds: float
    stopped: str = "steps"


def draw_pairs(screen, target, cfg, fit_pixels, device):
    """A fixed draw of a screen's pairs, for renders that estimate the full one.

    In each of ``fit_pixels``, ``K = cfg.pairs_per_pixel`` of the pixel's ``n`` pairs
    are drawn with replacement, pair ``k`` with probability
    ``p_k = (1 - u) c_k / sum c + u / n`` (``u = cfg.uniform_share``; ``c_k`` the table's
    integrand at the pair, ``target * screen.rw`` summed over the channels; uniform when
    the pixel's integrand is zero) and weighted ``1 / (K p_k)``, so that
    ``screen.render_hyponet(..., idx, weight)`` is an unbiased estimate of the full
    render, exact for the table itself. Pixels without pairs are skipped.

    Parameters
    ----------
    screen
        :class:`brdfkit.render.screen.Screen` with ``M`` pairs and ``P`` pixels.
    target
        The table at the pairs (:meth:`brdfkit.render.screen.Screen.lookup`), float64
        torch ``(M, 3)``, 1/sr.
    cfg
        :class:`CompressConfig`: ``seed`` (of a NumPy generator), ``pairs_per_pixel``
        and ``uniform_share``.
    fit_pixels
        Integer array of the pixels to draw in, each in ``[0, P)``, in the draw's order.
    device
        Torch device of the results.

    Returns
    -------
    idx : torch.Tensor
        int64 ``(K * F,)`` pair indices in ``[0, M)``, ``K`` per pixel with pairs, pixel
        after pixel (``F`` such pixels).
    weight : torch.Tensor
        float32 ``(K * F,)`` the pairs' ``1 / (K p_k)``.
    """
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
        :class:`CompressConfig` (its defaults when ``None``; ``steps = 0`` skips the
        refinement).
    source
        Provenance recorded in the embedding.
    encoder_embedding
        The encoder's pass, when already made.

    Returns
    -------
    CompressResult
        Its embedding records the refinement (``Embedding.refinement``: steps, the step
        kept, why it stopped).
    """
    from brdfkit.hypernet.encoding import encode_table
    from brdfkit.runtime import torch_threads

    cfg = config or CompressConfig()
    with torch_threads(THREADS):
        emb0 = encoder_embedding if encoder_embedding is not None else encode_table(model, table, source)
        if cfg.steps == 0:
            return CompressResult(emb0, emb0, 0, 0, (float("nan"),) * 2, 0.0, "encoder")
        return _refine(model, table, cfg, emb0)


@dataclasses.dataclass
class _View:
    """One objective scene's small render of the table: its screen, the fitted pixels'
    pair draw and the held-out pixels' pairs, the target image (float32 torch)."""

    screen: object
    idx: object
    weight: object
    fit_pixels: object
    held_pixels: object
    held_pairs: object
    target: object


def _views(table, cfg: CompressConfig, dev) -> list:
    """The :class:`_View` of every objective scene of ``cfg.scenes``, each with its own
    held-out pixels and pair draw (seeded by ``cfg.seed``)."""
    import torch

    from brdfkit.render.scene_suite import scene_env
    from brdfkit.render.screen import screen

    rng = np.random.default_rng(cfg.seed)
    views = []
    for name in cfg.scenes:
        sc = screen(dev, cfg.resolution, env=scene_env(name))
        with torch.no_grad():
            at_pairs = sc.lookup(table)
            target = sc.render_table(table, at_pairs)
        perm = rng.permutation(sc.pixels)
        n_held = max(1, int(round(cfg.holdout * sc.pixels)))
        held = torch.from_numpy(np.sort(perm[:n_held])).to(dev)
        fit = np.sort(perm[n_held:])
        idx, wts = draw_pairs(sc, at_pairs, cfg, fit, dev)
        views.append(_View(sc, idx, wts, torch.from_numpy(fit).to(dev), held,
                           torch.isin(sc.pix, held).nonzero().squeeze(1), target.float()))
    return views


def _refine(model, table, cfg: CompressConfig, emb0: Embedding) -> CompressResult:
    """The steps of :func:`compress_table` from the encoder's embedding ``emb0``: step
    ``k`` descends objective scene ``k mod K``'s fitted pixels; the held-out error is
    the mean over all ``K`` scenes."""
    import torch

    from brdfkit.render.screen import screen_error

    views = _views(table, cfg, model.device)
    net = model.net
    was = [p.requires_grad for p in net.parameters()]
    for p in net.parameters():
        p.requires_grad_(False)

    def held_error(z):
        with torch.no_grad():
            w = net.hyponet_weights(z)
            return float(np.mean([float(screen_error(v.screen.render_hyponet(model, w, v.held_pairs), v.target,
                                                     v.held_pixels)) for v in views]))

    try:
        z0 = torch.from_numpy(np.asarray(emb0.latent, np.float32).copy()).to(model.device)[None]
        z = z0.clone().requires_grad_(True)
        opt = torch.optim.Adam([z], lr=cfg.lr)
        best = (held_error(z0), 0, z0.clone())  # also makes the reference at the pairs
        first, step, stopped = best[0], 0, "steps"
        start = time.perf_counter()
        while step < cfg.steps:
            if cfg.max_seconds is not None and time.perf_counter() - start >= cfg.max_seconds:
                stopped = "max_seconds"
                break
            v = views[step % len(views)]
            img = v.screen.render_hyponet(model, net.hyponet_weights(z), v.idx, v.weight)
            loss = screen_error(img, v.target, v.fit_pixels)
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            step += 1
            if step % cfg.check_every == 0:
                err = held_error(z.detach())
                if err < best[0]:
                    best = (err, step, z.detach().clone())
                elif step - best[1] >= cfg.patience * cfg.check_every:
                    stopped = "converged"
                    break
    finally:
        for p, r in zip(net.parameters(), was):
            p.requires_grad_(r)
    err, best_step, zb = best
    record = {"steps": step, "best_step": best_step, "stopped": stopped}
    emb = Embedding(zb[0].cpu().numpy().astype(np.float32), emb0.model_fingerprint, emb0.source,
                    emb0.sample_count, refinement=record)
    return CompressResult(emb, emb0, step, best_step, (first, err), time.perf_counter() - start, stopped)
