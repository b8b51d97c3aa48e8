"""The PCA basis of Nielsen, Jensen and Ramamoorthi 2015 ("On Optimal, Minimal BRDF
Sampling for Reflectance Acquisition", SIGGRAPH Asia): a linear basis of log-mapped
measured BRDFs, and its fit to sparse samples by regularised least squares.

What is mapped
--------------
Each training table is cosine weighted and log-relative mapped, following the authors'
published code (``MapBRDF`` of brdf.compute.dtu.dk)::

    x    = rho * w,                w = cos(theta_i) cos(theta_o)
    x'   = ln((x + eps) / (x_ref + eps)),   eps = 0.001

with ``x_ref`` the per-cell median of the cosine-weighted training values (over every
material *and* channel, see below), in one function and its inverse
(:mod:`brdfkit.basis.mapping`). This is deliberately not
:func:`brdfkit.hypernet.mapping.to_mapped`, the hypernetwork paper's variant
``ln((rho + 0.002) / (rho_ref + 0.002) + 1)``: its ``+ 1`` flattens every value below
the reference towards 0, which throws away the dark half of the data a linear basis has
to model. The inverse is ``rho = ((exp(x') (x_ref + eps) - eps) / w`` passed through a
softplus of scale ``0.01 eps``, so that it never crosses zero
(:func:`brdfkit.basis.mapping.from_mapped`).

A basis may bound the weight from below, ``w = max(cos_i cos_o, w_floor)`` (``brdfkit
fit --method basis -O w_floor=W``; Nielsen's mapping is ``w_floor = 0``). Why: ``eps`` is a
floor of ``eps / w`` in BRDF units, which grows without bound towards grazing angles
(``w`` about 5e-3 at ``theta_h = 86 deg``: 0.2 /sr), so there every value of a dark or
diffuse material maps to nearly the same ``x'``; the basis cannot tell them apart, and the
inverse turns a small error of ``x'`` into 0 (``docs/notes/generalisation.md`` measured reconstructions of 0
where the data hold 4e-3 to 1e-2). The floor caps it at ``eps / w_floor``
(``docs/notes/generalisation.md`` measures it on renders). Cells on the horizon (``cos_i
cos_o = 0``) stay outside the basis.

Channels
--------
As in Nielsen et al., the three colour channels of a material are three separate
observations of one shared basis: ``M`` training materials give ``3 M`` vectors (so the
reference is one value per cell, the median over all ``3 M``). A sample set is fitted
channel by channel with the same basis.

Basis
-----
PCA over the cells measured by at least one training table (:mod:`brdfkit.basis.fit`), ``K``
components kept; the basis is stored in its own file (:mod:`.basis_file`).

Reconstruction
--------------
The mean, components and reference are interpolated trilinearly at each sample's angles
(:func:`brdfkit.geometry.trilinear.lookup_trilinear`; a sample on a cell's own angles reads that
cell exactly), the sample is mapped with its exact ``w``, and the coefficients solve::

    min_z || A diag(sigma) z - b ||^2 + lam ||z||^2,      c = sigma * z

with ``A`` the components at the samples, ``b`` the mapped samples minus the mean and
``sigma_k`` the standard deviation of the training coefficients of component ``k``: a
ridge on coefficients measured in training standard deviations, i.e. a Gaussian
regulariser fitted to the training set (Nielsen et al. regularise the singular-value-scaled
components with one fixed ``eta`` in the same way). ``lam`` is :data:`DEFAULT_LAMBDA`
unless given (see ``docs/baselines.md`` for how it was chosen).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from brdfkit.basis.mapping import EPS, FLOOR, NIELSEN, LogMapping
from brdfkit.errors import InputError
from brdfkit.geometry import GRID_SHAPE, N_CELLS, grid_cosine_weight, io_from_half_diff
from brdfkit.geometry.trilinear import lookup_trilinear

__all__ = ["PcaBasis", "EPS", "DEFAULT_LAMBDA", "DEFAULT_COMPONENTS", "cosine_weight"]

DEFAULT_COMPONENTS = 8
DEFAULT_LAMBDA = 0.1
DECODE_PIECE = 1 << 17
"""Cells of one piece of a dense decode's inverse mapping (pieces run on
:func:`brdfkit.runtime.thread_map`'s threads)."""


def cosine_weight(theta_h, theta_d, phi_d) -> np.ndarray:
    """Nielsen's cosine weight ``max(cos theta_i, 0) * max(cos theta_o, 0)`` at
    Rusinkiewicz angles (radians, broadcastable); float64 of the broadcast shape."""
    wi, wo = io_from_half_diff(theta_h, theta_d, phi_d)
    return np.clip(wi[..., 2], 0.0, None) * np.clip(wo[..., 2], 0.0, None)


@dataclasses.dataclass
class PcaBasis:
    """A PCA basis of cosine-weighted, log-mapped BRDF tables.

    Attributes
    ----------
    cells
        int64 ``(P,)``, sorted flat MERL indices of the cells the basis covers.
    reference
        float32 ``(P,)``, per-cell median of the cosine-weighted training values.
    mean
        float32 ``(P,)``, mean of the mapped training vectors.
    components
        float32 ``(K, P)``, orthonormal principal directions, strongest first.
    sigma
        float32 ``(K,)``, standard deviation of the training coefficients along each
        component.
    materials
        Names of the training materials.
    w_floor
        Lower bound of the mapping's cosine weight (module docstring; 0: Nielsen's).
    mapping
        The log mapping (:class:`~brdfkit.basis.mapping.LogMapping`: Nielsen's, or one
        that resolves the grazing cells).
    """

    cells: np.ndarray
    reference: np.ndarray
    mean: np.ndarray
    components: np.ndarray
    sigma: np.ndarray
    materials: list = dataclasses.field(default_factory=list)
    w_floor: float = 0.0
    mapping: LogMapping = NIELSEN
    _dense: np.ndarray | None = dataclasses.field(default=None, repr=False, compare=False)
    _rows: object = dataclasses.field(default=None, repr=False, compare=False)
    _compact: object = dataclasses.field(default=None, repr=False, compare=False)

    @classmethod
    def deferred(cls, cells, reference, mean, rows, sigma, materials=(), w_floor: float = 0.0,
                 compact=None, mapping: LogMapping = NIELSEN) -> "PcaBasis":
        """A basis whose components are restored from compact storage when first used:
        ``rows(k)`` gives the ``k`` leading ones, float32 ``(k, P)`` (:meth:`leading`
        restores only those; :attr:`components` all of them). ``compact``: the
        :class:`~brdfkit.basis.storage.Compact` storage they come from, when there is one:
        :meth:`decode`, :meth:`decode_at` and :meth:`project` then work on it without
        restoring the components at every cell."""
        basis = cls(cells, reference, mean, None, sigma, list(materials), w_floor, mapping, _rows=rows,
                    _compact=compact)
        del basis.__dict__["components"]  # restored by __getattr__ on first use
        return basis

    def __getattr__(self, name):
        d = self.__dict__
        if name == "components" and d.get("_rows") is not None:
            d["components"] = d["_rows"](int(d["sigma"].shape[0]))
            return d["components"]
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    @property
    def n_components(self) -> int:
        return int(self.sigma.shape[0])

    def leading(self, k: int) -> "PcaBasis":
        """The basis of the ``k`` strongest components. PCA bases are nested: this is the
        basis a fit with ``k`` components to the same tables gives (the same mean,
        reference and components, to float precision)."""
        if not 1 <= k <= self.n_components:
            raise InputError(f"a basis of {self.n_components} components has no {k} leading ones")
        # The leading bases made are kept (a few of a few sizes): an encode asks for the
        # same one several times, and a compact basis restores its rows for each.
        made = self.__dict__.setdefault("_leading", {})
        if k not in made:
            if len(made) >= 4:
                made.clear()
            # A compact basis's leading bases are compact too, whether or not its full
            # components were restored by an earlier use: the arithmetic, and so the
            # bytes, of a table's encode must not depend on what the process did before.
            if self._rows is not None:
                made[k] = PcaBasis.deferred(self.cells, self.reference, self.mean, self._rows, self.sigma[:k],
                                            self.materials, self.w_floor, self._compact, self.mapping)
            else:
                made[k] = dataclasses.replace(self, components=self.components[:k], sigma=self.sigma[:k], _dense=None,
                                              _rows=None)
        return made[k]

    def baseline(self) -> "PcaBasis":
        """The basis of the IPCA baseline: Nielsen et al.'s :data:`DEFAULT_COMPONENTS`
        leading components when this basis has more (the built-ins' basis has the 32 their
        learnt priors fit), else this basis."""
        return self.leading(DEFAULT_COMPONENTS) if self.n_components > DEFAULT_COMPONENTS else self

    def weight(self, theta_h, theta_d, phi_d) -> np.ndarray:
        """The mapping's weight at Rusinkiewicz angles (radians): :func:`cosine_weight`
        raised to :attr:`w_floor` where it is positive (0 on and below the horizon)."""
        w = cosine_weight(theta_h, theta_d, phi_d)
        return np.where(w > 0, np.maximum(w, self.w_floor), 0.0)

    def cell_weight(self, cells=None) -> np.ndarray:
        """:meth:`weight` at the cells' own angles (flat MERL indices; default the basis's
        cells), float64."""
        w = grid_cosine_weight()[self.cells if cells is None else cells].astype(np.float64)
        return np.where(w > 0, np.maximum(w, self.w_floor), 0.0)

    def lookup_table(self) -> np.ndarray:
        """Dense ``(N_CELLS, K + 2)`` float32 ``[reference, mean, components...]``, NaN
        off the basis cells, built once for trilinear lookups."""
        if self._dense is None:
            dense = np.full((N_CELLS, self.n_components + 2), np.nan, dtype=np.float32)
            dense[self.cells, 0] = self.reference
            dense[self.cells, 1] = self.mean
            dense[self.cells, 2:] = self.components.T
            self._dense = dense
        return self._dense

    def coefficients(self, samples, lam: float | None = None) -> np.ndarray:
        """Fit the basis to a sample set: coefficients ``(K, 3)``, one column per channel.

        Parameters
        ----------
        samples
            :class:`brdfkit.io.samples.SampleSet`; BRDF values in 1/sr.
        lam
            Ridge weight (``>= 0``; default :data:`DEFAULT_LAMBDA`), on coefficients in
            units of the training standard deviations.
        """
        lam = DEFAULT_LAMBDA if lam is None else float(lam)
        if not lam >= 0 or not np.isfinite(lam):
            raise InputError(f"ridge lambda must be a finite number >= 0, got {lam}")
        if len(samples) == 0:
            raise InputError(f"{samples.source or 'samples'}: no samples to fit")
        at = lookup_trilinear(self.lookup_table().reshape(GRID_SHAPE + (-1,)),
                              samples.theta_h, samples.theta_d, samples.phi_d)
        w = self.weight(samples.theta_h, samples.theta_d, samples.phi_d)
        # Samples no basis cell reaches, with no weight (on the horizon), or unmeasured
        # (NaN, MERL's convention) say nothing.
        measured = samples.measured()
        use = np.isfinite(at).all(axis=1) & (w > 0) & measured
        if not use.any():
            what = ("no sample has a measured (non-NaN) value" if not measured.any()
                    else "no sample lies on a cell the PCA basis covers")
            raise InputError(f"{samples.source or 'samples'}: {what}")
        at, w = at[use], w[use]
        ref, mean, comp = at[:, 0], at[:, 1], at[:, 2:]
        b = self.mapping.to_mapped(np.asarray(samples.rgb, np.float64)[use], w[:, None], ref[:, None]) - mean[:, None]
        a = comp * self.sigma.astype(np.float64)[None, :]
        lhs = a.T @ a + lam * np.eye(self.n_components)
        z = np.linalg.lstsq(lhs, a.T @ b, rcond=None)[0] if lam == 0 else np.linalg.solve(lhs, a.T @ b)
        return z * self.sigma.astype(np.float64)[:, None]

    def decode(self, coefficients: np.ndarray, floor: float = FLOOR) -> np.ndarray:
        """Dense table from coefficients ``(K, 3)``: float64 ``(90, 90, 180, 3)``, 1/sr,
        ``> 0`` (``>= 0`` with ``floor=0``: :func:`brdfkit.basis.mapping.from_mapped`),
        NaN off the basis cells."""
        return self.decode_mapped(self.mapped_values(coefficients), floor)

    def mapped_values(self, coefficients: np.ndarray) -> np.ndarray:
        """The mapped values ``mean + U c`` at the basis's cells of coefficients
        ``(K, 3)``: float32 ``(P, 3)`` (from compact storage without restoring the
        components, when the basis has it)."""
        if self._compact is not None:
            return self._compact.mapped(coefficients)
        return self.mean[:, None] + self.components.T @ np.asarray(coefficients, np.float32)

    def decode_at(self, coefficients: np.ndarray, cells, floor: float = FLOOR) -> tuple:
        """:meth:`decode` at some cells only: ``(at, values)``, the flat MERL ``cells``
        the basis covers (int64, ascending) and the BRDF there, float64 ``(n, 3)``, 1/sr
        (what a render that reaches only those cells needs)."""
        cells = np.unique(np.asarray(cells, np.int64))
        pos = np.searchsorted(self.cells, cells).clip(0, self.cells.size - 1)
        hit = self.cells[pos] == cells
        pos, at = pos[hit], cells[hit]
        mapped = self.mean[pos, None] + self.rows_at(pos).T @ np.asarray(coefficients, np.float32)
        ref = self.reference[pos, None].astype(np.float64)
        return at, self.mapping.from_mapped(mapped, self.cell_weight(at)[:, None], ref, floor)

    def rows_at(self, positions) -> np.ndarray:
        """The components at some of the basis's cells (positions among :attr:`cells`),
        float32 ``(K, n)``."""
        if self._compact is not None:
            return self._compact.rows_at(self.n_components, positions)
        return self.components[:, positions]

    def decode_mapped(self, mapped: np.ndarray, floor: float = FLOOR) -> np.ndarray:
        """Dense table from mapped values at the basis's cells ``(P, 3)`` (the mean
        included): float64 ``(90, 90, 180, 3)``, 1/sr, NaN off the basis cells
        (:func:`brdfkit.basis.mapping.from_mapped`)."""
        from brdfkit.runtime import thread_map

        out = np.full((N_CELLS, 3), np.nan)
        weight = self.cell_weight()

        def piece(s):  # elementwise: fixed pieces of cells, the same bytes on any threads
            e = min(s + DECODE_PIECE, self.cells.size)
            out[self.cells[s:e]] = self.mapping.from_mapped(mapped[s:e], weight[s:e, None],
                                                            self.reference[s:e, None].astype(np.float64), floor)

        list(thread_map(piece, range(0, self.cells.size, DECODE_PIECE)))
        return out.reshape(GRID_SHAPE + (3,))

    def mapped_table(self, table: np.ndarray) -> np.ndarray:
        """A dense table's mapped values at the basis's cells, ``(P, 3)`` float64, NaN
        where the table is unmeasured (:func:`brdfkit.basis.mapping.to_mapped`)."""
        flat = np.asarray(table, np.float64).reshape(N_CELLS, 3)[self.cells]
        return self.mapping.to_mapped(flat, self.cell_weight()[:, None], self.reference[:, None].astype(np.float64))

    def reconstruct(self, samples, lam: float | None = None, floor: float = FLOOR) -> np.ndarray:
        """Dense table fitted to a sample set (see :meth:`coefficients`, :meth:`decode`)."""
        return self.decode(self.coefficients(samples, lam), floor)

    def project(self, table: np.ndarray) -> np.ndarray:
        """Least-squares coefficients ``(K, 3)`` of a dense table over all basis cells it
        measures (no regulariser): the best this basis can do for that material."""
        mapped = self.mapped_table(table)
        ok = np.isfinite(mapped).all(axis=1)
        if self._compact is not None:
            mapped -= self.mean[:, None]
            ata, atb = self._compact.normal_equations(self.n_components, mapped, None if ok.all() else ok)
            return np.linalg.solve(ata, atb)
        b = mapped[ok] - self.mean[ok, None]
        a = (self.components if ok.all() else self.components[:, ok]).astype(np.float64)
        # Normal equations (K x K): a tenth of lstsq's time over a million cells. Not
        # a @ b alone: a stored basis (int8, half phi_d) is orthonormal only to 1e-3.
        return np.linalg.solve(a @ a.T, a @ b)

