"""A PCA basis plus a hypernetwork residual: the paper's idea (Gokbudak et al. 2024) where
a linear basis is weakest.

The ``K`` coefficients of one channel of a basis embedding (:mod:`brdfkit.basis`) are the
input of a hypernetwork that predicts the weights of a small hyponet over the cells'
Rusinkiewicz HD vectors; its output corrects the basis's mapped table. One network serves
every size it was trained for. ``docs/compression.md`` reports what it gains over the
basis alone and over a full-precision PCA of equal size, on materials it never saw.

* :mod:`~brdfkit.residual.network`: the network (torch for training, NumPy for decoding);
* :mod:`brdfkit.residual.model`: :class:`BasisResidual`, a basis and its residual, decoded;
* :mod:`~brdfkit.residual.residual_file`: its file (format ``brdfkit-residual``), which
  records the digest of the basis it corrects;
* :mod:`~brdfkit.residual.training`: ``brdfkit fit --method residual`` (seeded, resumable,
  DDP under ``torchrun``);
* :mod:`~brdfkit.residual.encoding`: a table as a residual embedding (projection, fit
  through the correction, refinement on renders, a choice per material);
* :mod:`~brdfkit.residual.brdf`: a residual embedding as a renderable BRDF.

May import: the ground floor, :mod:`brdfkit.geometry`, :mod:`brdfkit.io`,
:mod:`brdfkit.models`, :mod:`brdfkit.render` and :mod:`brdfkit.basis`; never
:mod:`brdfkit.hypernet` (``tests/test_layout.py``). Importing it loads NumPy only; decoding
loads no torch.
"""

from __future__ import annotations

from brdfkit.residual.model import BasisResidual
from brdfkit.residual.network import ResidualConfig
from brdfkit.residual.residual_file import RESIDUAL_FORMAT, load_residual, save_residual

__all__ = ["BasisResidual", "ResidualConfig", "RESIDUAL_FORMAT", "load_residual", "save_residual"]
