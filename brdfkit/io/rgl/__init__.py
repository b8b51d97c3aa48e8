"""The parts of the RGL ``.bsdf`` format (Dupuy and Jakob 2018) behind
:mod:`brdfkit.io.rgl_bsdf`.

* :mod:`~brdfkit.io.rgl.container`: Mitsuba's tensor file, the container (read and written).
* :mod:`~brdfkit.io.rgl.marginal`: the conditional 2D distributions the readers build from
  the fields (``Marginal2D``): interpolation, sampling warp and its inverse.
* :mod:`~brdfkit.io.rgl.fit`: the adaptive parameterization fitted to an isotropic BRDF
  (NDF by power iteration, projected area, visible normals, sample-space values).
* :mod:`~brdfkit.io.rgl.spectral`: spectra of RGB values for spectral files.

May import: the ground floor and numpy (and :mod:`brdfkit.geometry` through
:mod:`brdfkit.io.rgl_bsdf`).
"""
