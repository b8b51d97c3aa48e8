"""The demos: the main job on built-in data, from a fresh install.

* :mod:`~brdfkit.demos.real_materials`: ``brdfkit demo``: real materials (the shipped
  NBRDF networks) through the built-in models: sparse reconstruction, compression,
  editing, a sheet; :mod:`~brdfkit.demos.real_outputs`: what it writes and the clock of its
  steps.
* :mod:`~brdfkit.demos.synthetic_training`: ``brdfkit demo --train``: a small model
  trained on synthetic GGX materials, then the same jobs.

May import: any library package (they sit just under the CLI).
"""
