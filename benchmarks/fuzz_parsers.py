"""A long fuzz run of every brdfkit file parser (issue 6; the suite runs a short one).

    python benchmarks/fuzz_parsers.py --minutes 3            # every parser, 3 minutes each
    python benchmarks/fuzz_parsers.py --minutes 1 load_model read_embedding

Same inputs as ``tests/test_fuzz.py`` (:mod:`brdfkit.testing.fuzzing`): random bytes and
mutated valid files. Only brdfkit's own one-line errors may escape; the first other
outcome (another exception, a multi-line message, anything printed by a C library or a
warning, a parse over 30 s) is printed with hypothesis' shrunk example, and the exit code
is 1. Prints per parser: examples run, how many were accepted as valid and how many
refused, and the slowest parse.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
import traceback

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from brdfkit.testing.fuzzing import PARSERS, check_parser, draw_input


def fuzz(name: str, seconds: float, folder: str, chunk: int = 100) -> tuple[dict, str | None]:
    """Runs of ``chunk`` examples (each run a fresh random seed) until ``seconds`` pass."""
    parser = PARSERS[name]
    parser.seed()
    stats = {"examples": 0, "accepted": 0, "refused": 0, "slowest_s": 0.0}
    deadline = time.monotonic() + seconds

    @settings(max_examples=chunk, deadline=None, database=None, print_blob=True,
              suppress_health_check=list(HealthCheck))
    @given(data=st.data())
    def run(data):
        accepted, seconds = check_parser(parser, draw_input(data, parser), folder)
        stats["accepted" if accepted else "refused"] += 1
        stats["slowest_s"] = max(stats["slowest_s"], seconds)
        stats["examples"] += 1

    while time.monotonic() < deadline:
        try:
            run()
        except Exception:  # hypothesis re-raises the shrunk failing example
            return stats, traceback.format_exc()
    return stats, None


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("parsers", nargs="*", help=f"which (default all): {', '.join(sorted(PARSERS))}")
    ap.add_argument("--minutes", type=float, default=3.0, help="per parser (default 3)")
    args = ap.parse_args(argv)
    import torch

    torch.set_num_threads(1)
    names = args.parsers or sorted(PARSERS)
    unknown = [n for n in names if n not in PARSERS]
    if unknown:
        ap.error(f"unknown parser(s) {unknown}; known: {sorted(PARSERS)}")
    status = 0
    print(f"{'parser':16s} {'minutes':>7s} {'examples':>9s} {'accepted':>9s} {'refused':>8s} {'slowest s':>10s}  result")
    for name in names:
        with tempfile.TemporaryDirectory(prefix=f"fuzz-{name}-") as folder:
            stats, failure = fuzz(name, args.minutes * 60.0, folder)
        result = "nothing found" if failure is None else "FAILED"
        print(f"{name:16s} {args.minutes:7.1f} {stats['examples']:9d} {stats['accepted']:9d} "
              f"{stats['refused']:8d} {stats['slowest_s']:10.2f}  {result}", flush=True)
        if failure:
            print(failure, file=sys.stderr)
            status = 1
    return status


if __name__ == "__main__":
    sys.exit(main())
