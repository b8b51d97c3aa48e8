"""The hypernetwork of Gokbudak et al. 2024 as a reconstruction method: encode the
samples with the set encoder, decode the hyponet on the whole grid
(:func:`brdfkit.api.sparse`); its model file comes from :func:`brdfkit.training.fit`."""

from __future__ import annotations

import os

from .. import api
from .method import Method

__all__ = ["METHOD"]


def _load(path, device):
    return api.load_model(path, device=device)


def _reconstruct(samples, model, options, *, seed, device):
    return api.sparse(model, samples)


def _fit(data, output, *, exclude=(), progress=True, **options):
    from ..training import fit

    return fit(data, output, exclude=exclude, progress=progress, **options)


def _compress(model, table, name):
    return api.decode(model, api.encode(model, table, source=name))


def _describe(model, path):
    stem = os.path.splitext(os.path.basename(os.fspath(path)))[0]
    return (f"hypernet {model.cfg.latent_dim}-D ({stem})", model.cfg.latent_dim,
            set(model.meta.get("materials") or ()))


METHOD = Method("hypernet", "hypernetwork: encode the samples, decode the neural BRDF (Gokbudak et al. 2024)",
                "hypernetwork model (.safetensors from `brdfkit fit` or `brdfkit demo`)", load_model=_load, reconstruct_fn=_reconstruct,
                fit_fn=_fit, fit_options=None, compress_fn=_compress, describe_fn=_describe,
                bench_option="model")
