"""Mitsuba 3 with brdfkit's BRDFs: the ``brdfkit`` BSDF plugin and path-traced scenes.

* :mod:`~brdfkit.render.mitsuba3.loader`: finding a libLLVM that Dr.Jit accepts, and
  importing Mitsuba with the ``llvm_ad_rgb`` variant (the plugin registered by name).
* :mod:`~brdfkit.render.mitsuba3.bsdf`: the ``brdfkit`` BSDF: evaluation through a BRDF's
  ``eval_dirs``, a mixture for sampling, in-memory sources.
* :mod:`~brdfkit.render.mitsuba3.scenes`: the reference scene as a Mitsuba scene, a
  user's XML scene with one BSDF replaced, renders in passes.

Mitsuba is imported only inside these modules' functions. May import: the ground floor,
:mod:`brdfkit.geometry` and :mod:`brdfkit.render`. A BRDF file a scene names is opened by
the loader :mod:`brdfkit.files.brdf_file` registers from above
(:func:`~brdfkit.render.mitsuba3.bsdf.set_file_opener`).
"""
