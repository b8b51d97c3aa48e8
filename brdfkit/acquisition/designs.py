"""The designs of ``brdfkit plan``: ways of choosing N measurement directions, by name.

============ ============================================================= =========
name         design                                                        basis
============ ============================================================= =========
``nielsen``  greedy minimum condition number of the basis rows (Nielsen,   needed
             Jensen and Ramamoorthi 2015), then moved cell by cell
``render``   greedy minimum expected render error of the fit under the     needed
             basis's prior (:mod:`brdfkit.acquisition.optimal_design`), or
             under its posterior after given samples
             (:mod:`brdfkit.acquisition.rounds`)
``uniform``  uniform over the Rusinkiewicz angles, as ``brdfkit sample``   optional
             draws (:func:`brdfkit.acquisition.sampling.draw_cells`)
============ ============================================================= =========

A design is a function ``choose(pool, n, seed, **options) -> cells`` registered in
:data:`DESIGNS` (:class:`Design`); :func:`brdfkit.acquisition.planning.plan_directions`
runs it on the basis's candidate cells (:class:`CandidatePool`).

The Nielsen et al. design
-------------------------
Nielsen, Jensen and Ramamoorthi 2015, "On Optimal, Minimal BRDF Sampling for
Reflectance Acquisition" (SIGGRAPH Asia), reconstruct a material by fitting a PCA basis
of log-mapped BRDFs to the samples (:mod:`brdfkit.methods.ipca`; the learnt prior,
:mod:`brdfkit.prior`, solves the same least-squares problem around a learnt
mean). The fit solves ``A c = b`` with ``A`` the ``N x K`` matrix of the basis rows at
the samples; its sensitivity to noise in ``b`` is the condition number of ``A``, so they
choose the directions that make it small. As in their code, the rows are those of the
components scaled by the spread of the training coefficients (their "scaled
eigenvectors", ``V S``; here ``components * sigma``, the columns the ridge fit of
:meth:`PcaBasis.coefficients <brdfkit.basis.PcaBasis.coefficients>` uses), at
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
import weakref
from typing import Callable

import numpy as np

from brdfkit.errors import InputError
from brdfkit.geometry import N_CELLS, N_PHI_D, N_THETA_D, N_THETA_H, grid_cosine_weight, valid_cells

__all__ = ["Design", "DESIGNS", "CandidatePool", "DEFAULT_EVALUATIONS", "DEFAULT_CANDIDATES"]

DEFAULT_EVALUATIONS = 2000
"""Cells evaluated per added direction: Nielsen et al. evaluate 500; 2,000 cost 5 to 8 ms
per direction on the 2-core development machine under load (a batch of ``K x K``
eigenvalue problems, ``K = 8``; ``docs/planning.md`` has whole-command times)."""
DEFAULT_CANDIDATES = 100_000
"""Candidate cells of the ``render`` design, drawn at random from the basis's measurable
cells (about 700,000 for a MERL basis): each added direction costs a pass over them."""
_MAX_SWEEPS = 40


@dataclasses.dataclass(frozen=True)
class Design:
    """One way of choosing directions, registered in :data:`DESIGNS` under its ``name``
    (``brdfkit plan --design``) with a one-line ``summary`` for help texts. It is the
    function ``choose(pool, n, seed, **options) -> cells`` (int64 ``(n,)`` flat cell
    indices), where ``pool`` holds the basis's candidate cells, their rows, the basis and
    the fit's likelihood (``None`` without a basis) and ``seed`` seeds everything random;
    ``needs_basis`` says it cannot run without a PCA basis, ``options`` names the
    keywords ``choose`` takes. ``takes_given``: it also plans given the samples measured
    so far (``brdfkit plan --given``): ``choose(pool, n, seed, given=posterior, **options)``,
    ``posterior`` a :class:`~brdfkit.acquisition.rounds.Posterior` and ``pool`` without
    its cells, returns ``(cells, (expected error before, after))``."""

    name: str
    summary: str
    choose: Callable = dataclasses.field(repr=False)
    needs_basis: bool = True
    options: tuple = ()
    takes_given: bool = False


@dataclasses.dataclass
class CandidatePool:
    """The candidate cells of a basis: sorted flat indices ``cells`` (P,), their design
    rows ``rows`` (P, K) float32 (components times sigma), and ``where`` (N_CELLS,) int64,
    each cell's position in ``cells`` or -1; the ``basis`` and the fit's ``likelihood``."""

    cells: np.ndarray
    rows: np.ndarray
    where: np.ndarray
    basis: object = None
    likelihood: object = None

    @classmethod
    def of(cls, basis, likelihood=None) -> "CandidatePool":
        """The pool of ``basis``'s candidate cells; its cells and rows are worked out once
        per basis object (a process that plans many times for one basis: the bench's
        planned samplings, 0.5 s each otherwise)."""
        hit = _POOLS.get(id(basis))
        if hit is not None and hit[0]() is basis:
            return dataclasses.replace(hit[1], likelihood=likelihood)
        pool = cls._of(basis, likelihood)
        _POOLS.clear()  # one basis at a time: a pool holds its (P, K) rows
        _POOLS[id(basis)] = (weakref.ref(basis), pool)
        return pool

    @classmethod
    def _of(cls, basis, likelihood) -> "CandidatePool":
        allowed = _valid_flat() & (grid_cosine_weight() > 0)
        keep = allowed[basis.cells]
        cells = np.asarray(basis.cells, np.int64)[keep]
        if cells.size == 0:
            raise InputError("the PCA basis covers no measurable cell of the MERL grid")
        rows = basis.components[:, keep].T * basis.sigma.astype(np.float32)[None, :]
        where = np.full(N_CELLS, -1, np.int64)
        where[cells] = np.arange(cells.size)
        return cls(cells, np.ascontiguousarray(rows, np.float32), where, basis, likelihood)

    def restricted(self, keep) -> "CandidatePool":
        """The pool of the cells where ``keep`` (bool ``(P,)``) is set: a design run on
        it chooses among them only (its moves, too)."""
        cells = self.cells[keep]
        where = np.full(N_CELLS, -1, np.int64)
        where[cells] = np.arange(cells.size)
        return CandidatePool(cells, np.ascontiguousarray(self.rows[keep]), where, self.basis, self.likelihood)


_POOLS: dict = {}  # id(basis) -> (weak reference to it, its pool)


def _valid_flat() -> np.ndarray:
    """:func:`brdfkit.geometry.valid_mask` flat, from the cells computed once a process."""
    mask = np.zeros(N_CELLS, bool)
    mask[valid_cells()] = True
    return mask


def _cond2(gram_batch: np.ndarray, rank: int) -> np.ndarray:
    """Squared condition numbers ``(B,)`` of matrices whose Gram matrices ``A^T A`` are
    ``gram_batch`` (B, K, K), counting the ``rank`` largest eigenvalues (the non-zero
    singular values squared); ``inf`` where the ``rank``-th is not positive."""
    ev = np.linalg.eigvalsh(gram_batch)  # ascending
    top, low = ev[:, -1], ev[:, -rank]
    ok = low > 1e-12 * np.maximum(top, 1e-300)
    return np.where(ok, top / np.where(ok, low, 1.0), np.inf)


def _cond2_added(a: np.ndarray, gram: np.ndarray, rows: np.ndarray, rank: int) -> np.ndarray:
    """:func:`_cond2` of the rows ``a`` (N, K) with each of ``rows`` (B, K) added in turn
    (``gram`` is ``a^T a``). While ``N + 1 < K`` the non-zero eigenvalues are those of the
    ``(N + 1) x (N + 1)`` matrix ``[a; r] [a; r]^T``, a far smaller problem than the ``K x
    K`` Gram matrix (the first directions of a 30-component basis: 10 to 80 times less
    work); from there on the ``K x K`` one."""
    n, k = a.shape
    if n + 1 >= k:
        return _cond2(gram[None] + rows[:, :, None] * rows[:, None, :], rank)
    small = np.empty((rows.shape[0], n + 1, n + 1))
    small[:, :n, :n] = a @ a.T
    small[:, :n, n] = small[:, n, :n] = rows @ a.T
    small[:, n, n] = np.einsum("ij,ij->i", rows, rows)
    return _cond2(small, rank)


def _cond2_replaced(a: np.ndarray, gram: np.ndarray, i: int, rows: np.ndarray, rank: int) -> np.ndarray:
    """:func:`_cond2` of the rows ``a`` (N, K) with row ``i`` replaced by each of ``rows``
    (B, K) in turn (``gram`` is ``a^T a``); the ``N x N`` problem while ``N < K``, as
    :func:`_cond2_added`."""
    n, k = a.shape
    if n >= k:
        old = a[i]
        return _cond2((gram - np.outer(old, old))[None] + rows[:, :, None] * rows[:, None, :], rank)
    small = np.empty((rows.shape[0], n, n))
    small[:] = a @ a.T
    cross = rows @ a.T  # (B, N): the new row against every row, its own old one at i
    small[:, i, :] = small[:, :, i] = cross
    small[:, i, i] = np.einsum("ij,ij->i", rows, rows)
    return _cond2(small, rank)


def _nielsen(pool: CandidatePool, n: int, rng: np.random.Generator, evaluations: int = DEFAULT_EVALUATIONS,
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
    a = pool.rows[chosen].astype(np.float64)  # the chosen rows (N, K)
    gram = a.T @ a
    while len(chosen) < n:
        cand = np.unique(rng.integers(0, p, size=min(evaluations, p)))
        cand = cand[~taken[cand]]
        if cand.size == 0:  # a tiny pool, nearly used up: every cell left is a candidate
            cand = np.flatnonzero(~taken)
        # Shuffled, so that exact ties (a symmetric basis) go to a random cell, not the
        # lowest index.
        cand = rng.permutation(cand)
        rows = pool.rows[cand].astype(np.float64)
        c2 = _cond2_added(a, gram, rows, min(len(chosen) + 1, k))
        best = int(cand[int(np.argmin(c2))])
        chosen.append(best)
        taken[best] = True
        r = pool.rows[best].astype(np.float64)
        a = np.vstack([a, r])
        gram += np.outer(r, r)
    chosen = np.array(chosen, np.int64)
    if refine and n > 1:
        chosen = _refine(pool, chosen, rng)
    return chosen


def _refine(pool: CandidatePool, chosen: np.ndarray, rng: np.random.Generator) -> np.ndarray:
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
                rows = pool.rows[pos].astype(np.float64)
                c2 = _cond2_replaced(a, gram, i, rows, rank)
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


def _render_design(pool, n, seed, draws=None, candidates=DEFAULT_CANDIDATES, given=None):
    from brdfkit.acquisition.optimal_design import DEFAULT_DRAWS, cell_precision, greedy_render, render_metric

    draws = DEFAULT_DRAWS if draws is None else int(draws)
    if draws < 0 or int(candidates) < 1:
        raise InputError(f"render design: draws must be >= 0 and candidates >= 1, got {draws} and {candidates}")
    if given is not None:  # from the posterior after the samples, at this material
        from brdfkit.acquisition.rounds import render_given

        return render_given(pool, n, seed, given, draws, candidates)
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
    from brdfkit.acquisition.sampling import draw_cells

    # The cells `brdfkit sample -n N --seed S` draws from a table measured wherever the
    # grid can be (every MERL file, every proxy): the two give the same directions.
    return draw_cells(_valid_flat(), n, seed, "angles")


DESIGNS: dict[str, Design] = {
    "nielsen": Design("nielsen", "greedy minimum condition number of the PCA basis rows (Nielsen et al. 2015)",
                      _nielsen_design, needs_basis=True, options=("evaluations", "refine")),
    "render": Design("render", "greedy minimum expected render error of the fit under the basis's prior "
                     "(brdfkit.acquisition.optimal_design)", _render_design, needs_basis=True,
                     options=("draws", "candidates"), takes_given=True),
    "uniform": Design("uniform", "uniform over the Rusinkiewicz angles, as `brdfkit sample -n` draws",
                      _uniform_design, needs_basis=False),
}
"""The designs by name."""
