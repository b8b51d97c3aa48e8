"""Everyday commands timed as a user runs them: whole process, start-up included.

Issue 14, items 1, 2 and 4. Each command runs in a fresh process (``brdfkit ...``, the
console script), best of ``--repeat``; then once more under ``python -X importtime`` for
its import time, the part of it that is torch, and whether torch was imported at all.
The inputs are made first and not timed: two synthetic MERL tables (``stiff-white``,
``stiff-grazing``), an untrained model of the paper's architecture, 400 samples of the
first table, two embeddings, and the two tables' reference-scene renders as EXR.

The goals of issue 14: ``render`` of a table (256 px reference scene) at most 2.5 s;
``metrics`` of two tables under 5 s; commands that do not need torch (``sample``,
``interpolate`` without ``--binary``, ``plot`` of tables, ``metrics`` of images) never
import it. The bound of the render itself (the BRDF evaluations alone) is measured by
``benchmarks/render.py`` in the same ``benchmarks/run.py`` run.

Usage::

    python benchmarks/commands.py [--repeat 3] [--json out.json]
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time

import common


def importtime(argv, env):
    """``(total import seconds, torch's seconds, modules imported at top level)`` of
    ``brdfkit argv`` from ``python -X importtime``."""
    code = "import sys; from brdfkit.cli import main; sys.argv[0] = 'brdfkit'; main(sys.argv[1:])"
    r = subprocess.run([sys.executable, "-X", "importtime", "-c", code, *argv], env=env,
                       capture_output=True, text=True)
    total, top = 0, {}
    for line in r.stderr.splitlines():
        m = re.match(r"import time:\s+(\d+) \|\s+(\d+) \|( *)(\S+)", line)
        if m and len(m.group(3)) == 1:
            top[m.group(4)] = top.get(m.group(4), 0) + int(m.group(2))
            total += int(m.group(2))
    return total / 1e6, top.get("torch", 0) / 1e6, sorted(top)


def wall(argv, env, k):
    """Best wall time of ``k`` runs of ``brdfkit argv`` (an error stops the benchmark)."""
    exe = os.path.join(os.path.dirname(sys.executable), "brdfkit")
    best = float("inf")
    for _ in range(k):
        t = time.perf_counter()
        r = subprocess.run([exe, *argv], env=env, capture_output=True, text=True)
        best = min(best, time.perf_counter() - t)
        if r.returncode != 0:
            raise RuntimeError(f"brdfkit {' '.join(argv)} failed: {r.stderr.strip()[-400:]}")
    return best


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--json", default=None)
    args = p.parse_args(argv)

    from brdfkit.materials import synthetic
    from brdfkit.io.merl import write_merl

    env = {k: v for k, v in os.environ.items() if k not in ("BRDFKIT_MODEL",)}
    rows, results = [], []
    with tempfile.TemporaryDirectory() as tmp:
        j = lambda *a: os.path.join(tmp, *a)  # noqa: E731
        write_merl(j("a.binary"), synthetic.table(synthetic.STIFF[2]))
        write_merl(j("b.binary"), synthetic.table(synthetic.STIFF[3]))
        _, model, _ = common.untrained_model(tmp)
        prep = [["sample", j("a.binary"), "-n", "400", "-o", j("s.csv")],
                ["encode", j("a.binary"), j("b.binary"), "-m", model, "-o", tmp],
                ["render", j("a.binary"), "-o", j("a.exr")],
                ["render", j("b.binary"), "-o", j("b.exr")]]
        for a in prep:
            wall(a, env, 1)
        commands = [
            ("brdfkit --help", ["--help"]),
            ("sample 400", ["sample", j("a.binary"), "-n", "400", "-o", j("s2.csv")]),
            ("interpolate (.emb)", ["interpolate", j("a.emb"), j("b.emb"), "--t", "0.3", "-o", j("c.emb")]),
            ("plot a table", ["plot", j("a.binary"), "-o", j("p.png")]),
            ("metrics a.exr b.exr", ["metrics", "--ref", j("b.exr"), j("a.exr")]),  # the records' name
            ("sparse 400", ["sparse", j("s.csv"), "-m", model, "-o", j("sp.binary")]),
            ("encode a table", ["encode", j("a.binary"), "-m", model, "-o", j("enc")]),
            ("decode", ["decode", j("a.emb"), "-m", model, "-o", j("d.binary")]),
            ("render a table (256 px)", ["render", j("a.binary"), "-o", j("r.exr")]),
            ("render an .emb (256 px)", ["render", j("a.emb"), "-m", model, "-o", j("e.exr")]),
            ("metrics a.binary b.binary", ["metrics", "--ref", j("b.binary"), j("a.binary")]),  # likewise
        ]
        os.makedirs(j("enc"))
        for name, a in commands:
            t = wall(a, env, args.repeat)
            imp, imp_torch, top = importtime(a, env)
            r = {"command": name, "argv": a[:1], "wall_s": t, "import_s": imp, "torch_import_s": imp_torch,
                 "imports_torch": "torch" in top, "load_average": common.load_average()}
            results.append(r)
            rows.append([name, t, imp, imp_torch if r["imports_torch"] else "-", "yes" if r["imports_torch"] else "no",
                         " ".join(f"{v:.1f}" for v in r["load_average"])])
    data = {"machine": common.machine(), "repeat": args.repeat, "results": results,
            "goal": {"render_table_s_max": 2.5, "metrics_tables_s_max": 5.0}}
    common.report("commands", f"Whole commands in a fresh process, best of {args.repeat}",
                  ["command", "wall s", "imports s", "of which torch s", "imports torch", "load 1/5/15"],
                  rows, data, args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
