"""The hypernetwork of Gokbudak et al. 2024 as a reconstruction method: encode the
samples with the set encoder (:func:`brdfkit.hypernet.encoding.encode_samples`),
optionally refine the result on the samples (:mod:`brdfkit.hypernet.refine_on_samples`),
decode the hyponet on the whole grid; its network file comes from
:func:`brdfkit.hypernet.training.loop.fit`. The samples go straight to the encoder, not
through :func:`brdfkit.api.encode`, which takes paths, tables and sample sets alike."""

from __future__ import annotations

import dataclasses

from brdfkit.errors import InputError
from brdfkit.methods.method import Method, MethodOptions

__all__ = ["METHOD", "HypernetOptions", "DEFAULT_REFINE_STEPS"]

DEFAULT_REFINE_STEPS = 300
"""Most Adam steps of each stage of the hypernet method's refinement
(:attr:`brdfkit.hypernet.refine_on_samples.RefineConfig.max_steps`, whose default it is)."""


def _load(path, device):
    from brdfkit.models.builtin import load_part

    return load_part(path, "network", device)


@dataclasses.dataclass(frozen=True)
class HypernetOptions(MethodOptions):
    """``refine``: fit the encoded material to its own samples, early-stopped on held-out
    ones (:func:`brdfkit.hypernet.refine_on_samples.refine`; off: the paper's one encoder pass);
    ``refine_target``: ``latent`` or ``weights`` (the latent, then the hyponet's weights);
    ``steps``: most Adam steps of each stage of the refinement (a budget in steps, not
    seconds: the same samples give the same table on any machine).
    On the validation split refining beat the encoder alone at every N, and ``weights``
    beat ``latent`` at N = 40 and 4000 and tied it at 400 (``docs/notes/generalisation.md``,
    Lever 4)."""

    refine: bool = True
    refine_target: str = "weights"
    steps: int = DEFAULT_REFINE_STEPS

    def __post_init__(self):
        if not isinstance(self.refine, bool):
            raise InputError(f"hypernet option refine must be true or false, got {self.refine!r}")
        if self.refine_target not in ("latent", "weights"):
            raise InputError(f"hypernet option refine_target must be 'latent' or 'weights', "
                             f"got {self.refine_target!r}")
        if isinstance(self.steps, bool) or not isinstance(self.steps, int) or self.steps < 1:
            raise InputError(f"hypernet option steps must be a whole number >= 1, got {self.steps!r}")

    def quick(self) -> "HypernetOptions":
        return dataclasses.replace(self, steps=min(10, self.steps))


def _reconstruct(samples, model, options, *, seed, device):
    from brdfkit.hypernet.encoding import encode_samples
    from brdfkit.hypernet.neural_brdf import NeuralBRDF

    emb = encode_samples(model, samples)
    if not options.refine:
        return NeuralBRDF.from_embedding(model, emb).to_table(), emb
    from brdfkit.hypernet.refine_on_samples import RefineConfig, refine

    config = RefineConfig(target=options.refine_target, max_steps=options.steps)
    result = refine(model, samples, emb, config=config, seed=seed)
    # The weights stage changes the hyponet, which no latent decodes to: no embedding then.
    return result.brdf.to_table(), result.embedding if options.refine_target == "latent" else None


METHOD = Method("hypernet", "hypernetwork: encode the samples, decode the neural BRDF (Gokbudak et al. 2024)",
                "hypernetwork model (.safetensors from `brdfkit fit` or `brdfkit demo`)", options=HypernetOptions,
                part="network", load_fn=_load, reconstruct_fn=_reconstruct, embedding_kind="hypernet",
                bench_option="model")
