"""The PCA baseline of Nielsen, Jensen and Ramamoorthi 2015, "On Optimal, Minimal BRDF
Sampling for Reflectance Acquisition" (SIGGRAPH Asia), as compared against in Gokbudak et
al. 2024, as a reconstruction method: a linear basis of log-mapped measured BRDFs,
fitted to sparse samples by regularised least squares.

This package registers the method (:data:`METHOD`) and gives its public names; its
parts are

- :mod:`.model`: the basis and its fit to samples (:class:`~.model.IpcaModel`; the
  mapping, the channels and the ridge fit are described there);
- :mod:`.fit`: the basis fitted to training tables, ``brdfkit fit --method ipca``;
- :mod:`.basis_file`: its file (format ``brdfkit-ipca``), on its own or inside a
  learnt-prior model file (:mod:`brdfkit.methods.prior.prior_file`);
- :mod:`.basis_storage`: the compact storage of the bases shipped with the package
  (float16 or int8, every other ``phi_d`` cell);
- :mod:`.refine_on_screen`: a table's coefficients refined on renders of the objective
  scenes;
- :mod:`.embedding`: basis embeddings, the default ``brdfkit encode`` of a built-in
  that ships a basis (issue 29).

May import: what :mod:`brdfkit.methods` may (the objective scenes' screens of
:mod:`brdfkit.hypernet.refine_on_screen` and :mod:`brdfkit.render.screen` included); no
other method.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from brdfkit.errors import InputError
from brdfkit.methods.method import Method, MethodOptions
from brdfkit.methods.ipca.basis_file import IPCA_FORMAT, IPCA_VERSION, basis_tensors, load_ipca, read_ipca, save_ipca, storage_of
from brdfkit.methods.ipca.fit import fit_ipca, fit_ipca_files
from brdfkit.methods.ipca.model import DEFAULT_COMPONENTS, DEFAULT_LAMBDA, EPS, IpcaModel, cosine_weight

__all__ = ["IpcaModel", "IpcaOptions", "fit_ipca", "fit_ipca_files", "load_ipca", "save_ipca", "METHOD",
           "IPCA_FORMAT", "IPCA_VERSION", "read_ipca", "basis_tensors", "EPS", "DEFAULT_LAMBDA",
           "DEFAULT_COMPONENTS", "cosine_weight", "storage_of"]


@dataclasses.dataclass(frozen=True)
class IpcaOptions(MethodOptions):
    """``lam``: the ridge weight of :meth:`IpcaModel.coefficients`."""

    lam: float = DEFAULT_LAMBDA

    def __post_init__(self):
        if not (isinstance(self.lam, (int, float)) and self.lam >= 0 and np.isfinite(self.lam)):
            raise InputError(f"ipca option lam (ridge lambda) must be a finite number >= 0, got {self.lam!r}")


def _load(path, device):
    from brdfkit.models.builtin import is_path_spec, resolve_basis

    basis = load_ipca(resolve_basis(path))
    # A built-in's basis has the components its learnt prior fits; a file is used whole.
    return basis if is_path_spec(path) else basis.baseline()


def _reconstruct(samples, model, options, *, seed, device):
    return model.reconstruct(samples, lam=options.lam), None


def _compress(model, table, name):
    return model.decode(model.project(table))


def _describe(model, path):
    return f"ipca {model.n_components} components", model.n_components, set(model.materials)


METHOD = Method("ipca", "PCA basis of log-mapped tables fitted by ridge regression (Nielsen et al. 2015)",
                "PCA basis (.safetensors from `brdfkit fit --method ipca`)", options=IpcaOptions,
                load_model=_load, reconstruct_fn=_reconstruct, fit_fn=fit_ipca_files,
                fit_options=("components", "half", "phi_stride", "w_floor", "int8"), compress_fn=_compress, describe_fn=_describe,
                bench_option="ipca")

