"""The PCA baseline of Nielsen, Jensen and Ramamoorthi 2015, "On Optimal, Minimal BRDF
Sampling for Reflectance Acquisition" (SIGGRAPH Asia), as compared against in Gokbudak et
al. 2024, registered as a reconstruction method: the basis of :mod:`brdfkit.basis`
fitted to sparse samples by regularised least squares
(:meth:`brdfkit.basis.model.PcaBasis.coefficients`).

Its model is a basis file (``brdfkit fit --method basis``, :func:`brdfkit.basis.fit.fit_basis_files`),
or a built-in's name: the built-ins ship the basis their learnt prior is fitted with, of
which the baseline takes Nielsen et al.'s 8 leading components. Without ``-m`` it takes
the default built-in's.

May import: what :mod:`brdfkit.methods` may.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from brdfkit.basis.model import DEFAULT_LAMBDA
from brdfkit.errors import InputError
from brdfkit.methods.method import Method, MethodOptions

__all__ = ["IpcaOptions", "METHOD"]


@dataclasses.dataclass(frozen=True)
class IpcaOptions(MethodOptions):
    """``lam``: the ridge weight of :meth:`brdfkit.basis.model.PcaBasis.coefficients`."""

    lam: float = DEFAULT_LAMBDA

    def __post_init__(self):
        if not (isinstance(self.lam, (int, float)) and self.lam >= 0 and np.isfinite(self.lam)):
            raise InputError(f"ipca option lam (ridge lambda) must be a finite number >= 0, got {self.lam!r}")


def _load(path, device):
    from brdfkit.models.parts import get_part
    from brdfkit.models.builtin import is_builtin_part, resolve_basis

    path = resolve_basis(path)
    basis, _ = get_part("basis").load(path, device)
    # A built-in's basis has the components its learnt prior fits; the baseline is
    # Nielsen's 8 of them. A file of the user's is used whole.
    return basis.baseline() if is_builtin_part(path, "basis") else basis


def _reconstruct(samples, model, options, *, seed, device):
    # Nielsen et al.'s inverse as published (clamped at 0): the baseline keeps its dark band.
    return model.reconstruct(samples, lam=options.lam, floor=0.0), None


def _compress(model, table, name):
    return model.decode(model.project(table), floor=0.0)


def _describe(model, path):
    import os

    k, stem = model.n_components, os.path.splitext(os.path.basename(os.fspath(path)))[0]
    return f"basis-{k} ({3 * k} numbers, {stem})", 3 * k, set(model.materials)


METHOD = Method("ipca", "PCA basis of log-mapped tables fitted by ridge regression (Nielsen et al. 2015)",
                "PCA basis (.safetensors from `brdfkit fit --method basis`, or a built-in's name)",
                options=IpcaOptions, part="basis", load_fn=_load, reconstruct_fn=_reconstruct, compress_fn=_compress,
                describe_fn=_describe, bench_option="ipca")
