"""Evaluation: how far a reconstruction is from its reference.

* :mod:`~brdfkit.evaluation.metrics`: BRDF-space and image errors (PSNR, Delta E 2000
  from colour-science, SSIM), and :func:`~brdfkit.evaluation.metrics.score`, which
  ``brdfkit metrics``, ``compare`` and ``bench`` all call.
* :mod:`~brdfkit.evaluation.comparison`: files against files (``brdfkit metrics``): the
  reading and rendering of each input once, folders matched by name.
* :mod:`~brdfkit.evaluation.holdout`: held-out error on measurements (``brdfkit
  validate``): a fraction of a sample file held out, the reconstruction from the rest
  scored at it; a BRDF file scored at a sample file's directions.

May import: everything below it (the ground floor, geometry, io, render, the methods'
registry, :mod:`brdfkit.files` and, through it, the hypernetwork). colour-science is imported inside the functions that
need it.
"""
