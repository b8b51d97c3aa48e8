"""Property-based fuzzing of every file parser: random bytes and mutated valid files
raise nothing but brdfkit's own one-line errors naming the file (issue 6).

The suite runs ``BRDFKIT_FUZZ_EXAMPLES`` examples per parser (default 60);
``benchmarks/fuzz_parsers.py`` runs minutes per parser. ``test_samples.py`` has its own
CSV and MERL fuzzers (CSV-shaped text, full-size MERL payloads); these add mutations of
valid files and the other formats.
"""

from __future__ import annotations

import os

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from brdfkit.testing.fuzzing import PARSERS, check_parser, draw_input

EXAMPLES = int(os.environ.get("BRDFKIT_FUZZ_EXAMPLES", "60"))
# The suite draws the same examples on every run (a CI result depends on the code, not on
# the draw); BRDFKIT_FUZZ_RANDOM=1 draws new ones, to explore (as found the vast empty
# field of an RGL file, tests/test_bad_input_rgl.py).
RANDOM = bool(os.environ.get("BRDFKIT_FUZZ_RANDOM"))


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(PARSERS))
def test_fuzz_parser(name, tmp_path):
    parser = PARSERS[name]
    parser.seed()  # built once, outside the examples

    @settings(max_examples=EXAMPLES, deadline=None, database=None, derandomize=not RANDOM,
              suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
    @given(data=st.data())
    def run(data):
        check_parser(parser, draw_input(data, parser), str(tmp_path))

    run()
