"""Bad input through every command that takes it (issue 6, docs/errors.md).

Each case: exit code 2, exactly one line on stderr that names the input and the problem,
no traceback, no output file and no temporary file left behind. The library-level
checks of each reader live with the reader's tests (``test_merl.py``, ``test_samples.py``,
``test_embedding.py``, ``test_modelfile.py``); these run the readers as the commands
use them.
"""

from __future__ import annotations

import os
import time
import tracemalloc

import pytest

from brdfkit import samples as samples_mod
from brdfkit.errors import FormatError
from brdfkit.samples import read_samples


# --- a runaway CSV file --------------------------------------------------------------------

def test_ten_million_rows_refused_before_parsing(tmp_path):
    # A real 10^7-row file (short rows: 120 MB, written in ~0.3 s), not a patched limit
    # (test_samples.py::test_too_many_rows patches MAX_ROWS to test the boundary).
    # Regression: the row count was checked only after decoding and splitting the file
    # into 10^7 strings: 29 s and 2.1 GB for a 240 MB file. Now it is counted in the raw
    # bytes first.
    path = tmp_path / "huge.csv"
    row = b"0,0,0,0,0,0\n"
    with open(path, "wb") as f:
        f.write(b"theta_h,theta_d,phi_d,r,g,b\n")
        block = row * 100_000
        for _ in range(100):
            f.write(block)
    size = path.stat().st_size
    assert 10_000_000 > samples_mod.MAX_ROWS
    tracemalloc.start()
    try:
        t0 = time.perf_counter()
        with pytest.raises(FormatError, match=r": 10000000 sample rows, more than the limit of 5832000"):
            read_samples(path)
        seconds = time.perf_counter() - t0
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 1.5 * size, (peak, size)  # the bytes read, and small blocks
    assert seconds < 20, seconds


def test_row_count_guard_counts_only_value_lines(tmp_path, monkeypatch):
    # The raw-byte count (a lower bound: comment, blank and indented lines not counted)
    # must never refuse a file that is within the limit.
    monkeypatch.setattr(samples_mod, "MAX_ROWS", 3)
    path = tmp_path / "s.csv"
    path.write_bytes(b"# c\r\ntheta_h,theta_d,phi_d,r,g,b\r\n\r\n# x\n0.3,0.4,1.0,0.1,0.2,0.3\n\n"
                     b"  0.3,0.4,1.0,0.1,0.2,0.3\r0.3,0.4,1.0,0.1,0.2,0.3\n#\n\n")
    assert len(read_samples(path)) == 3
    path.write_bytes(b"theta_h,theta_d,phi_d,r,g,b\n" + b"0.3,0.4,1.0,0.1,0.2,0.3\r\n" * 4)
    with pytest.raises(FormatError, match="4 sample rows, more than the limit of 3"):
        read_samples(path)
