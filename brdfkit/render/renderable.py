"""BRDFs a renderer evaluates at the pairs it queries.

A renderable BRDF has a ``name`` and one of

* ``eval_pairs(block) -> (3, M)`` float32: the BRDF (1/sr) at a block's pairs
  (:class:`brdfkit.render.pairs.PairBlock`: their MERL grid coordinates, radiance weights
  and, when the renderer was asked for them, local directions); a table's, by a
  trilinear lookup at the grid coordinates;
* ``eval_dirs(wi, wo) -> (M, 3)``: the BRDF at local direction pairs (NumPy float32
  ``(M, 3)`` unit vectors, ``z`` the normal; 0 where either is at or below the horizon),
  for a BRDF that is not a function of the grid's angles alone (an RGL file conditioned
  on the view, :class:`brdfkit.render.measured.MeasuredBRDF`) or is evaluated from its
  own inputs (a hyponet, :class:`brdfkit.hypernet.neural_brdf.NeuralBRDF`).

:class:`TableBRDF` is a dense MERL-grid table, interpolated as
:func:`brdfkit.geometry.trilinear.lookup_trilinear` does (NaN-aware; 0 where no corner is
measured) through :class:`brdfkit.render.lookup.TableRows`.
:func:`brdfkit.files.brdf_file.load_brdf` opens any of them from a file.
"""

from __future__ import annotations

import numpy as np

from brdfkit.errors import InputError
from brdfkit.geometry import TABLE_SHAPE

__all__ = ["RowLookups", "TableBRDF", "TableStackBRDF", "DecodedBRDF", "stack_tables", "coords_of_dirs"]


def coords_of_dirs(wi, wo):
    """Grid coordinates ``(3, M)`` float32 of local direction pairs ``(M, 3)`` and the
    mask of those above the horizon (both ``z > 0``)."""
    from brdfkit.render.pairs import _coords

    wi = np.ascontiguousarray(np.asarray(wi, np.float32).reshape(-1, 3).T)
    wo = np.ascontiguousarray(np.asarray(wo, np.float32).reshape(-1, 3).T)
    out = np.empty((3, wi.shape[1]), np.float32)
    _coords(wi, wo, out)
    return out, (wi[2] > 0) & (wo[2] > 0)


class RowLookups:
    """``eval_pairs`` and ``eval_dirs`` of a BRDF whose values are lookups of its ``rows``
    (:class:`~brdfkit.render.lookup.TableRows`): a table's, or a decoder's."""

    def eval_pairs(self, block):
        """float32 ``(3, M)`` at a :class:`~brdfkit.render.pairs.PairBlock`'s pairs."""
        return self.rows.lookup(block.coords)

    def eval_dirs(self, wi, wo):
        """BRDF ``(M, 3)`` float32 at local direction pairs ``wi, wo`` ``(M, 3)`` (0 below
        the horizon)."""
        coords, above = coords_of_dirs(wi, wo)
        out = self.rows.lookup(coords)
        out[:, ~above] = 0.0
        return out.T


class TableBRDF(RowLookups):
    """A dense ``(90, 90, 180, 3)`` BRDF table as a renderable BRDF.

    Parameters
    ----------
    table
        Array-like ``(90, 90, 180, 3)``, 1/sr, NaN where not measured.
    name
        Shown in progress messages and metric tables.
    device
        Ignored (renders run in NumPy); kept for callers that pass one.
    """

    def __init__(self, table, name: str = "table", device=None):
        arr = np.asarray(table)
        if arr.shape != TABLE_SHAPE:
            raise InputError(f"{name}: BRDF table of shape {arr.shape}, expected {TABLE_SHAPE}")
        self.name = name
        self.table = arr
        self.device = "cpu"
        self._rows = None

    @property
    def rows(self):
        """The :class:`~brdfkit.render.lookup.TableRows` of the table (made once)."""
        if self._rows is None:
            from brdfkit.render.lookup import TableRows

            self._rows = TableRows(self.table)
        return self._rows


class DecodedBRDF(RowLookups):
    """A renderable BRDF that a decoder makes on the MERL grid (a basis or residual
    embedding): evaluated, for a render, only at the cells its pairs reach.

    A subclass gives ``to_table()`` (the whole table) and ``at_cells(cells) -> (at,
    values)`` (the decode at those of ``cells`` it covers, ``(n, 3)``); a render calls
    :meth:`prepare_cells` with the cells its pairs' trilinear corners reach
    (:meth:`brdfkit.render.quadrature.ScenePairs.reached_cells`), and the lookups read
    the decode there (:class:`~brdfkit.render.lookup.TableRows` holding only those cells),
    the same values a lookup of the whole decoded table reads. Without it, the whole table
    is decoded once, on first use.
    """

    name = "embedding"
    device = "cpu"
    _rows = None

    def prepare_cells(self, cells) -> None:
        """Decode at ``cells`` only (flat MERL indices), for the lookups that follow."""
        from brdfkit.render.lookup import TableRows

        at, values = self.at_cells(cells)
        self._rows = TableRows.from_cells(at, values)

    @property
    def rows(self):
        """The :class:`~brdfkit.render.lookup.TableRows` its lookups read (the whole table's
        unless :meth:`prepare_cells` was called)."""
        if self._rows is None:
            from brdfkit.render.lookup import TableRows

            self._rows = TableRows(self.to_table())
        return self._rows


class TableStackBRDF:
    """Several :class:`TableBRDF` evaluated together at the same pairs (a quadrature pass
    rendering two tables: ``brdfkit metrics`` of a pair): the corners' rows and weights
    are computed once for all members; each member's values are those of its own
    ``eval_pairs``, to the bit.

    Attributes
    ----------
    members
        Number of tables: ``eval_pairs`` returns ``(3 members, M)``.
    """

    def __init__(self, brdfs):
        self.brdfs = list(brdfs)
        if not self.brdfs or any(not isinstance(b, TableBRDF) for b in self.brdfs):
            raise TypeError("TableStackBRDF takes TableBRDF members")
        self.members = len(self.brdfs)
        self.device = "cpu"
        self.name = " + ".join(b.name for b in self.brdfs)

    def eval_pairs(self, block):
        """float32 ``(3 members, M)``: member ``j`` in rows ``3 j .. 3 j + 2``."""
        from brdfkit.render.lookup import BLOCK, corners

        tables = [b.rows for b in self.brdfs]
        m = block.coords.shape[1]
        out = np.empty((3 * len(tables), m), np.float32)
        for s in range(0, m, BLOCK):
            rows, w = corners(block.coords[:, s:s + BLOCK])
            for j, t in enumerate(tables):
                t.combine(t.gather(rows), w, out[3 * j:3 * j + 3, s:s + BLOCK])
        return out


def stack_tables(brdfs) -> list:
    """How a pass evaluates ``brdfs``: ``[(evaluator, indices)]``, the :class:`TableBRDF`
    among them (two or more) as one :class:`TableStackBRDF` whose members are
    ``brdfs[i]`` for ``i`` in ``indices`` (in order), every other BRDF alone."""
    out, stack = [], None
    for i, b in enumerate(brdfs):
        if type(b) is TableBRDF:
            if stack is None:
                stack = []
                out.append(stack)
            stack.append(i)
        else:
            out.append([i])
    return [(TableStackBRDF([brdfs[i] for i in idx]) if len(idx) > 1 else brdfs[idx[0]], idx) for idx in out]
