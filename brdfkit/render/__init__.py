"""Rendering: the reference scene (deterministic quadrature) and a Mitsuba 3 plugin.

Modules, one concept each:

* :mod:`.scene`: the reference scene's constants (sphere, orthographic camera, resolution,
  samples, quadrature settings);
* :mod:`.envmap`: the procedural HDR environment map;
* :mod:`.brdf`: BRDFs a renderer can evaluate (dense tables, neural BRDFs) and
  :func:`~.brdf.load_brdf`;
* :mod:`.quadrature`: the noise-free reference renderer (torch, no path tracing);
* :mod:`.mitsuba_plugin`: the ``brdfkit`` BSDF for Mitsuba 3 and path-traced renders;
* :mod:`.image`: EXR and PNG files.

Nothing here is imported by ``import brdfkit``; torch and Mitsuba load only when used.
"""
