"""The PCA basis: a linear basis of log-mapped measured BRDFs (Nielsen, Jensen and
Ramamoorthi 2015), the core of brdfkit's compression and of its learnt prior.

A material is a point in the basis: ``K`` coefficients per colour channel, ``3 K``
numbers. ``brdfkit encode`` makes those numbers from a dense table (a *basis
embedding*), ``decode`` turns them back into a table, ``interpolate`` blends them, the
learnt prior (:mod:`brdfkit.prior`) fits them to sparse samples around a learnt
mean, and the IPCA baseline (:mod:`brdfkit.methods.ipca`) fits them by ridge regression.

One module per concept, in the order data flows:

* :mod:`~brdfkit.basis.model`: :class:`PcaBasis`, the mapping, the ridge fit to samples,
  the projection of a table and the closed-form decode;
* :mod:`~brdfkit.basis.fit`: the basis fitted to training tables (``brdfkit fit --method
  ipca``): :func:`fit_basis`, :func:`fit_basis_files`;
* :mod:`~brdfkit.basis.storage`: compact storage (float16, int8 blocks, every other
  ``phi_d`` cell);
* :mod:`~brdfkit.basis.basis_file`: the basis file (format ``brdfkit-basis``):
  :func:`save_basis`, :func:`load_basis`;
* :mod:`~brdfkit.basis.least_squares`: Levenberg-Marquardt, the one solver of every
  encode's small least-squares problems (the refinement on renders, a residual's fit
  through its correction);
* :mod:`~brdfkit.basis.refine_on_screen`: a table's coefficients refined on renders of
  the objective scenes (:mod:`brdfkit.render.objective`);
* :mod:`~brdfkit.basis.coefficients`: a table as a basis embedding and a basis embedding
  as a renderable BRDF (:func:`encode_coefficients`, :class:`BasisBRDF`).

May import: the ground floor, :mod:`brdfkit.geometry`, :mod:`brdfkit.io` and, for the
refinement on renders, :mod:`brdfkit.render`. Never :mod:`brdfkit.hypernet` (nor does
the hypernetwork import the basis): ``tests/test_layout.py`` checks both. Importing this
package loads NumPy only; torch loads when a refinement or a render runs.
"""

from __future__ import annotations

from brdfkit.basis.basis_file import (
    BASIS_FORMAT,
    BASIS_VERSION,
    basis_tensors,
    load_basis,
    read_basis,
    save_basis,
    storage_of,
)
from brdfkit.basis.coefficients import BasisBRDF, check_coefficients, encode_coefficients
from brdfkit.basis.fit import fit_basis, fit_basis_files
from brdfkit.basis.model import DEFAULT_COMPONENTS, DEFAULT_LAMBDA, EPS, PcaBasis, cosine_weight

__all__ = ["PcaBasis", "fit_basis", "fit_basis_files", "load_basis", "save_basis", "read_basis", "basis_tensors",
           "storage_of", "BASIS_FORMAT", "BASIS_VERSION", "EPS", "DEFAULT_LAMBDA", "DEFAULT_COMPONENTS",
           "cosine_weight", "BasisBRDF", "check_coefficients", "encode_coefficients"]
