"""The options of a training run (:func:`brdfkit.hypernet.training.loop.fit`): :class:`TrainOptions`,
their checks together with the architecture's (:func:`parse_options`, for ``brdfkit fit
-O KEY=VALUE``), and the learning-rate schedule they define (:func:`lr_factor`).

They are kept apart from the step loop because a checkpoint's identity, the benchmarks and
the tests read them without training anything. ``docs/training.md`` lists the keys and
why the defaults are what they are.
"""

from __future__ import annotations

import dataclasses
import json
import math

from brdfkit.errors import InputError

__all__ = ["TrainOptions", "parse_options", "lr_factor"]


@dataclasses.dataclass(frozen=True)
class TrainOptions:
    """Advanced training options (``fit(**advanced)``, ``brdfkit fit -O KEY=VALUE``).

    Attributes
    ----------
    batch_materials
        Materials per step and process (capped at the process's share).
    query_size
        Query cells per material per step (the loss).
    context_min, context_max
        Range of the context size, drawn log-uniformly once per step.
    angle_fraction
        Share of context sets drawn uniformly over angles (the rest: over cells).
    lr, warmup_steps, lr_schedule, lr_final
        Adam learning rate, linear warm-up length (steps), then ``"cosine"`` (decay to
        ``lr * lr_final`` at the end of the run: the last step, or the end of the
        ``minutes`` budget, whichever comes first) or ``"constant"``. Measured in
        ``docs/training.md``: cosine from 1e-3 trained best.
    grad_clip
        Gradient norm clip.
    checkpoint_minutes
        Minutes between checkpoints.
    max_bad_steps
        Consecutive non-finite steps after which training stops with an error.
    weight_decay
        Decoupled weight decay (AdamW, Loshchilov & Hutter 2019); 0: plain Adam.
    mixup
        Probability that a batch slot mixes two training materials in mapped space
        (:class:`brdfkit.hypernet.training.dataset.BatchSampler`); 0: never.
    """

    batch_materials: int = 8
    query_size: int = 4096
    context_min: int = 40
    context_max: int = 4000
    angle_fraction: float = 0.5
    lr: float = 1e-3
    warmup_steps: int = 100
    lr_schedule: str = "cosine"
    lr_final: float = 0.1
    grad_clip: float = 1.0
    checkpoint_minutes: float = 2.0
    max_bad_steps: int = 25
    weight_decay: float = 0.0
    mixup: float = 0.0

    # Options that may change between a run and its resumption.
    RESUMABLE_CHANGES = ("checkpoint_minutes", "max_bad_steps")
    # Options added later: left out of the identity at their defaults, so that older
    # checkpoints still resume.
    LATER_OPTIONS = ("weight_decay", "mixup")

    def identity_json(self) -> str:
        defaults = {f.name: f.default for f in dataclasses.fields(self)}
        d = {k: v for k, v in dataclasses.asdict(self).items() if k not in self.RESUMABLE_CHANGES
             and not (k in self.LATER_OPTIONS and v == defaults[k])}
        return json.dumps(d, sort_keys=True)


def parse_options(latent_dim, advanced: dict):
    """Split ``fit``'s ``**advanced`` into :class:`TrainOptions` and a
    :class:`~brdfkit.hypernet.network.HyperConfig` of ``latent_dim``, every value checked.

    Raises
    ------
    InputError
        An unknown key, a value of the wrong type or out of its range.
    """
    from brdfkit.hypernet.network import HyperConfig

    opt_fields = {f.name: f for f in dataclasses.fields(TrainOptions)}
    cfg_fields = {f.name: f for f in dataclasses.fields(HyperConfig)}
    opt_kw, cfg_kw = {}, {"latent_dim": latent_dim}
    for key, value in advanced.items():
        if key in opt_fields:
            opt_kw[key] = value
        elif key in cfg_fields and key != "latent_dim":
            cfg_kw[key] = tuple(value) if key == "encoder_hidden" else value
        else:
            known = sorted(set(opt_fields) | set(cfg_fields) - {"latent_dim"})
            raise InputError(f"unknown training option {key!r}; known: {', '.join(known)}")
    for key, value in list(opt_kw.items()):
        want = type(opt_fields[key].default)
        if want is float and isinstance(value, int) and not isinstance(value, bool):
            value = float(value)
        if not isinstance(value, want) or isinstance(value, bool):
            raise InputError(f"training option {key}: {value!r} is not a {want.__name__}")
        opt_kw[key] = value
    opts = TrainOptions(**opt_kw)
    for key in ("batch_materials", "query_size", "context_min", "max_bad_steps"):
        if getattr(opts, key) < 1:
            raise InputError(f"training option {key} must be at least 1, got {getattr(opts, key)}")
    if opts.context_max < opts.context_min:
        raise InputError(f"training option context_max ({opts.context_max}) is below context_min "
                         f"({opts.context_min})")
    if opts.lr_schedule not in ("constant", "cosine"):
        raise InputError(f"training option lr_schedule: {opts.lr_schedule!r}; use 'constant' or 'cosine'")
    for key in ("lr", "grad_clip", "checkpoint_minutes"):
        v = getattr(opts, key)
        if not (v > 0 and math.isfinite(v)):
            raise InputError(f"training option {key} must be a positive number, got {v}")
    if not (opts.weight_decay >= 0 and math.isfinite(opts.weight_decay)):
        raise InputError(f"training option weight_decay must be a number >= 0, got {opts.weight_decay}")
    if not all(0.0 <= v <= 1.0 for v in (opts.angle_fraction, opts.lr_final, opts.mixup)):
        raise InputError("training options angle_fraction, lr_final and mixup must lie in [0, 1]")
    if opts.warmup_steps < 0:
        raise InputError(f"training option warmup_steps must be >= 0, got {opts.warmup_steps}")
    if not isinstance(latent_dim, int) or latent_dim < 1:
        raise InputError(f"latent dimension must be a positive integer, got {latent_dim!r}")
    try:
        cfg = HyperConfig(**cfg_kw)
        cfg.to_json()
    except (TypeError, ValueError) as e:
        raise InputError(f"bad model configuration: {e}") from None
    for key in ("hypo_hidden", "hypo_layers", "decoder_hidden", "decoder_layers"):
        v = getattr(cfg, key)
        if not isinstance(v, int) or v < 1:
            raise InputError(f"model option {key} must be a positive integer, got {v!r}")
    return opts, cfg


def lr_factor(step: int, fraction: float, opts: TrainOptions) -> float:
    """Learning-rate multiplier at ``step`` (0-based), ``fraction`` of the run done
    (0 ... 1): a linear warm-up over ``opts.warmup_steps``, times the cosine decay to
    ``opts.lr_final`` or a constant 1 (``opts.lr_schedule``)."""
    warm = min(1.0, (step + 1) / opts.warmup_steps) if opts.warmup_steps else 1.0
    if opts.lr_schedule == "cosine":
        t = min(max(fraction, 0.0), 1.0)
        return warm * (opts.lr_final + (1 - opts.lr_final) * 0.5 * (1 + math.cos(math.pi * t)))
    return warm
