"""Sparse-reconstruction methods by name: the hypernetwork and the baselines it is
compared against (Gokbudak et al. 2024, Sec. 4), in the style of colour-science's
``DELTA_E_METHODS`` and ``delta_E(..., method=)``.

============ ============================================================== ===============
name         method                                                         ``-m`` model
============ ============================================================== ===============
``hypernet`` the hypernetwork: encode the samples, decode the hyponet       network file
             (:mod:`.hypernet`, :func:`brdfkit.api.sparse`)
``ipca``     PCA basis of log-mapped tables, ridge fit to the samples       PCA basis file
             (Nielsen, Jensen and Ramamoorthi 2015; :mod:`.ipca`)
``nbrdf``    one 6-21-21-3 MLP fitted to the samples alone                  none
             (Sztrajman et al. 2021; :mod:`.nbrdf`)
``prior``    the basis fitted around a learnt prior: a set encoder of the   learnt-prior
             samples predicts the coefficients' prior mean (:mod:`.prior`;  file
             :mod:`brdfkit.prior`); ``--method auto``'s with a built-in
============ ============================================================== ===============

(``residual``, the learnt prior's fit through a correction trained on such fits, left on
2026-12-01: it served no built-in and gained at most 0.23 dB over ``prior`` on the
validation split, ``docs/notes/generalisation.md``, "What left the product".)

Every method has the same interface (:class:`~.method.Method`), so ``brdfkit sparse``,
``brdfkit validate`` and the benchmark loop over them alike (what ``brdfkit fit`` trains
is :data:`brdfkit.training.FITTERS`)::

    method = get_method("ipca")
    model = method.load("basis.safetensors")          # None for methods without a model
    table = method.reconstruct(samples, model, seed=0, device=None, lam=0.1)

or in one call, ``reconstruct(samples, method="ipca", model="basis.safetensors")``.

``reconstruct`` takes a :class:`brdfkit.io.samples.SampleSet` (BRDF in 1/sr) and returns a
dense float64 ``(90, 90, 180, 3)`` table in 1/sr, ``>= 0``, NaN on the cells it does not
cover. ``model`` is what :meth:`~.method.Method.load` returned, or a path (loaded on the
spot); it is required when ``needs_model`` and must be ``None`` otherwise. ``seed``
drives any randomness (NBRDF's initial weights); ``device`` picks the torch device
(default CUDA when available). The options are the fields of the method's options
dataclass (``lam`` for ``ipca``; ``steps``, ``lr``, ``patience`` for ``nbrdf``).

A new method is one module defining ``METHOD = Method(...)`` and one line in
:data:`METHODS` (see DEVELOPERS.md). Importing this package imports no torch.

What a model serves, kinds and sizes and methods, is :mod:`.service` (:func:`~.service.serves`),
which the choice of a ``-m`` value (:mod:`.choice`) and ``encode``'s decoder
(:func:`brdfkit.embeddings.choose_decoder`) ask.

May import: the ground floor, :mod:`brdfkit.geometry`, :mod:`brdfkit.io`,
:mod:`brdfkit.models`, :mod:`brdfkit.hypernet` (the ``hypernet`` method), and, in
:mod:`.service` alone, :mod:`brdfkit.embeddings`' registry (the same layer).
"""

from __future__ import annotations

from brdfkit.errors import InputError
from brdfkit.methods import hypernet, ipca, nbrdf, prior
from brdfkit.methods.method import Method, MethodOptions

__all__ = ["Method", "MethodOptions", "METHODS", "get_method", "reconstruct"]

METHODS: dict[str, Method] = {
    "hypernet": hypernet.METHOD,
    "ipca": ipca.METHOD,
    "nbrdf": nbrdf.METHOD,
    "prior": prior.METHOD,
}
"""The reconstruction methods by name."""


def get_method(name: str) -> Method:
    """The method called ``name``; :class:`InputError` listing the known ones otherwise."""
    try:
        return METHODS[name]
    except (KeyError, TypeError):
        raise InputError(f"unknown method {name!r}; known: {', '.join(METHODS)}") from None


def reconstruct(samples, method: str = "hypernet", model=None, **kwargs):
    """Dense ``(90, 90, 180, 3)`` table (1/sr) from a sample set with the method called
    ``method``; ``kwargs`` as :meth:`Method.reconstruct` takes them."""
    return get_method(method).reconstruct(samples, model, **kwargs)
