"""Acquisition: which measurements a material gets, and where a lab should measure.

* :mod:`~brdfkit.acquisition.sampling`: sample sets drawn from a table
  (:func:`~brdfkit.acquisition.sampling.draw_samples`) or measured at given directions
  (:func:`~brdfkit.acquisition.sampling.measure_samples`).
* :mod:`~brdfkit.acquisition.planning`: ``brdfkit plan``:
  :func:`~brdfkit.acquisition.planning.plan_directions`, the fit a plan is for, the
  condition number of a plan.
* :mod:`~brdfkit.acquisition.designs`: the designs by name
  (:data:`~brdfkit.acquisition.designs.DESIGNS`: ``nielsen``, ``render``, ``uniform``).
* :mod:`~brdfkit.acquisition.optimal_design`: the ``render`` design's criterion, the
  expected render error of the fit under the basis's prior (it plans; it renders nothing
  itself but reads the render-aligned error's pairs).
* :mod:`~brdfkit.acquisition.rounds`: measuring in rounds (``brdfkit plan --given``): the
  fit's posterior after the samples so far, the render design from it and at this
  material's estimate.
* :mod:`~brdfkit.acquisition.protocol`: the benchmarks' one sampling protocol.

May import: the ground floor, :mod:`brdfkit.geometry`, :mod:`brdfkit.io`,
:mod:`brdfkit.models`, :mod:`brdfkit.render` (the screen of the render design),
:mod:`brdfkit.prior` (the learnt prior's fit and sample rows, for a plan given samples) and
:mod:`brdfkit.methods` (the PCA bases and learnt priors planned for).
"""
