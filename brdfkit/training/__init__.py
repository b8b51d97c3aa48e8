"""What ``brdfkit fit`` trains, by name (:data:`FITTERS`): each part of a model has one
recipe that makes its file from MERL tables.

============== =================================================== ==========================
name           what it trains                                      its file (``Fitter.part``)
============== =================================================== ==========================
``hypernet``   the hypernetwork (Gokbudak et al. 2024;              ``network``
               :mod:`brdfkit.hypernet.training`)
``basis``      a PCA basis of log-mapped tables (Nielsen et al.     ``basis``
               2015; :mod:`brdfkit.basis.fit`); ``ipca`` before
``prior``      the learnt prior of a basis (:mod:`brdfkit.prior`)   ``prior``
``residual``   the hypernetwork residual of a basis                 ``residual``
               (:mod:`brdfkit.residual.training`)
============== =================================================== ==========================

(``correction``, a residual trained on a learnt prior's sparse fits, left on 2026-12-01
with ``brdfkit sparse --method residual``, the one route that read its file:
``docs/notes/generalisation.md``, "What left the product".)

Each recipe names the part of a model its file is, in the part registry
:data:`brdfkit.models.parts.PARTS` (which says how the file loads and what digest
names it).

``ipca`` remains the name of Nielsen et al.'s *reconstruction method*
(``brdfkit sparse --method ipca``), which fits a basis to samples; ``brdfkit fit
--method ipca`` still trains a basis, with a note.

May import: every package of a model part; nothing imports it but the front
(:mod:`brdfkit.api`, ``brdfkit.cli``).
"""

from __future__ import annotations

import dataclasses
from typing import Callable

from brdfkit.errors import InputError

__all__ = ["Fitter", "FITTERS", "get_fitter"]


@dataclasses.dataclass(frozen=True)
class Fitter:
    """One recipe of ``brdfkit fit``.

    Attributes
    ----------
    name, summary
        Registry key (``brdfkit fit --method``) and one line for help texts.
    part
        The part of a model its file is (a name of the part registry
        :data:`brdfkit.models.parts.PARTS`): what ``-m`` then takes it as, and what a
        built-in's manifest lists it under.
    fit_fn
        ``fit_fn(data, output, *, exclude, progress, **options) -> output``.
    options
        Names of the options ``fit_fn`` takes, or a function that gives them (read on use,
        so that the registry imports no model code); ``None``: any (the function checks
        them).
    aliases
        Old names still taken, each with a note.
    """

    name: str
    summary: str
    part: str
    fit_fn: Callable = dataclasses.field(repr=False)
    options: tuple | Callable | None = ()
    aliases: tuple = ()

    def fit(self, data, output, *, exclude=(), progress: bool = True, **options) -> str:
        """Train from MERL tables ``data`` (files or folders), ``exclude`` held out;
        returns ``output``."""
        names = self.options() if callable(self.options) else self.options
        if names is not None:
            extra = sorted(set(options) - set(names))
            if extra:
                takes = ", ".join(f"--{o.replace('_', '-')}" for o in names)
                raise InputError(f"--method {self.name} takes only {takes + ' and ' if takes else ''}"
                                 f"--exclude/--exclude-list, not {', '.join(extra)}")
        return self.fit_fn(data, output, exclude=exclude, progress=progress, **options)


def _hypernet(data, output, **kw):
    from brdfkit.hypernet.training.loop import fit

    return fit(data, output, **kw)


def _basis(data, output, **kw):
    from brdfkit.basis.fit import fit_basis_files

    return fit_basis_files(data, output, **kw)


def _prior(data, output, **kw):
    from brdfkit.prior.fit import fit_prior

    return fit_prior(data, output, **kw)


def _prior_options() -> tuple:
    from brdfkit.prior.fit import FIT_OPTIONS

    return FIT_OPTIONS


def _residual(data, output, **kw):
    from brdfkit.residual.training import fit_residual

    return fit_residual(data, output, **kw)


FITTERS: dict[str, Fitter] = {
    "hypernet": Fitter("hypernet", "the hypernetwork (Gokbudak et al. 2024)", "network", _hypernet, None),
    "basis": Fitter("basis", "a PCA basis of log-mapped tables (Nielsen et al. 2015)", "basis", _basis,
                    ("components", "half", "phi_stride", "w_floor", "int8", "deflate", "eps_share"),
                    aliases=("ipca",)),
    "prior": Fitter("prior", "the learnt prior of a basis", "prior", _prior, _prior_options),
    "residual": Fitter("residual", "the hypernetwork residual of a basis", "residual", _residual, None),
}
"""The recipes of ``brdfkit fit`` by name."""


def get_fitter(name: str) -> Fitter:
    """The recipe called ``name`` (or an old name of it); :class:`InputError` otherwise."""
    for f in FITTERS.values():
        if name == f.name or name in f.aliases:
            return f
    raise InputError(f"unknown --method {name!r} for fit; known: {', '.join(FITTERS)}")
