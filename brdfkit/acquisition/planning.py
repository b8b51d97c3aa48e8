"""Where to measure: N measurement directions chosen for a reconstruction.

A lab that can afford N measurements of a material picks N direction pairs, measures
there, and reconstructs the dense table from them (``docs/planning.md``). Which
directions is a *design*; the designs are listed by name in
:data:`brdfkit.acquisition.designs.DESIGNS` (``nielsen``, ``render``, ``uniform``), in the
style of :data:`brdfkit.methods.METHODS`.

A design is chosen for a *fit*: the PCA basis, and the precision the fit gives a sample
(:class:`~brdfkit.acquisition.optimal_design.Likelihood`), which a learnt-prior model's config holds
and a plain basis (IPCA's ridge fit) does not need. The ``render`` design uses both; the
``nielsen`` design the basis alone.

The designs themselves, and the Nielsen et al. design in detail, are
:mod:`brdfkit.acquisition.designs`'.
"""

from __future__ import annotations

import dataclasses
import os

import numpy as np

from brdfkit.acquisition.designs import DESIGNS, CandidatePool
from brdfkit.acquisition.rounds import posterior_after
from brdfkit.errors import InputError
from brdfkit.geometry import GRID_SHAPE, cell_angles
from brdfkit.geometry.trilinear import lookup_trilinear
from brdfkit.io.directions import DirectionSet

__all__ = ["Plan", "PlanTarget", "DEFAULT_DESIGN", "plan_directions", "plan_basis", "plan_target", "design_rows",
           "condition_number"]

DEFAULT_DESIGN = "render"
"""The design `brdfkit plan` and planned samples use unless told: chosen by renders (docs/planning.md)."""


@dataclasses.dataclass
class Plan:
    """N measurement directions and how they were chosen.

    Attributes
    ----------
    directions
        :class:`~brdfkit.io.directions.DirectionSet`, each pair at its cell's own angles.
    cells
        int64 ``(N,)``, their flat MERL cell indices.
    design, seed
        The design's name (:data:`DESIGNS`) and the seed it ran with.
    basis
        The PCA basis the design used or was scored with, as named (``None``: none).
    components
        ``K``, the basis's number of components (``None`` without a basis).
    condition_number
        Of the basis rows at the directions (:func:`condition_number`), with ``given``
        those of the samples it was given too (the rows the fit will have); ``None``
        without a basis.
    given
        The :class:`~brdfkit.acquisition.rounds.Posterior` after the samples the plan was
        made given (``None``: none).
    expected_error
        With ``given``: the design's expected screen error after the given samples, and
        after these directions too (:func:`brdfkit.acquisition.rounds.expected_error`).
    """

    directions: DirectionSet
    cells: np.ndarray
    design: str
    seed: int
    basis: str | None = None
    components: int | None = None
    condition_number: float | None = None
    given: object = None
    expected_error: tuple | None = None

    def __len__(self) -> int:
        return len(self.directions)

    def describe(self) -> str:
        """One line: the design, N, the seed, the samples it was planned given, the basis,
        the condition number and the expected error the plan leaves."""
        text = f"design {self.design}, N = {len(self)}, seed {self.seed}"
        if self.given is not None:
            g = self.given
            text += f", given {g.count} samples" + (f" of {g.source}" if g.source else "")
            text += f" ({g.used} on the basis)" if g.used < g.count else ""
        if self.basis is not None:
            text += (f"; basis of {self.basis}: {self.components} components, condition number "
                     f"{self.condition_number:.4g}" + (" with the given samples" if self.given is not None else ""))
        if self.expected_error is not None:
            text += "; expected screen error {:.4g} -> {:.4g}".format(*self.expected_error)
        return text


class PlanTarget(tuple):
    """What :func:`plan_target` returns: the tuple ``(basis, label, likelihood)``, and
    the learnt prior as ``prior`` (:class:`~brdfkit.prior.model.PriorModel`; ``None`` for
    a plain basis), whose fit reads the prior from the samples of a plan ``--given``."""

    def __new__(cls, basis, label, likelihood, prior=None):
        target = super().__new__(cls, (basis, label, likelihood))
        target.prior = prior
        return target


def plan_basis(spec: str | os.PathLike | None = None):
    """The PCA basis a ``-m`` value names for planning, and its label: the first two of
    :func:`plan_target`."""
    basis, label, _ = plan_target(spec)
    return basis, label


def plan_target(spec=None):
    """The fit a ``-m`` value names for planning: its PCA basis, a label and the
    precision the fit gives a sample.

    Parameters
    ----------
    spec
        A built-in model's name (its learnt prior: the basis and the prior's likelihood),
        a learnt-prior file (likewise), a PCA basis file (``brdfkit fit --method basis``;
        IPCA's ridge fit), an :class:`~brdfkit.basis.PcaBasis` or
        :class:`~brdfkit.prior.model.PriorModel`, or ``None`` (the default
        built-in's learnt prior).

    Returns
    -------
    PlanTarget
        ``(PcaBasis, label, Likelihood)``
        (:class:`~brdfkit.acquisition.optimal_design.Likelihood`), and the learnt prior
        (``prior``) when the fit is one.

    Raises
    ------
    InputError
        An unknown name, a built-in or file without a basis (a hypernetwork), no default
        built-in installed.
    """
    from brdfkit.atomic import check_input_file
    from brdfkit.basis import DEFAULT_LAMBDA, PcaBasis, load_basis
    from brdfkit.models.parts import file_part, part_of
    from brdfkit.methods.choice import resolve_for
    from brdfkit.models.builtin import default_bundle, is_path_spec
    from brdfkit.acquisition.optimal_design import Likelihood

    def prior(path, label):
        from brdfkit.methods import get_method

        return of_prior(get_method("prior").load(path, "cpu"), label)

    def of_prior(model, label):
        return PlanTarget(model.basis, label, Likelihood(model.cfg.weight, model.cfg.s2, model.cfg.lam), model)

    ridge = Likelihood(None, lam=DEFAULT_LAMBDA)
    if isinstance(spec, tuple) and len(spec) == 3 and isinstance(spec[0], PcaBasis):
        return spec if isinstance(spec, PlanTarget) else PlanTarget(*spec)  # loaded once, planned for many times
    if isinstance(spec, PcaBasis):
        return PlanTarget(spec, "the given basis", ridge)
    if not isinstance(spec, (str, os.PathLike)) and spec is not None:
        found = part_of(spec)
        if found is None or found.name != "prior":
            raise InputError(f"planning needs a PCA basis or a learnt prior, not a "
                             f"{found.label if found else type(spec).__name__}")
        return of_prior(spec, "the given learnt prior")
    if spec is None:
        entry = default_bundle()
        if entry is None:
            raise InputError("no PCA basis given: pass -m NAME (a built-in model with a learnt prior, "
                             "`brdfkit models`) or -m BASIS.safetensors (`brdfkit fit --method basis`); "
                             "no default built-in model is installed")
        return prior(resolve_for("prior", entry.name), f"{entry.name}, the default built-in")
    spec = os.fspath(spec)
    if not is_path_spec(spec):
        return prior(resolve_for("prior", spec), spec)
    check_input_file(spec)
    part = file_part(spec).name
    if part == "basis":
        return PlanTarget(load_basis(spec), os.path.basename(spec), ridge)
    if part == "prior":
        return prior(spec, os.path.basename(spec))
    raise InputError(f"{spec}: not a PCA basis or a learnt-prior model file; planning needs a basis: a built-in "
                     f"name with a learnt prior, a learnt-prior file or a file from `brdfkit fit --method basis`")


def design_rows(basis, directions: DirectionSet) -> np.ndarray:
    """The rows of the basis's design matrix at the directions the fit uses.

    The components times ``sigma`` (the scaled columns of the ridge fit,
    :meth:`PcaBasis.coefficients <brdfkit.basis.PcaBasis.coefficients>`),
    interpolated trilinearly as the fit interpolates them; directions the fit leaves
    out (no basis cell around them, or on the horizon: zero cosine weight) are left out.

    Returns
    -------
    numpy.ndarray
        float64 ``(M, K)``, ``M <= N``.
    """
    from brdfkit.basis import cosine_weight

    at = lookup_trilinear(basis.lookup_table().reshape(GRID_SHAPE + (-1,)), directions.theta_h, directions.theta_d,
                          directions.phi_d)[:, 2:].astype(np.float64)
    used = np.isfinite(at).all(axis=1) & (cosine_weight(directions.theta_h, directions.theta_d,
                                                        directions.phi_d) > 0)
    return at[used] * basis.sigma.astype(np.float64)[None, :]


def condition_number(rows: np.ndarray) -> float:
    """``sigma_1 / sigma_r`` of an ``(M, K)`` matrix, ``r = min(M, K)``: its largest
    singular value over its smallest of the ``r`` that rows in general position have
    (for ``M < K`` the non-zero ones); ``inf`` when that one is zero (dependent rows)
    or there are no rows."""
    rows = np.asarray(rows, np.float64)
    if rows.size == 0:
        return float("inf")
    s = np.linalg.svd(rows, compute_uv=False)
    low = s[min(rows.shape) - 1]
    return float(s[0] / low) if low > 1e-12 * s[0] else float("inf")


def plan_directions(model=None, n: int = 40, *, design: str = DEFAULT_DESIGN, seed: int = 0, within=None,
                    given=None, **options) -> Plan:
    """Choose ``n`` measurement directions with a design.

    Parameters
    ----------
    model
        The fit to plan for, as :func:`plan_target` takes it (a built-in name, a basis or
        learnt-prior file, an :class:`~brdfkit.basis.PcaBasis` or a learnt-prior
        model, or what :func:`plan_target` returned); ``None``: the
        default built-in's for a design that needs one, none for ``uniform`` (whose plan
        then has no condition number).
    n
        Number of directions, ``>= 1``.
    design
        A name of :data:`DESIGNS`.
    seed
        Seeds everything random in the design.
    within
        A :class:`~brdfkit.io.samples.SampleSet` (an instrument's measurements, or the
        configurations it can reach): the directions are chosen among its own, in
        distinct cells (the design runs on the cells they fall in; ``uniform`` draws
        them at random), and returned at the samples' own angles.
    given
        A :class:`~brdfkit.io.samples.SampleSet`, the samples of this material measured
        so far: the next ``n`` directions are chosen for it, from the fit's posterior
        after them and at its estimate (:mod:`brdfkit.acquisition.rounds`), never in a
        cell one of them falls in; a design that plans given samples only
        (``render``).
    options
        The design's options (``nielsen``: ``evaluations``, :data:`~brdfkit.acquisition.designs.DEFAULT_EVALUATIONS`;
        ``refine``, ``True``; ``render``: ``draws``,
        :data:`~brdfkit.acquisition.optimal_design.DEFAULT_DRAWS`; ``candidates``,
        :data:`~brdfkit.acquisition.designs.DEFAULT_CANDIDATES`).

    Returns
    -------
    Plan
        Directions at the cells' own angles (``phi_h = 0``), their cells, and the
        condition number of the basis rows there (with a basis); with ``given``, the
        posterior and the expected error before and after the plan.

    Raises
    ------
    InputError
        An unknown design or option, ``n < 1``, more directions than candidate cells, a
        model that is no basis, ``given`` with a design that does not take it, given
        samples the fit cannot use.

    Examples
    --------
    >>> plan = plan_directions(n=20, design="uniform", seed=0)  # no basis needed
    >>> len(plan), plan.design, plan.condition_number is None
    (20, 'uniform', True)
    >>> bool((plan_directions(n=20, design="uniform", seed=0).cells == plan.cells).all())
    True

    The next round for a material, given what it measured in the first:

    >>> from brdfkit.acquisition.sampling import measure_samples
    >>> from brdfkit.testing.examples import lambertian_table, tiny_basis
    >>> basis = tiny_basis(4)
    >>> first = plan_directions(basis, 4, draws=1, candidates=2000)
    >>> so_far = measure_samples(lambertian_table(), first.directions, source="round1.csv")
    >>> second = plan_directions(basis, 4, given=so_far, draws=1, candidates=2000)
    >>> second.describe().split(";")[0]
    'design render, N = 4, seed 0, given 4 samples of round1.csv'
    >>> bool(np.isin(second.cells, first.cells).any())  # never a cell measured before
    False
    >>> bool(second.expected_error[1] < second.expected_error[0])  # the design's expected error, before and after
    True
    """
    if design not in DESIGNS:
        raise InputError(f"unknown design {design!r}; known: {', '.join(DESIGNS)}")
    d = DESIGNS[design]
    unknown = sorted(set(options) - set(d.options))
    if unknown:
        takes = f"the option(s) {', '.join(d.options)}" if d.options else "no options"
        raise InputError(f"design {design!r} takes {takes}, got {', '.join(unknown)}")
    n = int(n)
    if n < 1:
        raise InputError(f"number of directions must be at least 1, got {n}")
    if given is not None and not d.takes_given:
        raise InputError(f"design {design!r} does not plan given samples; the design(s) that do: "
                         f"{', '.join(k for k, v in DESIGNS.items() if v.takes_given)}")
    target = (None, None, None) if model is None and not d.needs_basis else plan_target(model)
    basis, label, likelihood = target
    pool = CandidatePool.of(basis, likelihood) if basis is not None and d.needs_basis else None
    post = None if given is None else posterior_after(target, given)
    if post is not None:
        pool = pool.restricted(~np.isin(pool.cells, post.cells))  # never measure a cell twice
        options = {**options, "given": post}
    cells, (th, td, pd), expected = _choose(d, pool, n, seed, options, within, post is not None)
    directions = DirectionSet(th, td, pd, f"plan {design} N={n} seed={seed}")
    rows = None if basis is None else design_rows(basis, directions)
    cond = None if basis is None else condition_number(rows if post is None else np.vstack([post.rows, rows]))
    return Plan(directions, cells, design, int(seed), label, None if basis is None else basis.n_components, cond,
                post, expected)


def _choose(design, pool, n, seed, options, within, given: bool):
    """The chosen cells, their angles and the expected errors (with ``given``, else
    ``None``): the design run on the pool, or among ``within``'s directions."""
    if within is not None:
        return _choose_within(within, design, pool, n, seed, options, given)
    out = design.choose(pool, n, seed, **options)
    cells, expected = out if given else (out, None)
    cells = np.asarray(cells, np.int64)
    return cells, cell_angles(cells), expected


def _choose_within(samples, design, pool, n, seed, options, given: bool):
    """Cells, the samples' own angles and the expected errors (with ``given``, else
    ``None``) of ``n`` of ``samples``' directions, one per cell, chosen by ``design``
    among the cells they fall in (``pool`` restricted to them; a design without a basis:
    at random by ``seed``)."""
    from brdfkit.geometry import cell_index

    own = cell_index(samples.theta_h, samples.theta_d, samples.phi_d)
    cells, first = np.unique(own, return_index=True)
    expected = None
    if pool is not None:
        keep = np.isin(pool.cells, cells)
        yet = " and not measured yet" if given else ""
        if not keep.any():
            raise InputError(f"{samples.source}: none of its directions is in a cell the PCA basis covers{yet}")
        pool = pool.restricted(keep)
        if n > pool.cells.size:
            raise InputError(f"{n} directions asked for, but {samples.source} has directions in only "
                             f"{pool.cells.size} cells the basis covers{yet}")
        chosen = design.choose(pool, n, seed, **options)
        chosen, expected = chosen if given else (chosen, None)
        chosen = np.asarray(chosen, np.int64)
    else:
        if n > cells.size:
            raise InputError(f"{n} directions asked for, but {samples.source} has directions in only "
                             f"{cells.size} cells")
        chosen = np.sort(np.random.default_rng(seed).choice(cells, size=n, replace=False))
    idx = first[np.searchsorted(cells, chosen)]
    return chosen, (samples.theta_h[idx], samples.theta_d[idx], samples.phi_d[idx]), expected
