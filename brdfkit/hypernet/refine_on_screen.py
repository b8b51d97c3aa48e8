"""Compression of a dense table into a hypernetwork latent, refined on screen.

The paper (Gokbudak et al. 2024, Sec. 4.2) compresses a material into its latent ``z``
with one pass of the set encoder over all its cells. That pass renders about 10 dB below
an 8-component PCA in the reference scene, and a refinement of ``z`` in the BRDF log
metric renders 3 dB *worse* again. :func:`compress_table` refines ``z`` on what renders
see instead: from the encoder's pass ``z0``
(:func:`brdfkit.hypernet.encoding.encode_table`), ``z`` descends the render-aligned error
of the objective scenes (:mod:`brdfkit.render.objective`: the scenes, the pair draws, the
held-out pixels and the budget in steps), the hyponet evaluated only at the scenes'
direction pairs (no dense table is decoded), and the latent with the lowest held-out
error is kept, the encoder's own included: refinement is never worse than the encoder
pass on the held-out pixels, and it stops after ``patience`` checks without a gain.

The whole compression runs on :data:`~brdfkit.render.objective.THREADS` torch thread(s)
whatever the caller's setting: the same table, model and version give the same latent to
the bit, however loaded the machine is (a wall-clock cap, ``max_seconds``, is only applied
when asked for, and the result says when it cut).

``docs/notes/render-error.md`` measures the error (rank correlation with 128 px renders on two
scenes), ``docs/model.md`` the error against encode time.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from brdfkit.io.embedding import Embedding
from brdfkit.render.objective import THREADS, ObjectiveConfig, objective_views

__all__ = ["DEFAULT_LR", "DEFAULT_STEPS", "CompressResult", "compress_table"]

DEFAULT_STEPS = 40
"""Most Adam steps of the refinement per table by default (``brdfkit encode --steps``).
Measured in the scene suite (``benchmarks/encode_budget.py``, 5 in-sample MERL proxies,
64 px, the six judged scenes' mean; ``docs/compression.md``): with the objective scenes,
0 / 20 / 40 / 80 steps gave 40.73 / 46.29 / 47.30 / 47.80 dB in 1.1 / 5.1 / 6.7 / 11.5 s
an encode on one thread at load 2 (record ``2026-11-26-encode-steps-objective.json``)."""

DEFAULT_LR = 0.005
"""Adam's learning rate on the latent when :attr:`ObjectiveConfig.lr` is ``None``. Chosen by
renders: on the six materials blue-metallic-paint, gold-metallic-paint, teflon,
chrome-steel, violet-rubber, red-fabric with the first screen-tuned ``merl-rgl-l40``, a
3 s budget and 64 px renders, 0.002 / 0.005 / 0.02 gave 44.58 / 45.39 / 42.64 dB (Delta E
0.62 / 0.60 / 0.78; the encoder's pass 36.91 dB, 1.31)."""


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


def compress_table(model, table, config: ObjectiveConfig | None = None, source: str = "",
                   encoder_embedding: Embedding | None = None) -> CompressResult:
    """Compress a dense table into the model's latent, refined on screen (module docstring).

    Parameters
    ----------
    model
        :class:`~brdfkit.hypernet.loaded.LoadedNetwork`, whose encoder gives the start.
    table
        ``(90, 90, 180, 3)`` BRDF in 1/sr, NaN where unmeasured.
    config
        :class:`~brdfkit.render.objective.ObjectiveConfig` (its defaults when ``None``;
        ``steps = 0`` skips the refinement).
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

    cfg = config or ObjectiveConfig(steps=DEFAULT_STEPS)
    with torch_threads(THREADS):
        emb0 = encoder_embedding if encoder_embedding is not None else encode_table(model, table, source)
        if cfg.steps == 0:
            return CompressResult(emb0, emb0, 0, 0, (float("nan"),) * 2, 0.0, "encoder")
        return _refine(model, table, cfg, emb0)


def _refine(model, table, cfg: ObjectiveConfig, emb0: Embedding) -> CompressResult:
    """The steps of :func:`compress_table` from the encoder's embedding ``emb0``, in the
    one refine-with-a-held-out-check loop (:func:`brdfkit.render.objective.refine_loop`):
    step ``k`` descends objective scene ``k mod K``'s fitted pixels (Adam; the unknown is a
    latent of a large network, so first-order steps through torch's autograd); the
    held-out error is the mean over all ``K`` scenes."""
    import torch

    from brdfkit.render.objective import Adam, refine_loop
    from brdfkit.render.screen import screen_error

    views = objective_views(table, cfg)
    tv = [v.tensors(model.device) for v in views]
    net = model.net
    was = [p.requires_grad for p in net.parameters()]
    for p in net.parameters():
        p.requires_grad_(False)

    def held_error(z):
        with torch.no_grad():
            w = net.hyponet_weights(z)
            return float(np.mean([float(screen_error(v.screen.render_hyponet(model, w, t["held_pairs"]), t["target"],
                                                     t["held_pixels"])) for v, t in zip(views, tv)]))

    try:
        z0 = torch.from_numpy(np.asarray(emb0.values, np.float32).copy()).to(model.device)[None]
        z = z0.clone().requires_grad_(True)
        opt = Adam([z], lr=cfg.learning_rate(DEFAULT_LR))

        def step(_, k):
            v, t = views[(k - 1) % len(views)], tv[(k - 1) % len(views)]
            img = v.screen.render_hyponet(model, net.hyponet_weights(z), t["idx"], t["weight"])
            loss = screen_error(img, t["target"], t["fit_pixels"])
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            return z, False

        start = time.perf_counter()
        zb, rec = refine_loop(z0, step, lambda x: held_error(x.detach()), steps=cfg.steps,
                              check_every=cfg.check_every, patience=cfg.patience, max_seconds=cfg.max_seconds,
                              solver="adam", snapshot=lambda x: x.detach().clone())
    finally:
        for p, r in zip(net.parameters(), was):
            p.requires_grad_(r)
    record = {key: rec[key] for key in ("steps", "best_step", "stopped", "solver")}
    record["heldout"] = [float(f"{e:.6g}") for e in rec["heldout"]]
    emb = Embedding(zb[0].cpu().numpy().astype(np.float32), "hypernet", emb0.decoder, emb0.source,
                    emb0.sample_count, refinement=record)
    return CompressResult(emb, emb0, rec["steps"], rec["best_step"], (rec["heldout"][0], min(rec["heldout"])),
                          time.perf_counter() - start, rec["stopped"])
