"""Where to measure: N measurement directions chosen for a reconstruction.

A lab that can afford N measurements of a material picks N direction pairs, measures
there, and reconstructs the dense table from them (``docs/planning.md``). Which
directions is a *design*; the designs are listed by name in :data:`DESIGNS`, in the
style of :data:`brdfkit.methods.METHODS`:

============ ============================================================= =========
name         design                                                        basis
============ ============================================================= =========
``nielsen``  greedy minimum condition number of the basis rows (Nielsen,   needed
             Jensen and Ramamoorthi 2015), then moved cell by cell
``render``   greedy minimum expected render error of the fit under the     needed
             basis's prior (:mod:`brdfkit.render_design`)
``uniform``  uniform over the Rusinkiewicz angles, as ``brdfkit sample``   optional
             draws (:func:`brdfkit.samples.draw_cells`)
============ ============================================================= =========

A design is chosen for a *fit*: the PCA basis, and the precision the fit gives a sample
(:class:`~brdfkit.render_design.Likelihood`), which a learnt-prior model's config holds
and a plain basis (IPCA's ridge fit) does not need. The ``render`` design uses both; the
``nielsen`` design the basis alone.

The Nielsen et al. design
-------------------------
Nielsen, Jensen and Ramamoorthi 2015, "On Optimal, Minimal BRDF Sampling for
Reflectance Acquisition" (SIGGRAPH Asia), reconstruct a material by fitting a PCA basis
of log-mapped BRDFs to the samples (:mod:`brdfkit.methods.ipca`; the learnt prior,
:mod:`brdfkit.methods.prior`, solves the same least-squares problem around a learnt
mean). The fit solves ``A c = b`` with ``A`` the ``N x K`` matrix of the basis rows at
the samples; its sensitivity to noise in ``b`` is the condition number of ``A``, so they
choose the directions that make it small. As in their code, the rows are those of the
components scaled by the spread of the training coefficients (their "scaled
eigenvectors", ``V S``; here ``components * sigma``, the columns the ridge fit of
:meth:`IpcaModel.coefficients <brdfkit.methods.ipca.IpcaModel.coefficients>` uses), at
the cells' own angles. The design:

1. the first direction is the cell whose row is longest (the largest leverage);
2. each next one is, among ``evaluations`` cells drawn at random (their 500; here
   :data:`DEFAULT_EVALUATIONS`), the one whose row gives the lowest condition number
   with the rows chosen so far;
3. then every chosen cell in turn is moved to whichever of its six grid neighbours
   (``+-step`` in each index, ``step`` 3 then 1) lowers the condition number most, over
   sweeps until a sweep gains less than 0.1% (their ``OptimizeLocations``, which they
   run after each addition; here once, at the end, which costs a fraction of a second).

Condition number of ``N < K`` rows: ``sigma_1 / sigma_N`` of the ``N x K`` matrix, its
largest over its smallest *non-zero* singular value (rows that are independent have
``N`` of them), so the first few directions are chosen to be as different as possible in
the basis's terms. (Nielsen et al.'s code takes the ``N x N`` block of the ``N``
strongest components instead.) From ``N >= K`` on it is the ordinary condition number.

The candidates are the measurable cells (both directions above the horizon,
:func:`brdfkit.geometry.valid_cells`) that the basis covers with a non-zero cosine
weight: the samples the fit uses. Everything random (the evaluated cells, the order of
the moves) comes from one generator seeded by ``seed``: the same seed, the same plan.
"""

from __future__ import annotations

import dataclasses
import os
from typing import Callable

import numpy as np

from .directions import DirectionSet
from .errors import InputError
from .geometry import GRID_SHAPE, N_CELLS, N_PHI_D, N_THETA_D, N_THETA_H, cell_angles, grid_cosine_weight, \
    valid_mask
from .trilinear import lookup_trilinear

__all__ = ["Plan", "Design", "DESIGNS", "DEFAULT_DESIGN", "DEFAULT_EVALUATIONS", "DEFAULT_CANDIDATES",
           "plan_directions", "plan_basis", "plan_target", "design_rows", "condition_number"]

DEFAULT_DESIGN = "render"
"""The design `brdfkit plan` and planned samples use unless told: chosen by renders (docs/planning.md)."""
DEFAULT_EVALUATIONS = 2000
"""Cells evaluated per added direction: Nielsen et al. evaluate 500; 2,000 cost 5 to 8 ms
per direction on the 2-core development machine under load (a batch of ``K x K``
eigenvalue problems, ``K = 8``; ``docs/planning.md`` has whole-command times)."""
DEFAULT_CANDIDATES = 100_000
"""Candidate cells of the ``render`` design, drawn at random from the basis's measurable
cells (about 700,000 for a MERL basis): each added direction costs a pass over them."""
_MAX_SWEEPS = 40


@dataclasses.dataclass
class Plan:
    """N measurement directions and how they were chosen.

    Attributes
    ----------
    directions
        :class:`~brdfkit.directions.DirectionSet`, each pair at its cell's own angles.
    cells
        int64 ``(N,)``, their flat MERL cell indices.
    design, seed
        The design's name (:data:`DESIGNS`) and the seed it ran with.
    basis
        The PCA basis the design used or was scored with, as named (``None``: none).
    components
        ``K``, the basis's number of components (``None`` without a basis).
    condition_number
        Of the basis rows at the directions (:func:`condition_number`), ``None`` without
        a basis.
    """

    directions: DirectionSet
    cells: np.ndarray
    design: str
    seed: int
    basis: str | None = None
    components: int | None = None
    condition_number: float | None = None

    def __len__(self) -> int:
        return len(self.directions)

    def describe(self) -> str:
        """One line: the design, N, the seed, the basis and the condition number."""
        text = f"design {self.design}, N = {len(self)}, seed {self.seed}"
        if self.basis is not None:
            text += (f"; basis of {self.basis}: {self.components} components, condition number "
                     f"{self.condition_number:.4g}")
        return text


@dataclasses.dataclass(frozen=True)
class Design:
    """One way of choosing directions, registered in :data:`DESIGNS` under its ``name``
    (``brdfkit plan --design``) with a one-line ``summary`` for help texts. It is the
    function ``choose(pool, n, seed, **options) -> cells`` (int64 ``(n,)`` flat cell
    indices), where ``pool`` holds the basis's candidate cells, their rows, the basis and
    the fit's likelihood (``None`` without a basis) and ``seed`` seeds everything random;
    ``needs_basis`` says it cannot run without a PCA basis, ``options`` names the
    keywords ``choose`` takes."""

    name: str
    summary: str
    choose: Callable = dataclasses.field(repr=False)
    needs_basis: bool = True
    options: tuple = ()


@dataclasses.dataclass
class _Pool:
    """The candidate cells of a basis: sorted flat indices ``cells`` (P,), their design
    rows ``rows`` (P, K) float32 (components times sigma), and ``where`` (N_CELLS,) int64,
    each cell's position in ``cells`` or -1; the ``basis`` and the fit's ``likelihood``."""

    cells: np.ndarray
    rows: np.ndarray
    where: np.ndarray
    basis: object = None
    likelihood: object = None

    @classmethod
    def of(cls, basis, likelihood=None) -> "_Pool":
        allowed = valid_mask().reshape(N_CELLS) & (grid_cosine_weight() > 0)
        keep = allowed[basis.cells]
        cells = np.asarray(basis.cells, np.int64)[keep]
        if cells.size == 0:
            raise InputError("the PCA basis covers no measurable cell of the MERL grid")
        rows = basis.components[:, keep].T * basis.sigma.astype(np.float32)[None, :]
        where = np.full(N_CELLS, -1, np.int64)
        where[cells] = np.arange(cells.size)
        return cls(cells, np.ascontiguousarray(rows, np.float32), where, basis, likelihood)


def _cond2(gram_batch: np.ndarray, rank: int) -> np.ndarray:
    """Squared condition numbers ``(B,)`` of matrices whose Gram matrices ``A^T A`` are
    ``gram_batch`` (B, K, K), counting the ``rank`` largest eigenvalues (the non-zero
    singular values squared); ``inf`` where the ``rank``-th is not positive."""
    ev = np.linalg.eigvalsh(gram_batch)  # ascending
    top, low = ev[:, -1], ev[:, -rank]
    ok = low > 1e-12 * np.maximum(top, 1e-300)
    return np.where(ok, top / np.where(ok, low, 1.0), np.inf)


def _nielsen(pool: _Pool, n: int, rng: np.random.Generator, evaluations: int = DEFAULT_EVALUATIONS,
             refine: bool = True) -> np.ndarray:
    """The design of the module docstring; positions into ``pool.cells``."""
    p, k = pool.rows.shape
    if n > p:
        raise InputError(f"{n} directions asked for, but the basis covers only {p} measurable cells")
    if evaluations < 1:
        raise InputError(f"evaluations must be at least 1, got {evaluations}")
    chosen = [int(np.argmax(np.einsum("ij,ij->i", pool.rows, pool.rows)))]
    taken = np.zeros(p, bool)
    taken[chosen[0]] = True
    r0 = pool.rows[chosen[0]].astype(np.float64)
    gram = np.outer(r0, r0)
    while len(chosen) < n:
        cand = np.unique(rng.integers(0, p, size=min(evaluations, p)))
        cand = cand[~taken[cand]]
        if cand.size == 0:  # a tiny pool, nearly used up: every cell left is a candidate
            cand = np.flatnonzero(~taken)
        # Shuffled, so that exact ties (a symmetric basis) go to a random cell, not the
        # lowest index.
        cand = rng.permutation(cand)
        rows = pool.rows[cand].astype(np.float64)
        c2 = _cond2(gram[None] + rows[:, :, None] * rows[:, None, :], min(len(chosen) + 1, k))
        best = int(cand[int(np.argmin(c2))])
        chosen.append(best)
        taken[best] = True
        r = pool.rows[best].astype(np.float64)
        gram += np.outer(r, r)
    chosen = np.array(chosen, np.int64)
    if refine and n > 1:
        chosen = _refine(pool, chosen, rng)
    return chosen


def _refine(pool: _Pool, chosen: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Nielsen et al.'s ``OptimizeLocations``: move each chosen cell to the grid
    neighbour (``+-step`` in one index; ``phi_d`` wraps, the thetas stop at the grid's
    edge) that lowers the condition number most, if any does; sweeps with ``step`` 3
    until one gains less than 0.1%, then with ``step`` 1 until the same."""
    k = pool.rows.shape[1]
    rank = min(chosen.size, k)
    a = pool.rows[chosen].astype(np.float64)
    gram = a.T @ a
    current = float(_cond2(gram[None], rank)[0])
    taken = np.zeros(pool.cells.size, bool)
    taken[chosen] = True
    for step in (3, 1):
        for _ in range(_MAX_SWEEPS):
            start = current
            for i in rng.permutation(chosen.size):
                cell = int(pool.cells[chosen[i]])
                ih, rest = divmod(cell, N_THETA_D * N_PHI_D)
                jd, kp = divmod(rest, N_PHI_D)
                moves = [(min(max(ih + dh, 0), N_THETA_H - 1), min(max(jd + dd, 0), N_THETA_D - 1), (kp + dp) % N_PHI_D)
                         for dh, dd, dp in ((step, 0, 0), (-step, 0, 0), (0, step, 0), (0, -step, 0),
                                            (0, 0, step), (0, 0, -step))]
                pos = pool.where[[kk + N_PHI_D * (jj + N_THETA_D * ii) for ii, jj, kk in moves]]
                pos = np.unique(pos[pos >= 0])
                pos = pos[~taken[pos]]
                if pos.size == 0:
                    continue
                old = a[i]
                rows = pool.rows[pos].astype(np.float64)
                c2 = _cond2((gram - np.outer(old, old))[None] + rows[:, :, None] * rows[:, None, :], rank)
                j = int(np.argmin(c2))
                if c2[j] < current * (1 - 1e-12):
                    taken[chosen[i]] = False
                    chosen[i] = pos[j]
                    taken[pos[j]] = True
                    a[i] = rows[j]
                    gram = a.T @ a  # recomputed, not updated: no drift over many moves
                    current = float(_cond2(gram[None], rank)[0])
            if current > start * (1 - 1e-3):
                break
    return chosen


def _nielsen_design(pool, n, seed, evaluations=DEFAULT_EVALUATIONS, refine=True):
    rng = np.random.default_rng(seed)
    return pool.cells[_nielsen(pool, n, rng, evaluations=evaluations, refine=refine)]


def _render_design(pool, n, seed, draws=None, candidates=DEFAULT_CANDIDATES):
    from .render_design import DEFAULT_DRAWS, cell_precision, greedy_render, render_metric

    draws = DEFAULT_DRAWS if draws is None else int(draws)
    if draws < 0 or int(candidates) < 1:
        raise InputError(f"render design: draws must be >= 0 and candidates >= 1, got {draws} and {candidates}")
    rng = np.random.default_rng(seed)
    p = pool.cells.size
    if n > p:
        raise InputError(f"{n} directions asked for, but the basis covers only {p} measurable cells")
    pick = np.sort(rng.choice(p, size=min(p, max(int(candidates), n)), replace=False))
    cells = pool.cells[pick]
    q = cell_precision(pool.basis, cells, pool.likelihood, draws=draws, seed=seed)
    metric = render_metric(pool.basis, draws=draws, seed=seed)
    return cells[greedy_render(pool.rows[pick], q, metric, n)]


def _uniform_design(pool, n, seed):
    from .samples import draw_cells

    # The cells `brdfkit sample -n N --seed S` draws from a table measured wherever the
    # grid can be (every MERL file, every proxy): the two give the same directions.
    return draw_cells(valid_mask().reshape(N_CELLS), n, seed, "angles")


DESIGNS: dict[str, Design] = {
    "nielsen": Design("nielsen", "greedy minimum condition number of the PCA basis rows (Nielsen et al. 2015)",
                      _nielsen_design, needs_basis=True, options=("evaluations", "refine")),
    "render": Design("render", "greedy minimum expected render error of the fit under the basis's prior "
                     "(brdfkit.render_design)", _render_design, needs_basis=True, options=("draws", "candidates")),
    "uniform": Design("uniform", "uniform over the Rusinkiewicz angles, as `brdfkit sample -n` draws",
                      _uniform_design, needs_basis=False),
}
"""The designs by name."""


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
        a learnt-prior file (likewise), a PCA basis file (``brdfkit fit --method ipca``;
        IPCA's ridge fit), an :class:`~brdfkit.methods.ipca.IpcaModel` or
        :class:`~brdfkit.methods.prior.model.PriorModel`, or ``None`` (the default
        built-in's learnt prior).

    Returns
    -------
    tuple
        ``(IpcaModel, label, Likelihood)``
        (:class:`~brdfkit.render_design.Likelihood`).

    Raises
    ------
    InputError
        An unknown name, a built-in or file without a basis (a hypernetwork), no default
        built-in installed.
    """
    from .atomic import check_input_file
    from .methods.ipca import DEFAULT_LAMBDA, IpcaModel, load_ipca
    from .methods.model_spec import file_method, resolve_for
    from .model.builtin import is_path_spec, read_manifest
    from .render_design import Likelihood

    def prior(path, label):
        from .methods import get_method

        model = get_method("prior").load(path, "cpu")
        return model.basis, label, Likelihood(model.cfg.weight, model.cfg.s2, model.cfg.lam)

    ridge = Likelihood(None, lam=DEFAULT_LAMBDA)
    if isinstance(spec, tuple) and len(spec) == 3 and isinstance(spec[0], IpcaModel):
        return spec  # a target this function made: loaded once, planned for many times
    if isinstance(spec, IpcaModel):
        return spec, "the given basis", ridge
    if hasattr(spec, "basis") and hasattr(spec, "cfg"):
        return spec.basis, "the given learnt prior", Likelihood(spec.cfg.weight, spec.cfg.s2, spec.cfg.lam)
    if spec is None:
        entry = next((m for m in read_manifest().installed() if m.default), None)
        if entry is None:
            raise InputError("no PCA basis given: pass -m NAME (a built-in model with a learnt prior, "
                             "`brdfkit models`) or -m BASIS.safetensors (`brdfkit fit --method ipca`); "
                             "no default built-in model is installed")
        return prior(resolve_for("prior", entry.name), f"{entry.name}, the default built-in")
    spec = os.fspath(spec)
    if not is_path_spec(spec):
        return prior(resolve_for("prior", spec), spec)
    check_input_file(spec)
    kind = file_method(spec)
    if kind == "ipca":
        return load_ipca(spec), os.path.basename(spec), ridge
    if kind == "prior":
        return prior(spec, os.path.basename(spec))
    raise InputError(f"{spec}: not a PCA basis or a learnt-prior model file; planning needs a basis: a built-in "
                     f"name with a learnt prior, a learnt-prior file or a file from `brdfkit fit --method ipca`")


def design_rows(basis, directions: DirectionSet) -> np.ndarray:
    """The rows of the basis's design matrix at the directions the fit uses.

    The components times ``sigma`` (the scaled columns of the ridge fit,
    :meth:`IpcaModel.coefficients <brdfkit.methods.ipca.IpcaModel.coefficients>`),
    interpolated trilinearly as the fit interpolates them; directions the fit leaves
    out (no basis cell around them, or on the horizon: zero cosine weight) are left out.

    Returns
    -------
    numpy.ndarray
        float64 ``(M, K)``, ``M <= N``.
    """
    from .methods.ipca import cosine_weight

    at = lookup_trilinear(basis._table().reshape(GRID_SHAPE + (-1,)), directions.theta_h, directions.theta_d,
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


def plan_directions(model=None, n: int = 40, *, design: str = DEFAULT_DESIGN, seed: int = 0, **options) -> Plan:
    """Choose ``n`` measurement directions with a design.

    Parameters
    ----------
    model
        The fit to plan for, as :func:`plan_target` takes it (a built-in name, a basis or
        learnt-prior file, an :class:`~brdfkit.methods.ipca.IpcaModel` or a learnt-prior
        model, or what :func:`plan_target` returned); ``None``: the
        default built-in's for a design that needs one, none for ``uniform`` (whose plan
        then has no condition number).
    n
        Number of directions, ``>= 1``.
    design
        A name of :data:`DESIGNS`.
    seed
        Seeds everything random in the design.
    options
        The design's options (``nielsen``: ``evaluations``, :data:`DEFAULT_EVALUATIONS`;
        ``refine``, ``True``; ``render``: ``draws``,
        :data:`~brdfkit.render_design.DEFAULT_DRAWS`; ``candidates``,
        :data:`DEFAULT_CANDIDATES`).

    Returns
    -------
    Plan
        Directions at the cells' own angles (``phi_h = 0``), their cells, and the
        condition number of the basis rows there (with a basis).

    Raises
    ------
    InputError
        An unknown design or option, ``n < 1``, more directions than candidate cells, a
        model that is no basis.
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
    basis, label, likelihood = (None, None, None) if model is None and not d.needs_basis else plan_target(model)
    pool = _Pool.of(basis, likelihood) if basis is not None and d.needs_basis else None
    cells = np.asarray(d.choose(pool, n, seed, **options), np.int64)
    th, td, pd = cell_angles(cells)
    directions = DirectionSet(th, td, pd, f"plan {design} N={n} seed={seed}")
    cond = None if basis is None else condition_number(design_rows(basis, directions))
    return Plan(directions, cells, design, int(seed), label, None if basis is None else basis.n_components, cond)
