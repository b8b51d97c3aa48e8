"""Materials brdfkit makes rather than reads: built-in data for the demos, tests and
stability checks.

* :mod:`~brdfkit.materials.synthetic`: analytic GGX materials (dielectrics, conductors)
  and the stiff cases (mirror-like peaks, black, white), as MERL tables;
  ``brdfkit.synthetic`` names it too.
* :mod:`~brdfkit.materials.nbrdf_networks`: the published NBRDF networks shipped in
  ``brdfkit/data/`` (Sztrajman et al. 2021), decoded into dense MERL tables: the real
  materials of ``brdfkit demo``, one of them written by ``brdfkit material NAME``
  (:func:`~brdfkit.materials.nbrdf_networks.write_material`).

May import: the ground floor, :mod:`brdfkit.geometry`, :mod:`brdfkit.io`; torch inside
:func:`~brdfkit.materials.nbrdf_networks.nbrdf_table` only.
"""
