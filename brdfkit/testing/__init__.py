"""Tools for testing brdfkit itself.

* :mod:`~brdfkit.testing.fuzzing`: the fuzzer of every file parser (the tests and
  ``benchmarks/fuzz_parsers.py``; needs hypothesis).
* :mod:`~brdfkit.testing.mitsuba_measured`: Mitsuba 3's own ``measured`` BSDF on a
  ``.bsdf`` file, in a child process (scalar variants): the judge of the files brdfkit
  writes (``tests/test_rgl_bsdf.py``, ``benchmarks/studies/rgl_roundtrip.py``).

May import: any library package.
"""
