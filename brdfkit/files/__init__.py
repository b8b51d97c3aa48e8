"""BRDF files of any type, opened by one loader: MERL tables, RGL ``.bsdf`` files and
embeddings (``.emb``), as dense tables or as renderable BRDFs, converted, and rendered.

* :mod:`~brdfkit.files.brdf_file`: a file's type, :func:`~brdfkit.files.brdf_file.read_table`,
  :func:`~brdfkit.files.brdf_file.load_brdf`, :func:`~brdfkit.files.brdf_file.convert`, and
  the decoders ``.emb`` files need, loaded once (it registers the loader the Mitsuba
  plugin opens a scene's files with);
* :mod:`~brdfkit.files.render_file`: BRDF files rendered, in the reference scene, a
  judged scene or a Mitsuba scene (``brdfkit render``, ``brdfkit metrics``).

May import: everything below it (the ground floor, :mod:`brdfkit.geometry`,
:mod:`brdfkit.io`, :mod:`brdfkit.models`, :mod:`brdfkit.render`, the model packages and
:mod:`brdfkit.embeddings`); torch only for an embedding or a render.
"""
