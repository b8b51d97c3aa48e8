"""Peak memory of ``brdfkit fit`` and ``brdfkit decode``, beside what the data must take.

Issue 7, item 5.

* ``fit``: the peak (``VmHWM``) and current (``VmRSS``) resident size of every running
  ``brdfkit fit`` process, read from ``/proc/<pid>/status`` (run this while a real
  training runs, e.g. the 80-material MERL run, and again later), with its material
  count, beside the arithmetic: a training material expanded to its 1,458,000 cells x 9
  float32 numbers (HD vector + RGB) would take 52.5 MB, 4.2 GB for 80; ``TrainingSet``
  keeps only the mapped RGB of the measured cells (13.3 MB a material) plus, while
  loading, the float32 stack of the raw tables (17.5 MB a material) for the median.
* ``decode``: ``brdfkit decode`` of a real embedding with an untrained default model, in
  a child process, its peak RSS from ``resource.getrusage(RUSAGE_CHILDREN).ru_maxrss``;
  beside the peak of a process that only imports torch and the brdfkit API (the floor).

Usage::

    python benchmarks/memory.py [--json out.json]
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile

import common

CELLS = 1_458_000
MEASURED = 1_111_432
MB = 1e6


def _status(pid):
    with open(f"/proc/{pid}/status") as f:
        text = f.read()
    return {k: int(re.search(rf"^{k}:\s+(\d+) kB", text, re.M).group(1)) * 1024 for k in ("VmHWM", "VmRSS")}


def fit_processes():
    out = []
    for pid in os.listdir("/proc"):
        if not pid.isdigit():
            continue
        try:
            with open(f"/proc/{pid}/cmdline", "rb") as f:
                argv = [a.decode(errors="replace") for a in f.read().split(b"\0") if a]
            if len(argv) < 3 or not any(a.endswith("brdfkit") for a in argv[:2]) or "fit" not in argv[1:3]:
                continue
            st = _status(pid)
        except (OSError, AttributeError):
            continue
        data = [a for a in argv[argv.index("fit") + 1:] if not a.startswith("-")][:1]
        n = None
        if data and os.path.isdir(data[0]):
            n = len([f for f in os.listdir(data[0]) if f.endswith(".binary")])
            n -= sum(1 for a in argv if a == "--exclude")
            excl = argv[argv.index("--exclude-list") + 1] if "--exclude-list" in argv else None
            if excl:
                try:
                    with open(excl if os.path.isabs(excl) else os.path.join(os.readlink(f"/proc/{pid}/cwd"), excl)) as f:
                        n -= len([ln for ln in f.read().splitlines() if ln.split("#")[0].strip()])
                except OSError:
                    pass
        out.append({"pid": int(pid), "cmd": " ".join(argv[1:])[:300], "materials": n,
                    "peak_rss_bytes": st["VmHWM"], "rss_bytes": st["VmRSS"]})
    return out


def child_peak(code: str) -> int:
    """Peak RSS in bytes of a child Python process running ``code``, read in a wrapper
    process of its own so that no other child shares the RUSAGE_CHILDREN maximum."""
    wrapper = ("import resource, subprocess, sys; r = subprocess.run([sys.executable, '-c', sys.argv[1]]); "
               "print(r.returncode, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)")
    r = subprocess.run([sys.executable, "-c", wrapper, code], capture_output=True, text=True)
    rc, kb = r.stdout.split()[-2:]
    if rc != "0":
        raise RuntimeError(f"child failed: {r.stderr[-500:]}")
    return int(kb) * 1024


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--json", default=None)
    args = p.parse_args(argv)

    import numpy as np

    from brdfkit.io.embedding import Embedding, write_embedding

    fits = fit_processes()
    with tempfile.TemporaryDirectory() as tmp:
        model, model_path, _ = common.untrained_model(tmp)
        emb_path = os.path.join(tmp, "m.emb")
        rng = np.random.default_rng(0)
        write_embedding(emb_path, Embedding((0.1 * rng.normal(size=40)).astype(np.float32), "hypernet", model.digest))
        out = os.path.join(tmp, "m.binary")
        decode = child_peak("import sys; from brdfkit.cli import main; "
                            f"main(['decode', {emb_path!r}, '-m', {model_path!r}, '-o', {out!r}])")
        floor = child_peak("import torch, brdfkit.api, brdfkit.hypernet.neural_brdf, brdfkit.io.merl")
        # load_model + grid_hd + to_table without the write: where the decode's memory goes.
        decode_only = child_peak(
            "import brdfkit.api as a; from brdfkit.io.embedding import read_embedding; "
            f"m = a.load_model({model_path!r}); a.decode(read_embedding({emb_path!r}), m)")

    per_material_expanded = CELLS * 9 * 4
    arithmetic = {
        "expanded_per_material_bytes": per_material_expanded,
        "trainset_values_per_material_bytes": MEASURED * 3 * 4,
        "loading_stack_per_material_bytes": CELLS * 3 * 4,
        "decode_arrays_bytes": {"grid_hd float32 (1.458M x 6)": CELLS * 6 * 4,
                                "decode input + ones row float32 (7 x 1.11M)": 7 * MEASURED * 4,
                                "rho_ref at measured cells float32 (3 x 1.11M)": 3 * MEASURED * 4,
                                "decoded values float32 (3 x 1.11M)": 3 * MEASURED * 4,
                                "table float64 (1.458M x 3)": CELLS * 3 * 8,
                                "write_merl: stored values + channel-major copy, float64": 2 * CELLS * 3 * 8},
    }
    rows = []
    for f in fits:
        m = f["materials"]
        if m:
            expect_peak = m * (MEASURED * 3 * 4 + CELLS * 3 * 4)
            f["expected_data_peak_bytes"] = expect_peak
            f["expected_data_steady_bytes"] = m * MEASURED * 3 * 4
            f["expanded_would_be_bytes"] = m * per_material_expanded
        rows.append([f"fit pid {f['pid']} ({m or '?'} materials)", f"{f['peak_rss_bytes'] / MB:,.0f}",
                     f"{f['rss_bytes'] / MB:,.0f}",
                     f"{f.get('expected_data_peak_bytes', 0) / MB:,.0f} peak / "
                     f"{f.get('expected_data_steady_bytes', 0) / MB:,.0f} steady",
                     f"{f.get('expanded_would_be_bytes', 0) / MB:,.0f}"])
    dec_arrays = sum(arithmetic["decode_arrays_bytes"].values())
    rows.append(["decode (child process, whole CLI)", f"{decode / MB:,.0f}", "-",
                 f"{floor / MB:,.0f} imports + {dec_arrays / MB:,.0f} arrays", "-"])
    rows.append(["decode without the file write", f"{decode_only / MB:,.0f}", "-", "-", "-"])
    rows.append(["import torch + brdfkit only", f"{floor / MB:,.0f}", "-", "-", "-"])
    data = {"machine": common.machine(), "fit_processes": fits, "decode_peak_rss_bytes": decode,
            "decode_no_write_peak_rss_bytes": decode_only, "import_floor_peak_rss_bytes": floor,
            "arithmetic": arithmetic}
    common.report("memory", "Peak memory (MB = 10^6 bytes)",
                  ["process", "peak RSS MB", "current RSS MB", "data arithmetic MB",
                   "9 float32 per cell per material would be MB"], rows, data, args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
