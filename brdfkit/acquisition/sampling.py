"""Sample sets drawn from a dense table, or measured from it at given directions: the
measurements a lab would take, were the table the material.

* :func:`draw_samples`: ``n`` cells drawn at random (uniform over the Rusinkiewicz
  angles, as ``brdfkit sample -n`` draws, or over the measured cells);
* :func:`draw_cells`: the same draw of cells, for a mask of allowed cells;
* :func:`measure_samples`: the table at given directions (``brdfkit sample --at``);
* :func:`join_samples`: the samples so far and a round's, one set (``brdfkit sample
  --at --given``: a lab measuring in rounds, ``docs/planning.md``).

Examples
--------
>>> import numpy as np
>>> from brdfkit.geometry import TABLE_SHAPE
>>> table = np.full(TABLE_SHAPE, 0.5)
>>> s = draw_samples(table, 40, seed=0)
>>> len(s), float(s.rgb.max())
(40, 0.5)
>>> bool((draw_samples(table, 40, seed=0).theta_h == s.theta_h).all())
True
"""

from __future__ import annotations

import numpy as np

from brdfkit.errors import InputError
from brdfkit.geometry import GRID_SHAPE, HALF_PI, N_CELLS, cell_angles, cell_index
from brdfkit.geometry.trilinear import lookup_trilinear
from brdfkit.io.directions import DirectionSet
from brdfkit.io.samples import SampleSet

__all__ = ["draw_samples", "draw_cells", "measure_samples", "join_samples"]


def draw_samples(table: np.ndarray, n: int, seed: int | None = 0,
                 distribution: str = "angles", source: str = "") -> SampleSet:
    """Draw ``n`` measurements of a dense table, only from measured cells.

    Parameters
    ----------
    table
        ``(90, 90, 180, 3)`` in physical units, NaN where not measured.
    n
        Number of samples (cells may repeat, as they would in a real acquisition that
        revisits a direction).
    seed
        Seed of the NumPy generator; the same seed gives the same samples.
    distribution
        ``"angles"``: uniform over the Rusinkiewicz angles ``(theta_h, theta_d, phi_d)``
        in ``[0, pi/2]^2 x [0, pi)``, each draw taking the value of its cell;
        ``"cells"``: uniform over the measured cells (:func:`draw_cells`).

    Returns
    -------
    SampleSet
        Angles of the chosen cells (the grid's own angles) and their values.
    """
    if n < 1:
        raise InputError(f"number of samples must be at least 1, got {n}")
    flat = np.asarray(table).reshape(N_CELLS, 3)
    measured = np.isfinite(flat).all(axis=1)
    if not measured.any():
        raise InputError(f"{source or 'table'}: no measured cells to sample from")
    idx = draw_cells(measured, n, seed, distribution)
    th, td, pd = cell_angles(idx)
    return SampleSet(th, td, pd, flat[idx].astype(np.float64), source)


def draw_cells(allowed: np.ndarray, n: int, seed: int | None = 0, distribution: str = "angles") -> np.ndarray:
    """Flat indices of ``n`` cells drawn among the ``allowed`` ones (bool ``(N_CELLS,)``,
    at least one set), as :func:`draw_samples` draws them (the same seed, the same cells).

    ``"angles"`` draws uniformly over ``(theta_h, theta_d, phi_d)`` in ``[0, pi/2]^2 x
    [0, pi)`` and keeps the draws that land in an allowed cell (so a cell's chance is
    its angular volume: the square-root spacing of ``theta_h`` makes the cells next to
    the specular peak small); ``"cells"`` draws uniformly over the allowed cells. Cells
    may repeat. int64 ``(n,)``.
    """
    rng = np.random.default_rng(seed)
    if distribution == "cells":
        return rng.choice(np.flatnonzero(allowed), size=n)
    if distribution != "angles":
        raise InputError(f"unknown distribution {distribution!r}; use 'angles' or 'cells'")
    chunks, have = [], 0
    while have < n:
        m = max(2 * (n - have), 64)
        th = rng.uniform(0, HALF_PI, m)
        td = rng.uniform(0, HALF_PI, m)
        pd = rng.uniform(0, np.pi, m)
        cand = cell_index(th, td, pd)
        cand = cand[allowed[cand]]
        chunks.append(cand)
        have += cand.size
    return np.concatenate(chunks)[:n]


def measure_samples(table: np.ndarray, directions: DirectionSet, source: str = "") -> SampleSet:
    """A dense table measured at given directions: what an instrument set to them would
    read, were the table the material.

    The value at a direction is the table's trilinear interpolation there
    (:func:`brdfkit.geometry.trilinear.lookup_trilinear`, the lookup the renderers and the PCA
    fits use, in the grid's own coordinates, unmeasured corners left out). A real
    measurement reads the material's BRDF at the direction itself, which the table
    knows only at its cells: between them, the interpolation is the table's best
    statement of it, continuous in the direction (the nearest cell would jump from one
    value to the next, and MERL's own lookup takes the cell *below*, not the nearest).
    At a cell's own angles, as :func:`brdfkit.acquisition.planning.plan_directions` and
    ``brdfkit sample -n`` give them, the weight of every other corner is zero (or a
    rounding error of ``1e-15``) and the value is the cell's.

    Parameters
    ----------
    table
        ``(90, 90, 180, 3)`` in physical units (1/sr), NaN where not measured.
    directions
        :class:`brdfkit.io.directions.DirectionSet`.
    source
        The material's name, for the sample set and messages.

    Returns
    -------
    SampleSet
        The directions' own angles and the values, float64, 1/sr.

    Raises
    ------
    InputError
        A direction with no measured cell among the eight around it (named by its line).
    """
    table = np.asarray(table, np.float64)
    if table.shape != GRID_SHAPE + (3,):
        raise InputError(f"{source or 'table'}: expected a (90, 90, 180, 3) table, got shape {table.shape}")
    if len(directions) == 0:
        raise InputError(f"{directions.source or 'directions'}: no directions to measure at")
    rgb = lookup_trilinear(table, directions.theta_h, directions.theta_d, directions.phi_d)
    bad = ~np.isfinite(rgb).all(axis=1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise InputError(f"{directions.source or 'directions'}: {directions.where(i)}: {source or 'the table'} "
                         f"has no measured cell around this direction ({int(bad.sum())} such direction"
                         f"{'s' if bad.sum() > 1 else ''})")
    return SampleSet(np.array(directions.theta_h, np.float64), np.array(directions.theta_d, np.float64),
                     np.array(directions.phi_d, np.float64), np.clip(rgb, 0.0, None), source)


def join_samples(*sets: SampleSet, source: str = "") -> SampleSet:
    """Sample sets one after the other, as one set: the samples measured so far, then a
    round's (``brdfkit sample --at PLAN --given SO_FAR``). The values and angles are
    kept as they are (a cell measured twice stays twice: both are measurements).

    Parameters
    ----------
    sets
        :class:`~brdfkit.io.samples.SampleSet`, at least one.
    source
        The joined set's name; default the sets' names joined by ``+``.

    Returns
    -------
    SampleSet
        Their notes kept, each once.

    Examples
    --------
    >>> from brdfkit.geometry import TABLE_SHAPE
    >>> table = np.full(TABLE_SHAPE, 0.5)
    >>> both = join_samples(draw_samples(table, 3, seed=0, source="a"), draw_samples(table, 2, seed=1, source="b"))
    >>> len(both), both.source
    (5, 'a+b')
    """
    if not sets:
        raise InputError("no sample sets to join")
    notes = list(dict.fromkeys(s.note for s in sets if s.note))
    return SampleSet(*(np.concatenate([getattr(s, k) for s in sets]) for k in ("theta_h", "theta_d", "phi_d", "rgb")),
                     source or "+".join(s.source for s in sets if s.source), "; ".join(notes))
