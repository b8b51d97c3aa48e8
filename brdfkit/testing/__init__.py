"""Tools for testing brdfkit itself.

* :mod:`~brdfkit.testing.fuzzing`: the fuzzer of every file parser (the tests and
  ``benchmarks/fuzz_parsers.py``; needs hypothesis).

May import: any library package.
"""
