"""Files in and out: the formats brdfkit reads and writes, each checked on reading.

* :mod:`~brdfkit.io.merl`: MERL ``.binary`` tables (Matusik et al. 2003), read and written.
* :mod:`~brdfkit.io.rgl_bsdf`: RGL ``.bsdf`` files (Dupuy and Jakob 2018; Mitsuba 3,
  pbrt-v4), read, evaluated and written; its parts (the tensor-file container, the
  ``Marginal2D`` warps, the parameterization's fit) in :mod:`brdfkit.io.rgl`.
* :mod:`~brdfkit.io.csvfile`: numeric CSV files with a header, the reading and row
  refusals that sample sets and directions share.
* :mod:`~brdfkit.io.samples`: sample sets (:class:`~brdfkit.io.samples.SampleSet`) and
  their CSV files.
* :mod:`~brdfkit.io.directions`: measurement directions without values
  (:class:`~brdfkit.io.directions.DirectionSet`) and their CSV files.
* :mod:`~brdfkit.io.measurements`: measurements as instruments write them (angle
  conventions in radians or degrees, RGB or spectral values) checked into sample sets;
  :mod:`~brdfkit.io.pbrt_brdf`: pbrt-v2 / Cornell ``.brdf`` spectral samples;
  :mod:`~brdfkit.io.spectral`: spectra to linear sRGB (colour-science);
  :mod:`~brdfkit.io.sample_files`: any sample file by one reader (``read_sample_file``).
* :mod:`~brdfkit.io.embedding`: embedding files (``.emb``, JSON).
* :mod:`~brdfkit.io.tensorfile`: the one checked safetensors reader (network files,
  reference tables, PCA bases); never unpickles.
* :mod:`~brdfkit.io.folders`: folders of tables, material names, exclude lists.
* :mod:`~brdfkit.io.digest`: the sha256 of a file's bytes.

May import: the ground floor (``errors``, ``atomic``) and :mod:`brdfkit.geometry`;
numpy, safetensors inside the functions that read tensors, colour-science inside
:func:`brdfkit.io.rgl_bsdf.rgb_to_spectra` and :mod:`brdfkit.io.spectral`'s functions. No torch.
"""
