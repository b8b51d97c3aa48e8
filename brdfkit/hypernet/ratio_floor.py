"""The ratio floor of a tune (``brdfkit tune -O floor_weight=W``): a loss that sees the
relative error where the mapped loss cannot.

The paper's mapping (:mod:`brdfkit.hypernet.mapping`) is ``ln(1 + (rho + eps) / (rho_ref +
eps))``: where a material is far below the reference, its mapped value is about ``rho /
rho_ref``, nearly 0, and a mapped error of that size decodes the material black while the
cosine-weighted mapped loss and the renders hardly see it. The 7-D latent's corner
(``theta_h < 3``, ``theta_d > 62`` degrees, where the reference is 30 to 60 times the
diffuse materials) decoded 0.54% of the positive cells of the first 10 MERL test materials
below 1% of their value (``benchmarks/black_cells.py``). The floor is one-sided::

    mean(relu(1 - pred / m_f)^2),   m_f = the mapped value of f rho

0 wherever the decoded value is at least ``f`` times the material's, so it leaves the rest
of the fit alone.

Examples
--------
>>> import torch
>>> from brdfkit.hypernet.mapping import EPS, to_mapped
>>> rho, ref = torch.tensor([1.0]), torch.tensor([60.0])
>>> zero = EPS / (ref + EPS)
>>> target = to_mapped(rho, ref)
>>> float(floor_loss(target, target, zero, 0.1))                    # the material itself
0.0
>>> round(float(floor_loss(to_mapped(0.01 * rho, ref), target, zero, 0.1)), 3)   # 1%: costs
0.778
"""

from __future__ import annotations

import numpy as np

from brdfkit.errors import InputError

__all__ = ["FLOOR_REGION", "LOW_RATIO", "floor_loss", "floor_data", "low_ratio_cells"]

FLOOR_REGION = (4.0, 55.0)
"""``(theta_h below, theta_d above)`` in degrees: the near-specular grazing cells that
:attr:`brdfkit.hypernet.tuning.TuneOptions.floor_weight`'s loss draws on besides its
uniform cells, around the 7-D latent's black corner (``theta_h < 3``, ``theta_d > 62``
degrees; ``benchmarks/black_cells.py``).
There the reference (the training set's median) is 30 to 60 times the material, so the
mapped value of the material is about ``rho / rho_ref`` (0.02), and a mapped error of that
size, which neither the cosine-weighted mapped loss nor the renders see, decodes black."""


LOW_RATIO = 0.1
"""A cell where a material is below this share of the reference, ``(rho + eps) / (rho_ref +
eps) < 0.1`` in some channel, is one :func:`low_ratio_cells` may draw: there its mapped
value is under 0.1, and the mapped loss sees a black decode as an error of that size."""


def floor_loss(pred, target, zero, ratio: float):
    """``mean(relu(1 - pred / m_f)^2)``: ``m_f`` the mapped value of ``ratio`` times the
    material's value, from its mapped value ``target`` and what the mapping's log takes
    of a value of 0, ``zero = eps / (rho_ref + eps)`` (:mod:`brdfkit.hypernet.mapping`)::

        m_f = ln(1 + ratio (rho + eps) / (rho_ref + eps) + (1 - ratio) eps / (rho_ref + eps))

    ``m_f > 0`` everywhere, so the quotient is defined; the loss is 0 wherever the decoded
    value is at least ``ratio`` times the material's."""
    import torch

    m_f = torch.log1p(ratio * torch.expm1(target) + (1.0 - ratio) * zero)
    return torch.mean(torch.relu(1.0 - pred / m_f) ** 2)


def floor_data(tset, dev):
    """``(positions, zero)`` of :func:`brdfkit.hypernet.tuning.tune`'s ratio floor: int64
    torch positions in ``tset.cells`` (a :class:`~brdfkit.hypernet.training.dataset.TrainingSet`)
    inside :data:`FLOOR_REGION`, and float32 ``(n_cells, 3)`` ``eps / (rho_ref + eps)`` at
    each cell (:func:`floor_loss`'s ``zero``)."""
    import torch

    from brdfkit.geometry import N_CELLS, N_PHI_D, N_THETA_D, N_THETA_H
    from brdfkit.hypernet.mapping import EPS

    cells = tset.cells
    ih, id_ = cells // (N_THETA_D * N_PHI_D), (cells // N_PHI_D) % N_THETA_D
    th = np.degrees((ih / N_THETA_H) ** 2 * (np.pi / 2))
    td = np.degrees(id_ / N_THETA_D * (np.pi / 2))
    pos = np.flatnonzero((th < FLOOR_REGION[0]) & (td > FLOOR_REGION[1]))
    if pos.size == 0:
        raise InputError("tune -O floor_weight: the training set has no cell in the near-specular grazing region")
    ref = np.asarray(tset.rho_ref, np.float64).reshape(N_CELLS, 3)[cells]
    zero = (EPS / (ref + EPS)).astype(np.float32)
    return torch.from_numpy(pos).to(dev), torch.from_numpy(zero).to(dev)


def low_ratio_cells(values, candidates: int, most: int, gen, dev):
    """int64 torch positions (at most ``most``) among ``candidates`` uniform positions in
    the training cells where one material, of mapped values ``values`` (float32
    ``(n_cells, 3)`` on ``dev``), is below :data:`LOW_RATIO` of the reference in some
    channel; drawn with the generator ``gen`` (the tune's, seeded by the step)."""
    import torch

    c = torch.randint(0, values.shape[0], (candidates,), generator=gen).to(dev)
    low = (torch.expm1(values[c]) < LOW_RATIO).any(dim=-1)
    return c[low][:most]
