"""Run every performance benchmark of issue 7 and collect their JSON in one file.

Each benchmark runs in its own process (a fresh interpreter: import costs and caches
count as a user sees them), prints its table, and writes its JSON; this driver merges
them into ``--out`` (default ``perf-results.json``) with the machine, the load average
before and after each, and each one's wall time. Settings are sized to finish in under
10 minutes on the 2-core project machine under the load of two training runs; see
``docs/notes/performance.md`` for what each measures and the full-size settings.

Usage::

    python benchmarks/run.py [--out perf-results.json] [--only decode,encode,...]
                             [--ttq-minutes 1]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import common

HERE = os.path.dirname(os.path.abspath(__file__))


def plan(ttq_minutes):
    return [
        ("decode", ["decode.py", "--threads", "1,2", "--repeat", "5", "--multi-repeat", "2"]),
        ("encode", ["encode_bound.py", "--repeat", "20", "--cli-repeat", "2"]),
        ("train", ["train_throughput.py", "--repeat", "5"]),
        ("render", ["render.py", "--resolution", "256", "--threads", "2", "--repeat", "2", "--skip-mitsuba"]),
        ("render_mitsuba", ["render.py", "--resolution", "64", "--spp", "4"]),
        ("commands", ["commands.py", "--repeat", "2"]),
        ("memory", ["memory.py"]),
        ("time_to_quality", ["time_to_quality.py", "--minutes", str(ttq_minutes), "--materials", "10",
                             "--held-out", "2", "--checkpoint-minutes", "0.2"]),
    ]


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="perf-results.json")
    p.add_argument("--only", default="", help="comma-separated benchmark names")
    p.add_argument("--ttq-minutes", type=float, default=1.0)
    p.add_argument("--timeout", type=float, default=300, help="seconds per benchmark")
    args = p.parse_args(argv)
    only = {x for x in args.only.split(",") if x}
    results = {"machine": common.machine(), "benchmarks": {}}
    t_all = time.monotonic()
    with tempfile.TemporaryDirectory() as tmp:
        for name, cmd in plan(args.ttq_minutes):
            if only and name not in only:
                continue
            js = os.path.join(tmp, name + ".json")
            load_before = common.load_average()
            t0 = time.monotonic()
            try:
                r = subprocess.run([sys.executable, os.path.join(HERE, cmd[0]), *cmd[1:], "--json", js],
                                   timeout=args.timeout)
                rc = r.returncode
            except subprocess.TimeoutExpired:
                rc = "timeout"
            entry = {"returncode": rc, "wall_s": round(time.monotonic() - t0, 1),
                     "load_average_before": load_before, "load_average_after": common.load_average()}
            if os.path.exists(js):
                with open(js) as f:
                    entry["result"] = json.load(f)
            results["benchmarks"][name] = entry
            print(f"[run.py] {name}: exit {rc}, {entry['wall_s']} s, load {load_before} -> "
                  f"{entry['load_average_after']}", flush=True)
    results["total_wall_s"] = round(time.monotonic() - t_all, 1)
    from brdfkit.atomic import atomic_open

    with atomic_open(args.out, "w") as f:
        f.write(json.dumps(results, indent=1, sort_keys=True) + "\n")
    print(f"[run.py] all done in {results['total_wall_s']} s; results in {args.out}")
    failed = [n for n, e in results["benchmarks"].items() if e["returncode"] != 0]
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
