"""The ``hypernet`` embedding kind: a hypernetwork's latent (Gokbudak et al. 2024),
refined on renders (:mod:`brdfkit.hypernet`). Called ``latent`` before; files and
``--kind`` of that name still read."""

from __future__ import annotations

from brdfkit.embeddings.kind import EmbeddingKind, Offer

__all__ = ["KIND"]


def _encode(net, digest, table, *, source, size, steps, refine, max_seconds=None):
    from brdfkit.hypernet.encoding import encode_table

    if not refine:
        return encode_table(net, table, source)
    from brdfkit.hypernet.refine_on_screen import DEFAULT_STEPS, compress_table
    from brdfkit.render.objective import ObjectiveConfig

    cfg = ObjectiveConfig(steps=DEFAULT_STEPS if steps is None else steps, max_seconds=max_seconds)
    return compress_table(net, table, cfg, source).embedding


def _offer(path) -> Offer:
    from brdfkit.hypernet.network_file import read_latent_dim

    latent = read_latent_dim(path)
    return Offer((latent,), latent)


def _open(net, digest, emb, name, device):
    from brdfkit.hypernet.neural_brdf import NeuralBRDF

    return NeuralBRDF.from_embedding(net, emb, name)


KIND = EmbeddingKind("hypernet", "a hypernetwork's latent, refined on renders (Gokbudak et al. 2024)", "network",
                     lambda n: (int(n.cfg.latent_dim),), lambda n: int(n.cfg.latent_dim), _encode, _open,
                     aliases=("latent",), start="encoder pass", torch=True, wall_clock=True, offer=_offer)
