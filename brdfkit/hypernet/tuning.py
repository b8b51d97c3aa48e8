"""Screen tuning: a trained hypernetwork's auto-decoder stage, fitted on renders.

The paper trains the hypernetwork on its mapped loss alone (Gokbudak et al. 2024, eq. 3),
and its compressions render 10 dB below an 8-component PCA (``docs/notes/compression.md``). :func:`tune`
continues a trained model as an **auto-decoder** (Park et al. 2019, DeepSDF): one latent
``z_i`` per training material, initialised by the set encoder's pass over the material's
cells, is optimised *together with the decoder* on

    mean_i [ log E_screen(i) ] + map_weight * L_map + lambda_z mean(z^2)

* ``E_screen(i)``: the render-aligned error of :mod:`brdfkit.render.screen` (display MSE
  of a low-resolution render against the table's own render) in one of ``scenes``, the
  objective scenes of the suite (:mod:`brdfkit.render.scene_suite`; never a judged one;
  the shipped built-in models were tuned under the reference environment's turns 0, 0.25
  and 0.75 instead), with a fixed draw of ``pairs_per_pixel`` pairs per
  pixel, in proportion to the table's integrand, as in
  :mod:`brdfkit.hypernet.refine_on_screen`. The log makes the loss the *mean PSNR over
  materials* (a sum of ``-10 log10 MSE``), so a dark material counts as much as a bright
  one.
* ``L_map``: the paper's cosine-weighted mapped MSE on ``query`` random measured cells,
  which keeps the BRDF right where no render looks.

The **set encoder** is trained at the same time to reach the latents: the squared distance
of its pass over ``context`` random cells to ``z_i`` (a target, not a gradient path), so
that an encoder pass lands where the refinement of :mod:`brdfkit.hypernet.refine_on_screen` starts.

A checkpoint ``<output>.ckpt`` is written every ``checkpoint_minutes`` and on Ctrl-C;
``resume=True`` continues it (the batches are seeded by ``(seed, step)``); the learning
rates may be changed on resuming, the other options not.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import time

import numpy as np

from brdfkit.errors import InputError, require_counts
from brdfkit.hypernet.ratio_floor import floor_data, floor_loss, low_ratio_cells
from brdfkit.render.objective import OBJECTIVE

__all__ = ["TuneOptions", "tune"]

_COUNTS = ("batch", "pairs_per_pixel", "query", "context", "resolution")
"""The integer options of :class:`TuneOptions` (each at least 1)."""

@dataclasses.dataclass(frozen=True)
class TuneOptions:
    """Settings of :func:`tune` (``brdfkit tune -O KEY=VALUE``).

    Attributes
    ----------
    lr_decoder, lr_latent, lr_encoder
        Adam learning rates of the decoder, the per-material latents and the encoder.
    batch
        Materials per step.
    pairs_per_pixel
        Pairs per pixel of each material's fixed draw (the full 32 px render has ~280).
    scenes
        The objective scenes the renders are fitted in (default those of
        :data:`brdfkit.render.objective.OBJECTIVE`).
    map_weight
        Weight of the paper's mapped loss.
    lambda_z
        Weight of the latents' mean square.
    query, context
        Cells per material for the mapped loss and for the encoder's context.
    resolution
        Side in pixels of the renders (:data:`brdfkit.render.screen.SCREEN_RESOLUTION`).
    floor_weight
        Weight of the ratio floor (0: none): the one-sided loss
        ``mean(relu(1 - pred / m_f)^2)``, ``m_f`` the mapped value of ``floor_ratio``
        times the material's value, on the ``query`` uniform cells and ``query`` cells of
        :data:`~brdfkit.hypernet.ratio_floor.FLOOR_REGION`. It is 0 wherever the decoded value is at least that share of
        the material's, and sees the relative error where the mapped loss does not (a
        material far below the reference, whose mapped value is nearly 0).
    floor_ratio
        The share of the material's value below which :attr:`floor_weight` costs, in (0, 1).
    floor_candidates
        Uniform cells per material and step among which the ratio floor also takes up to
        ``query`` where the material is far below the reference
        (:func:`~brdfkit.hypernet.ratio_floor.low_ratio_cells`; 0: none): the dark cells
        under a bright median, wherever they are.
    """

    lr_decoder: float = 1e-4
    lr_latent: float = 3e-3
    lr_encoder: float = 3e-4
    batch: int = 4
    pairs_per_pixel: int = 32
    scenes: tuple = OBJECTIVE
    map_weight: float = 1.0
    lambda_z: float = 1e-3
    query: int = 4096
    context: int = 4096
    resolution: int = 32
    floor_weight: float = 0.0
    floor_ratio: float = 0.1
    floor_candidates: int = 0

    def __post_init__(self):
        for name in ("lr_decoder", "lr_latent", "lr_encoder", "map_weight", "lambda_z", "floor_weight"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise InputError(f"tune option {name} must be a finite number >= 0, got {v!r}")
        if not (isinstance(self.floor_candidates, int) and self.floor_candidates >= 0):
            raise InputError(f"tune option floor_candidates must be a count >= 0, got {self.floor_candidates!r}")
        if not (isinstance(self.floor_ratio, (int, float)) and 0 < self.floor_ratio < 1):
            raise InputError(f"tune option floor_ratio must be in (0, 1), got {self.floor_ratio!r}")
        require_counts(self, _COUNTS, "tune option ")
        from brdfkit.render.scene_suite import require_objective

        require_objective(self.scenes, "tune option scenes")

    @classmethod
    def parse(cls, given: dict) -> "TuneOptions":
        """From ``-O KEY=VALUE`` strings (``scenes=studio-0,studio-1``)."""
        fields = {f.name: f for f in dataclasses.fields(cls)}
        out = {}
        for key, value in given.items():
            if key not in fields:
                raise InputError(f"unknown tune option {key!r}; known: {', '.join(fields)}")
            try:
                if key == "scenes":
                    parts = value if isinstance(value, (tuple, list)) else str(value).split(",")
                    out[key] = tuple(str(v).strip() for v in parts)
                elif key in _COUNTS or key == "floor_candidates":
                    out[key] = int(value)
                else:
                    out[key] = float(value)
            except ValueError:
                raise InputError(f"tune option {key}={value!r} is not a number") from None
        return cls(**out)


def _material_data(model, paths, opts, screens, dev):
    """Per material: the encoder's latent, and per screen the table's image and the fixed
    pair draw ``(idx, weight)`` (:func:`brdfkit.render.objective.draw_pairs`)."""
    import torch

    from brdfkit.render.objective import ObjectiveConfig, draw_pairs
    from brdfkit.io.merl import read_merl
    from brdfkit.hypernet.encoding import encode_table

    cfg = ObjectiveConfig(pairs_per_pixel=opts.pairs_per_pixel, uniform_share=0.25)
    latents, per = [], []
    for i, p in enumerate(paths):
        table = read_merl(p)
        latents.append(np.asarray(encode_table(model, table).values, np.float32))
        views = []
        for k, sc in enumerate(screens):
            at = sc.lookup(table)  # the screens are NumPy; the tuning's tensors go to its device
            target = torch.from_numpy(sc.render_table(table, at).astype(np.float32)).to(dev)
            idx, w = draw_pairs(sc, at, dataclasses.replace(cfg, seed=1000 * i + k), np.arange(sc.pixels), dev)
            views.append((target, idx.int(), w))
        per.append(views)
    return np.stack(latents), per


def _identity_without_rates(text):
    """A checkpoint's identity with the learning rates left out (checkpoints of the first
    tunes recorded them; they may change on resuming)."""
    try:
        doc = json.loads(text)
        for key in ("lr_decoder", "lr_latent", "lr_encoder"):
            doc["options"].pop(key, None)
    except (TypeError, ValueError, KeyError, AttributeError):
        return None
    return json.dumps(doc, sort_keys=True)


def _identity(model_digest, names, opts, seed) -> str:
    """What a checkpoint must have been made for to be resumed: the model, the materials,
    the options but the learning rates, the seed (JSON, sorted keys)."""
    fields = dataclasses.asdict(opts)
    for key, default in (("resolution", 32), ("floor_weight", 0.0), ("floor_ratio", 0.1), ("floor_candidates", 0)):
        if fields[key] == default:  # added later: left out at its default, so older checkpoints resume
            del fields[key]
    for key in ("lr_decoder", "lr_latent", "lr_encoder"):  # may change on --resume
        del fields[key]
    return json.dumps({"model": model_digest, "materials": names, "options": fields, "seed": seed},
                      sort_keys=True)


@dataclasses.dataclass
class _Tuning:
    """A tune in progress: the trained tensors, their optimisers and what its checkpoint
    records.

    Attributes
    ----------
    net
        The model's :class:`~brdfkit.hypernet.network.HyperBRDF`, in training mode.
    latents
        Per material, its latent, float32 torch ``(1, latent_dim)`` with gradients.
    opt_dec, opt_lat, opt_enc
        Adam on the decoder, the latents and the encoder.
    identity
        :func:`_identity` of the run.
    names, digest, seed
        The materials, the training set's digest and the seed.
    t0
        ``time.monotonic()`` at the call.
    step, elapsed0, history
        Steps done, seconds spent by earlier runs of a resumed tune, and the
        ``(step, PSNR ema, mapped loss, encoder loss)`` every 50 steps.
    ema
        Exponential moving average of the batches' screen PSNR (dB); ``None`` before a step.
    """

    net: object
    latents: list
    opt_dec: object
    opt_lat: object
    opt_enc: object
    identity: str
    names: list
    digest: str
    seed: int
    t0: float
    step: int = 0
    elapsed0: float = 0.0
    history: list = dataclasses.field(default_factory=list)
    ema: float | None = None

    @property
    def optimizers(self) -> tuple:
        """``(opt_dec, opt_lat, opt_enc)``."""
        return self.opt_dec, self.opt_lat, self.opt_enc

    def checkpoint_state(self) -> dict:
        """The state :func:`brdfkit.hypernet.training.checkpoint.save_checkpoint` writes."""
        import torch

        return {"step": self.step, "elapsed": self.elapsed0 + time.monotonic() - self.t0,
                "net": self.net.state_dict(), "latents": torch.cat([z.detach() for z in self.latents]),
                "optimizer": {"opt_dec": self.opt_dec.state_dict(), "opt_lat": self.opt_lat.state_dict(),
                              "opt_enc": self.opt_enc.state_dict()},
                "history": self.history, "config": "", "options": self.identity, "materials": self.names,
                "data_digest": self.digest, "seed": self.seed}


def _start(net, z0, opts, dev, **record) -> _Tuning:
    """The tune of ``net`` from the encoder's latents ``z0`` (float32 ``(materials,
    latent_dim)``): everything trainable, one Adam per part at the options' rates;
    ``record``: the other :class:`_Tuning` fields."""
    import torch

    net.train()
    for p in net.parameters():
        p.requires_grad_(True)
    latents = [torch.from_numpy(z[None].copy()).to(dev).requires_grad_(True) for z in z0]
    opt_dec = torch.optim.Adam(net.decoder.parameters(), lr=opts.lr_decoder)
    opt_lat = torch.optim.Adam(latents, lr=opts.lr_latent)
    opt_enc = torch.optim.Adam(net.encoder.parameters(), lr=opts.lr_encoder)
    return _Tuning(net, latents, opt_dec, opt_lat, opt_enc, **record)


def _resume(run: _Tuning, state: dict, ckpt, opts):
    """Continue ``run`` from the checkpoint ``state`` read from ``ckpt``, at the options'
    learning rates; refused if it was made for another identity."""
    if _identity_without_rates(state.get("options")) != run.identity:
        raise InputError(f"{ckpt}: checkpoint was made for another model, data or options; "
                         f"tune afresh without --resume")
    run.net.load_state_dict(state["net"])
    for z, v in zip(run.latents, state["latents"]):
        z.data.copy_(v)
    for o, k, lr in ((run.opt_dec, "opt_dec", opts.lr_decoder), (run.opt_lat, "opt_lat", opts.lr_latent),
                     (run.opt_enc, "opt_enc", opts.lr_encoder)):
        o.load_state_dict(state["optimizer"][k])
        for group in o.param_groups:  # the options' rates, not the checkpoint's
            group["lr"] = lr
    run.step, run.elapsed0, run.history = int(state["step"]), float(state["elapsed"]), list(state["history"])


def _step(run: _Tuning, m, screens, views, values, cells, gen, opts, dev, floor=None):
    """One optimiser step on a batch seeded by ``(run.seed, run.step)``.

    ``values``: float32 torch ``(materials, n_cells, 3)``, the mapped values at ``cells``
    (int64 ``(n_cells,)`` flat MERL indices), on ``dev``; ``floor``: ``(positions in ``cells``
    of :data:`~brdfkit.hypernet.ratio_floor.FLOOR_REGION`, mapped value of 0 at ``cells``)`` (``None``: no ratio floor);
    ``views[i][k]``: material ``i``'s
    target image and pair draw under ``screens[k]``. Returns the batch's sums of the log
    screen errors, of the mapped losses, of the encoder's losses and of the ratio floor's
    losses (torch scalars; the last 0.0 without a floor).
    """
    import torch

    from brdfkit.geometry import cell_angles, cos_theta_i, hd_vectors
    from brdfkit.hypernet.network import hyponet_forward
    from brdfkit.render.screen import screen_error

    net, latents = run.net, run.latents
    gen.manual_seed(int(np.random.SeedSequence([run.seed, run.step]).generate_state(1, np.uint64)[0]))
    mats = torch.randperm(len(run.names), generator=gen)[:opts.batch]
    turn = torch.randint(0, len(screens), (opts.batch,), generator=gen)
    q = torch.randint(0, cells.numel(), (opts.batch, opts.query), generator=gen).to(dev)
    c = torch.randint(0, cells.numel(), (opts.batch, opts.context), generator=gen).to(dev)
    loss_s = loss_m = loss_e = loss_f = 0.0
    for b in range(opts.batch):
        i, k = int(mats[b]), int(turn[b])
        target, idx, w = views[i][k]
        weights = net.hyponet_weights(latents[i])
        img = screens[k].render_hyponet(m, weights, idx.long(), w)
        loss_s = loss_s + torch.log(screen_error(img, target) + 1e-10)
        th, td, pd = (a.float() for a in cell_angles(cells[q[b]]))
        pred = hyponet_forward(weights, hd_vectors(th, td, pd)[None])[0]
        cos = cos_theta_i(th, td, pd).clamp(min=0.0)[:, None]
        loss_m = loss_m + torch.mean((cos * (pred - values[i, q[b]])) ** 2)
        if floor is not None:
            region, zero = floor
            p = region[torch.randint(0, region.numel(), (opts.query,), generator=gen).to(dev)]
            th, td, pd = (a.float() for a in cell_angles(cells[p]))
            pred_r = hyponet_forward(weights, hd_vectors(th, td, pd)[None])[0]
            loss_f = loss_f + (floor_loss(pred, values[i, q[b]], zero[q[b]], opts.floor_ratio)
                               + floor_loss(pred_r, values[i, p], zero[p], opts.floor_ratio))
            if opts.floor_candidates:
                p = low_ratio_cells(values[i], opts.floor_candidates, opts.query, gen, dev)
                if p.numel():
                    th, td, pd = (a.float() for a in cell_angles(cells[p]))
                    pred_l = hyponet_forward(weights, hd_vectors(th, td, pd)[None])[0]
                    loss_f = loss_f + floor_loss(pred_l, values[i, p], zero[p], opts.floor_ratio)
        th, td, pd = (a.float() for a in cell_angles(cells[c[b]]))
        z_enc = net.encode(hd_vectors(th, td, pd)[None], values[i, c[b]][None])
        loss_e = loss_e + torch.mean((z_enc - latents[i].detach()) ** 2)
    zs = torch.cat([latents[int(i)] for i in mats])
    loss = ((loss_s + opts.map_weight * loss_m + opts.floor_weight * loss_f) / opts.batch
            + opts.lambda_z * torch.mean(zs ** 2))
    for o in run.optimizers:
        o.zero_grad(set_to_none=True)
    (loss + loss_e / opts.batch).backward()
    torch.nn.utils.clip_grad_norm_(net.decoder.parameters(), 1.0)
    for o in run.optimizers:
        o.step()
    return loss_s, loss_m, loss_e, loss_f


def _loop(run: _Tuning, m, screens, views, tset, opts, dev, steps, minutes, checkpoint_minutes, ckpt, say):
    """The steps until ``steps`` or ``minutes`` (since ``run.t0``), a checkpoint every
    ``checkpoint_minutes`` and on Ctrl-C (then re-raised)."""
    import torch

    from brdfkit.hypernet.training.checkpoint import save_checkpoint

    values = torch.from_numpy(tset.values).to(dev)
    cells = torch.from_numpy(tset.cells).to(dev)
    floor = floor_data(tset, dev) if opts.floor_weight > 0 else None
    gen = torch.Generator()
    last_ckpt = time.monotonic()
    say(f"tuning from step {run.step}")
    try:
        while (steps is None or run.step < steps) and (minutes is None or time.monotonic() - run.t0 < 60 * minutes):
            loss_s, loss_m, loss_e, loss_f = _step(run, m, screens, views, values, cells, gen, opts, dev, floor)
            run.step += 1
            psnr = -10 * loss_s.item() / opts.batch / math.log(10)
            run.ema = psnr if run.ema is None else 0.98 * run.ema + 0.02 * psnr
            if run.step % 50 == 0:
                run.history.append((run.step, round(run.ema, 3), float(loss_m) / opts.batch,
                                    float(loss_e) / opts.batch))
                say(f"step {run.step}: screen PSNR (ema) {run.ema:.2f} dB, "
                    f"mapped {float(loss_m) / opts.batch:.4g}, "
                    f"encoder {float(loss_e) / opts.batch:.4g}, "
                    + (f"floor {float(loss_f) / opts.batch:.4g}, " if floor is not None else "")
                    + f"{time.monotonic() - run.t0:.0f} s")
            if time.monotonic() - last_ckpt > 60 * checkpoint_minutes:
                save_checkpoint(ckpt, run.checkpoint_state())
                last_ckpt = time.monotonic()
    except KeyboardInterrupt:
        save_checkpoint(ckpt, run.checkpoint_state())
        raise
    save_checkpoint(ckpt, run.checkpoint_state())


def tune(model, data, output, *, exclude=(), steps: int | None = None, minutes: float | None = None,
         seed: int = 0, resume: bool = False, options: TuneOptions | None = None,
         checkpoint_minutes: float = 2.0, device=None, progress=None) -> dict:
    """Tune a trained hypernetwork on renders of its materials (module docstring).

    Parameters
    ----------
    model
        Model file or built-in name (:func:`brdfkit.models.builtin.resolve_network`); its reference table
        and architecture are kept.
    data
        MERL ``.binary`` files or folders (:func:`brdfkit.io.folders.collect_materials`).
    output
        Model file to write; the checkpoint is ``<output>.ckpt``.
    exclude
        Material names to leave out.
    steps, minutes
        Stop after this many steps or minutes (since the call), whichever first; one of
        them is required.
    options
        :class:`TuneOptions`.
    device
        ``"auto"`` / ``None`` (CUDA when present), ``"cpu"`` or ``"cuda"``.
    progress
        Optional callable ``progress(message)``.

    Returns
    -------
    dict
        The provenance saved in the model's ``meta["tune"]``.
    """
    import torch

    from brdfkit.atomic import refuse_overwrite_of_inputs
    from brdfkit.hypernet.training.checkpoint import checkpoint_path, load_checkpoint
    from brdfkit.io.folders import collect_materials
    from brdfkit.hypernet.network_file import load_network, save_network
    from brdfkit.models.builtin import resolve_network
    from brdfkit.render.scene_suite import scene_env
    from brdfkit.render.screen import screen
    from brdfkit.hypernet.training.dataset import TrainingSet
    from brdfkit.runtime import resolve_device

    t0 = time.monotonic()
    opts = options or TuneOptions()
    if steps is None and minutes is None:
        raise InputError("tune needs --steps or --minutes")
    say = progress or (lambda msg: None)
    output = os.fspath(output)
    ckpt = checkpoint_path(output)
    paths, names, excluded, _ = collect_materials(data, exclude)
    dev = resolve_device(None if device == "auto" else device)
    m = load_network(resolve_network(model), dev)
    refuse_overwrite_of_inputs(output, [*paths, m.path])
    refuse_overwrite_of_inputs(ckpt, [*paths, m.path])
    torch.manual_seed(seed)
    screens = [screen(dev, opts.resolution, scene_env(s)) for s in opts.scenes]
    say(f"reading {len(paths)} materials")
    z0, views = _material_data(m, paths, opts, screens, dev)
    tset = TrainingSet.load(paths, names, reference=m.rho_ref)
    run = _start(m.net, z0, opts, dev, identity=_identity(m.digest, names, opts, seed), names=names,
                 digest=tset.digest, seed=seed, t0=t0)
    if resume:
        _resume(run, load_checkpoint(ckpt, dev), ckpt, opts)
    _loop(run, m, screens, views, tset, opts, dev, steps, minutes, checkpoint_minutes, ckpt, say)
    run.net.eval()
    tuned = {"from": m.digest, "steps": run.step, "options": dataclasses.asdict(opts), "seed": seed,
             "wall_time_s": round(run.elapsed0 + time.monotonic() - t0, 1), "screen_psnr_ema": run.ema,
             "materials": names, "excluded": excluded}
    meta = dict(m.meta, tune=tuned)
    save_network(output, run.net, m.rho_ref, meta)
    return tuned
