"""The learnt prior of a PCA basis: a set encoder reads sparse samples and gives the prior
mean of the basis's coefficients, around which they are fitted in closed form
(``brdfkit sparse --method prior``, :mod:`brdfkit.methods.prior`;
``docs/notes/generalisation.md`` says why it is not the paper's decoder); and the
correction of its fits, a hypernetwork residual of the basis trained on them, through
which ``brdfkit sparse`` decodes them by default (:mod:`brdfkit.methods.residual`).

* :mod:`brdfkit.prior.model`: the network and the closed-form fit
  (:class:`~brdfkit.prior.model.PriorModel`, :func:`~brdfkit.prior.model.solve`); a
  reconstruction evaluates both in NumPy (:class:`~brdfkit.prior.model.PriorWeights`,
  no torch), the training in torch;
* :mod:`~brdfkit.prior.fit`: its training, ``brdfkit fit --method prior``;
* :mod:`~brdfkit.prior.training_data`: what the training fits on (the basis, the cells,
  the held-out fold bases, the tensors on the device);
* :mod:`~brdfkit.prior.prior_file`: its file (format ``brdfkit-prior``), which holds or
  names the PCA basis (:mod:`brdfkit.basis`);
* :mod:`~brdfkit.prior.correction`: the correction's training, ``brdfkit fit --method
  correction`` (a residual file, :mod:`brdfkit.residual`);
* :mod:`~brdfkit.prior.corrected`: a sparse fit decoded through the basis plus the
  correction, kept where held-out samples say it helps.

May import: the ground floor, :mod:`brdfkit.geometry`, :mod:`brdfkit.io`,
:mod:`brdfkit.models`, :mod:`brdfkit.render`, :mod:`brdfkit.basis` and
:mod:`brdfkit.residual` (the correction is a residual network).
"""
