"""BRDFs a renderer evaluates at the directions it queries.

A renderable BRDF has ``eval_dirs(wi, wo) -> (N, 3)`` (torch ``(N, 3)`` unit vectors in
the local frame, ``z`` the normal; BRDF in 1/sr, 0 where either direction is at or below
the horizon) and a ``name``. Two kinds exist:

* :class:`TableBRDF`: a dense MERL-grid table, interpolated with
  :func:`brdfkit.geometry.trilinear.lookup_trilinear` (NaN-aware; 0 where no corner is measured);
* :class:`brdfkit.hypernet.neural_brdf.NeuralBRDF`: one material's hyponet, evaluated directly at the
  queried directions (never through a dense table).

:func:`brdfkit.files.brdf_file.load_brdf` opens either from a file: a MERL ``.binary`` or an
embedding ``.emb`` with its model.
"""

from __future__ import annotations


import numpy as np

from brdfkit.runtime import resolve_device
from brdfkit.errors import InputError
from brdfkit.geometry import TABLE_SHAPE

__all__ = ["TableBRDF", "TableStackBRDF", "stack_tables"]


class TableBRDF:
    """A dense ``(90, 90, 180, 3)`` BRDF table as a renderable BRDF.

    Parameters
    ----------
    table
        Array-like ``(90, 90, 180, 3)``, 1/sr, NaN where not measured.
    name
        Shown in progress messages and metric tables.
    device
        Torch device of the float32 copy used for lookups (default: CUDA if available).

    Notes
    -----
    Lookups go through a :class:`brdfkit.geometry.trilinear.TrilinearTable` once the BRDF has been
    asked for :attr:`PREPARE_AFTER` pairs (same values to the bit; building it costs
    about as much as one plain lookup of a render's block, so a tiny render skips it).
    """

    PREPARE_AFTER = 1 << 18

    def __init__(self, table, name: str = "table", device=None):
        import torch

        arr = np.asarray(table)
        if arr.shape != TABLE_SHAPE:
            raise InputError(f"{name}: BRDF table of shape {arr.shape}, expected {TABLE_SHAPE}")
        self.name = name
        self.table = arr
        self.device = resolve_device(device)
        self._t = torch.as_tensor(np.ascontiguousarray(arr, np.float32), device=self.device)
        self._lut = None  # trilinear.TrilinearTable of _t, built after PREPARE_AFTER pairs
        self._pairs = 0

    def _lookup_table(self, pairs: int):
        """The table to look up after ``pairs`` more pairs: the prepared one once asked for
        :attr:`PREPARE_AFTER` in all, else the plain float32 table."""
        from brdfkit.geometry.trilinear import TrilinearTable

        self._pairs += pairs
        if self._lut is None and self._pairs >= self.PREPARE_AFTER:
            self._lut = TrilinearTable(self._t)
        return self._t if self._lut is None else self._lut

    def eval_dirs(self, wi, wo):
        """BRDF ``(N, 3)`` float32 at local direction pairs ``wi, wo`` (torch ``(N, 3)``)."""
        from brdfkit.geometry.trilinear import lookup_trilinear

        th, td, pd, above = _pair_angles(wi, wo, self.device)
        rho = lookup_trilinear(self._lookup_table(th.shape[0]), th, td, pd, fill=0.0)
        # In place on the (3, N) rows: the prepared lookup's (N, 3) is channel-major in
        # memory, and so is what comes back (the quadrature reads it per channel).
        return _zero_below(rho.T, above).T.to(wi.device)


def _zero_below(rows, above):
    """``rows`` ``(C, N)`` set to 0 in place where not ``above``: by the indices of the few
    pairs below the horizon (a third of a broadcast ``masked_fill_``'s time)."""
    return rows.index_fill_(1, (~above).nonzero().squeeze(1), 0.0)


def _pair_angles(wi, wo, device):
    """``(theta_h, theta_d, phi_d, above)`` of direction pairs, float32 on ``device``."""
    import torch

    from brdfkit.geometry import half_diff_from_io

    wi_ = wi.to(device, torch.float32).reshape(-1, 3)
    wo_ = wo.to(device, torch.float32).reshape(-1, 3)
    th, _, td, pd = half_diff_from_io(wi_, wo_)
    return th, td, pd, (wi_[:, 2] > 0) & (wo_[:, 2] > 0)


class TableStackBRDF:
    """Several :class:`TableBRDF` evaluated together at the same direction pairs (a
    quadrature pass rendering two tables: ``brdfkit metrics`` of a pair).

    The pairs' angles, and once both tables are prepared the corners' rows and weights
    (:func:`brdfkit.geometry.trilinear.lookup_prepared_many`), are computed once for all members;
    each member's values are those of its own ``eval_dirs``, to the bit.

    Parameters
    ----------
    brdfs
        :class:`TableBRDF` on one device.

    Attributes
    ----------
    members
        Number of tables: ``eval_dirs`` returns ``(N, 3 members)``.
    """

    def __init__(self, brdfs):
        self.brdfs = list(brdfs)
        if not self.brdfs or any(not isinstance(b, TableBRDF) for b in self.brdfs):
            raise TypeError("TableStackBRDF takes TableBRDF members")
        if len({str(b.device) for b in self.brdfs}) != 1:
            raise ValueError("the tables of a TableStackBRDF must share a device")
        self.members = len(self.brdfs)
        self.device = self.brdfs[0].device
        self.name = " + ".join(b.name for b in self.brdfs)

    def eval_dirs(self, wi, wo):
        """float32 ``(N, 3 members)`` at local direction pairs ``wi, wo`` (torch
        ``(N, 3)``): member ``j`` in columns ``3 j .. 3 j + 2``, channel-major in memory."""
        import torch

        from brdfkit.geometry import fractional_indices
        from brdfkit.geometry.trilinear import TrilinearTable, lookup_prepared_many, lookup_trilinear

        th, td, pd, above = _pair_angles(wi, wo, self.device)
        tables = [b._lookup_table(th.shape[0]) for b in self.brdfs]
        if all(isinstance(t, TrilinearTable) for t in tables):
            rhos = lookup_prepared_many(tables, *fractional_indices(th, td, pd), 0.0)
        else:
            rhos = [lookup_trilinear(t, th, td, pd, fill=0.0) for t in tables]
        return _zero_below(torch.cat([r.T for r in rhos]), above).T.to(wi.device)


def stack_tables(brdfs) -> list:
    """How a pass evaluates ``brdfs``: ``[(evaluator, indices)]``, the :class:`TableBRDF`
    among them (two or more on one device) as one :class:`TableStackBRDF` whose members
    are ``brdfs[i]`` for ``i`` in ``indices`` (in order), every other BRDF alone."""
    out, stacks = [], {}
    for i, b in enumerate(brdfs):
        if type(b) is TableBRDF:
            if str(b.device) not in stacks:
                stacks[str(b.device)] = []
                out.append(stacks[str(b.device)])
            stacks[str(b.device)].append(i)
        else:
            out.append([i])
    return [(TableStackBRDF([brdfs[i] for i in idx]) if len(idx) > 1 else brdfs[idx[0]], idx) for idx in out]
