"""The sampling protocol of the benchmarks: which N samples of a material draw ``d`` is.

``brdfkit bench`` (``brdfkit.bench.worker``) and ``benchmarks/eval_sparse.py`` take
their samples from :meth:`SamplingProtocol.samples`, with the same arguments (the table,
the material's name, ``N``, the draw index), so that their figures for the same
material, ``N`` and draw come from the same samples (``docs/bench.md``, "Sampling").

============ ==================================================================
sampling     the samples of draw ``d`` of ``N`` samples of material ``name``
============ ==================================================================
``uniform``  :func:`brdfkit.acquisition.sampling.draw_samples` (uniform over the Rusinkiewicz
             angles, each draw its cell's value) seeded by
             :func:`draw_seed` ``(d, N, name)``: another draw for every draw
             index, ``N`` and material, the same for every method
``planned``  the table measured (:func:`brdfkit.acquisition.sampling.measure_samples`) at
             :func:`brdfkit.acquisition.planning.plan_directions` ``(basis, N, seed=d)``: the
             same directions for every material, as a lab plans once and measures
             every material there; the draw index seeds the design's random
             choices, so each draw is another plan of the same design
============ ==================================================================
"""

from __future__ import annotations

import zlib

import numpy as np

from brdfkit.errors import InputError

__all__ = ["SAMPLINGS", "SamplingProtocol", "draw_seed"]

SAMPLINGS = ("uniform", "planned")
"""The samplings of :class:`SamplingProtocol`, by name."""


def draw_seed(draw: int, n: int, name: str) -> int:
    """Seed of the uniform draw of ``n`` samples of material ``name`` for draw index
    ``draw``: distinct per (draw, N, material), the same for every method (a
    :class:`numpy.random.SeedSequence` of the three, the name by its CRC-32)."""
    return int(np.random.SeedSequence([int(draw), int(n), zlib.crc32(name.encode())]).generate_state(1)[0])


class SamplingProtocol:
    """One sampling of the benchmarks.

    Parameters
    ----------
    sampling
        A name of :data:`SAMPLINGS`.
    basis
        ``planned``: the fit to plan for, as :func:`brdfkit.acquisition.planning.plan_target`
        takes it (a built-in name, a basis or learnt-prior file, an
        :class:`~brdfkit.basis.PcaBasis`); loaded once. ``uniform``: ``None``.
    design
        ``planned``: the design (:data:`brdfkit.acquisition.designs.DESIGNS`).

    Notes
    -----
    The plan of each ``(N, draw)`` is made once and kept (a second or so each).
    """

    def __init__(self, sampling: str = "uniform", basis=None, design: str | None = None):
        from brdfkit.acquisition.planning import DEFAULT_DESIGN, plan_target
        from brdfkit.acquisition.designs import DESIGNS

        if sampling not in SAMPLINGS:
            raise InputError(f"unknown sampling {sampling!r}; known: {', '.join(SAMPLINGS)}")
        self.sampling = sampling
        self.design = design or DEFAULT_DESIGN
        self.basis, self.basis_label = None, None
        self._plans = {}
        if sampling == "uniform":
            if basis is not None or design is not None:
                raise InputError("uniform sampling takes no basis and no design")
            return
        if self.design not in DESIGNS:
            raise InputError(f"unknown design {self.design!r}; known: {', '.join(DESIGNS)}")
        if basis is None:
            raise InputError("planned sampling needs the PCA basis to plan for")
        self._target = plan_target(basis)
        self.basis, self.basis_label = self._target[:2]

    def plan(self, n: int, draw: int):
        """The :class:`~brdfkit.acquisition.planning.Plan` of ``n`` directions for draw ``draw``
        (``planned`` only)."""
        from brdfkit.acquisition.planning import plan_directions

        key = (int(n), int(draw))
        if key not in self._plans:
            self._plans[key] = plan_directions(self._target, int(n), design=self.design, seed=int(draw))
        return self._plans[key]

    def samples(self, table, name: str, n: int, draw: int):
        """The samples of draw ``draw`` of ``n`` samples of material ``name``.

        Parameters
        ----------
        table
            The material's ``(90, 90, 180, 3)`` table, 1/sr, NaN where not measured.
        name
            Its name (the file's stem): the uniform draw depends on it.
        n, draw
            The number of samples and the draw index (``0, 1, ...``).

        Returns
        -------
        tuple
            ``(SampleSet, record)``: ``record`` says how the samples were made, for the
            benchmark's records: ``sampling``, then ``sample_seed`` (uniform) or
            ``design``, ``plan_seed`` and ``condition_number`` (planned), and
            ``samples_digest`` (:meth:`~brdfkit.io.samples.SampleSet.digest`).
        """
        from brdfkit.acquisition.sampling import draw_samples, measure_samples

        if self.sampling == "uniform":
            seed = draw_seed(draw, n, name)
            samples = draw_samples(table, int(n), seed=seed, source=name)
            info = {"sampling": "uniform", "sample_seed": seed}
        else:
            plan = self.plan(n, draw)
            samples = measure_samples(table, plan.directions, source=name)
            info = {"sampling": "planned", "design": plan.design, "plan_seed": plan.seed,
                    "condition_number": plan.condition_number}
        info["samples_digest"] = samples.digest()
        return samples, info
