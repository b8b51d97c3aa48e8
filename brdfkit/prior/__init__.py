"""The learnt prior of a PCA basis: a set encoder reads sparse samples and gives the prior
mean of the basis's coefficients, around which they are fitted in closed form
(``brdfkit sparse --method prior``, :mod:`brdfkit.methods.prior`, its default with the
built-ins; ``docs/notes/generalisation.md`` says why it is not the paper's decoder).

* :mod:`brdfkit.prior.model`: the network and the closed-form fit
  (:class:`~brdfkit.prior.model.PriorModel`, :func:`~brdfkit.prior.model.solve`); a
  reconstruction evaluates both in NumPy (:class:`~brdfkit.prior.model.PriorWeights`,
  no torch), the training in torch;
* :mod:`~brdfkit.prior.fit`: its training, ``brdfkit fit --method prior``;
* :mod:`~brdfkit.prior.training_data`: what the training fits on (the basis, the cells,
  the held-out fold bases, the tensors on the device);
* :mod:`~brdfkit.prior.prior_file`: its file (format ``brdfkit-prior``), which holds or
  names the PCA basis (:mod:`brdfkit.basis`).

A correction of its fits (``fit --method correction``, ``sparse --method residual``) left on
2026-12-01; ``benchmarks/studies/corrected_prior.py`` keeps what its study still runs.

May import: the ground floor, :mod:`brdfkit.geometry`, :mod:`brdfkit.io`,
:mod:`brdfkit.models`, :mod:`brdfkit.render` and :mod:`brdfkit.basis`.
"""
