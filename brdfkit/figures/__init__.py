"""Figures: PNG plots and sheets (matplotlib, imported inside the functions).

* :mod:`~brdfkit.figures.canvas`: what every sheet shares: the pyplot import, bare axes,
  a render shown as displayed, the PNG written atomically.
* :mod:`~brdfkit.figures.brdf_plot`: ``brdfkit plot``: in-plane lobes and
  ``theta_h`` / ``theta_d`` slices, as BRDF Explorer shows them.
* :mod:`~brdfkit.figures.comparison_sheet`: ``brdfkit compare``: renders beside their
  reference with false-colour error images.
* :mod:`~brdfkit.figures.interpolation_strip`: ``brdfkit interpolate --sheet``: the
  material-editing strip.

May import: everything below it (evaluation, render, :mod:`brdfkit.files`, the hypernetwork, the
embeddings of :mod:`brdfkit.embeddings`).
"""
