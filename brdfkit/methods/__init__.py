"""Sparse-reconstruction methods by name: the hypernetwork and the baselines it is
compared against (Gokbudak et al. 2024, Sec. 4).

============ =========================================================== ==============
name         method                                                      ``-m`` model
============ =========================================================== ==============
``hypernet`` the hypernetwork: encode the samples, decode the hyponet    model file
             (:func:`brdfkit.api.sparse`)
``ipca``     PCA basis of log-mapped tables, ridge fit to the samples    PCA basis file
             (Nielsen, Jensen and Ramamoorthi 2015; :mod:`.ipca`)
``nbrdf``    one 6-21-21-3 MLP fitted to the samples alone               none
             (Sztrajman et al. 2021; :mod:`.nbrdf`)
============ =========================================================== ==============

Every method has the same interface, so a benchmark loops over them alike::

    method = get_method("ipca")
    model = method.load("basis.safetensors")          # None for methods without a model
    table = method.reconstruct(samples, model, seed=0, device=None)

``reconstruct(samples, model=None, *, seed=0, device=None, **options)`` takes a
:class:`brdfkit.samples.SampleSet` (BRDF in 1/sr) and returns a dense float64
``(90, 90, 180, 3)`` table in 1/sr, ``>= 0``, NaN on the cells it does not cover.
``model`` is what :meth:`Method.load` returned, or a path (loaded on the spot); it is
required when ``needs_model`` and must be ``None`` otherwise. ``seed`` drives any
randomness (NBRDF's initial weights); ``device`` picks the torch device (default CUDA
when available). ``options`` are method-specific: ``lam`` for ``ipca``; ``steps``,
``lr``, ``patience`` for ``nbrdf``.

Importing this package imports neither torch nor the methods' modules.
"""

from __future__ import annotations

import dataclasses
import importlib
import os
from typing import Callable

from ..errors import InputError

__all__ = ["Method", "METHODS", "get_method"]


@dataclasses.dataclass(frozen=True)
class Method:
    """One reconstruction method.

    Attributes
    ----------
    name
        Registry key (``--method`` on the command line).
    summary
        One line for help texts.
    needs_model
        Whether :meth:`reconstruct` needs a model file (``-m``).
    model_kind
        What that file is, for messages ("" when ``needs_model`` is false).
    """

    name: str
    summary: str
    needs_model: bool
    model_kind: str
    _load: Callable | None = dataclasses.field(default=None, repr=False)
    _reconstruct: Callable | None = dataclasses.field(default=None, repr=False)

    def load(self, path: str | os.PathLike | None, device=None):
        """Load the method's model file; ``None`` for methods that need none."""
        if not self.needs_model:
            if path is not None:
                raise InputError(f"method {self.name!r} takes no model file, got {os.fspath(path)}")
            return None
        if path is None:
            raise InputError(f"method {self.name!r} needs a {self.model_kind} (-m FILE)")
        return self._load(os.fspath(path), device)

    def reconstruct(self, samples, model=None, *, seed: int = 0, device=None, **options):
        """Dense ``(90, 90, 180, 3)`` table (1/sr) from a sample set; see the module doc."""
        if model is None or isinstance(model, (str, os.PathLike)):
            model = self.load(model, device)
        return self._reconstruct(samples, model, seed=seed, device=device, **options)


def _hypernet_load(path, device):
    return importlib.import_module("brdfkit.api").load_model(path, device=device)


def _hypernet_reconstruct(samples, model, *, seed, device, **options):
    if options:
        raise InputError(f"method 'hypernet' takes no options, got {', '.join(sorted(options))}")
    table, _ = importlib.import_module("brdfkit.api").sparse(model, samples)
    return table


def _ipca_load(path, device):
    return importlib.import_module("brdfkit.baselines.ipca").load_ipca(path)


def _ipca_reconstruct(samples, model, *, seed, device, lam=None, **options):
    if options:
        raise InputError(f"method 'ipca' takes only the option lam, got {', '.join(sorted(options))}")
    return model.reconstruct(samples, lam=lam)


def _nbrdf_reconstruct(samples, model, *, seed, device, **options):
    allowed = {"steps", "lr", "patience"}
    if set(options) - allowed:
        raise InputError(f"method 'nbrdf' takes the options steps, lr, patience, got "
                         f"{', '.join(sorted(set(options) - allowed))}")
    fit = importlib.import_module("brdfkit.baselines.nbrdf").fit_nbrdf
    return fit(samples, seed=seed, device=device, **options).to_table()


METHODS = {
    "hypernet": Method("hypernet", "hypernetwork: encode the samples, decode the neural BRDF "
                       "(Gokbudak et al. 2024)", True, "hypernetwork model (.safetensors)",
                       _hypernet_load, _hypernet_reconstruct),
    "ipca": Method("ipca", "PCA basis of log-mapped tables fitted by ridge regression "
                   "(Nielsen et al. 2015)", True, "PCA basis (.safetensors from `brdfkit fit --method ipca`)",
                   _ipca_load, _ipca_reconstruct),
    "nbrdf": Method("nbrdf", "one small MLP fitted to the samples alone (Sztrajman et al. 2021)",
                    False, "", None, _nbrdf_reconstruct),
}


def get_method(name: str) -> Method:
    """The method called ``name``; :class:`InputError` listing the known ones otherwise."""
    try:
        return METHODS[name]
    except (KeyError, TypeError):
        raise InputError(f"unknown method {name!r}; known: {', '.join(METHODS)}") from None
