"""The learnt prior as a reconstruction method: a PCA basis fitted in closed form around
the prior mean a set encoder reads from the samples. ``brdfkit sparse``'s default with
the built-in models (``docs/notes/generalisation.md`` says why it is not the paper's decoder).

This module registers the method (:data:`METHOD`); the learnt prior itself lives in
:mod:`brdfkit.prior`:

- ``brdfkit.prior.model``: the network and the closed-form fit
  (:class:`~brdfkit.prior.model.PriorModel`, :func:`~brdfkit.prior.model.solve`);
- :mod:`brdfkit.prior.fit`: its training, ``brdfkit fit --method prior``;
- :mod:`brdfkit.prior.training_data`: what the training fits on (the basis, the cells,
  the held-out fold bases, the tensors on the device);
- :mod:`brdfkit.prior.prior_file`: its file (format ``brdfkit-prior``), which holds or
  names the PCA basis (:mod:`brdfkit.basis`).

May import: what :mod:`brdfkit.methods` may.
"""

from __future__ import annotations

import dataclasses
import os

from brdfkit.methods.method import Method, MethodOptions

__all__ = ["METHOD", "PriorOptions"]


@dataclasses.dataclass(frozen=True)
class PriorOptions(MethodOptions):
    """``use_prior``: solve around the network's prior mean (``False``: the plain basis
    fit, the network unused; for comparison)."""

    use_prior: bool = True


def _load(path, device):
    from brdfkit.models.builtin import load_part

    return load_part(path, "prior", device)


def _reconstruct(samples, model, options, *, seed, device):
    return model.reconstruct(samples, use_prior=options.use_prior), None


def _compress(model, table, name):
    return model.basis.decode(model.basis.project(table))


def _describe(model, path):
    stem = os.path.splitext(os.path.basename(os.fspath(path)))[0]
    k = model.basis.n_components
    return f"basis-{k} ({3 * k} numbers, {stem})", 3 * k, set(model.meta.get("materials") or ())


METHOD = Method("prior", "PCA basis fitted around a learnt prior: a set encoder of the samples gives the "
                "coefficients' prior mean (brdfkit's default, docs/notes/generalisation.md)",
                "learnt-prior model (.safetensors from `brdfkit fit --method prior`, or a built-in name)",
                options=PriorOptions, part="prior", load_fn=_load, reconstruct_fn=_reconstruct,
                compress_fn=_compress, describe_fn=_describe)  # bench: --model-file prior=FILE
