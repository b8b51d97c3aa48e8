"""Time to quality of ``brdfkit fit``: held-out error at N = 400 samples against training
wall time.

Issue 7, item 3 (second half). Writes a small synthetic library
(:func:`brdfkit.materials.synthetic.write_library`: GGX + Lambert, stiff cases included), holds
out ``--held-out`` of its random materials, and runs the real command line
``brdfkit fit LIB --exclude ... --minutes M --checkpoint-minutes C`` in a subprocess.
This process watches the checkpoint file (written atomically every ``C`` minutes) and
evaluates each new one as the user would use the model: per held-out material,
``--n`` samples (:func:`brdfkit.acquisition.sampling.draw_samples`, seed 0) -> encode -> dense decode
-> :func:`brdfkit.evaluation.metrics.brdf_log_rmse` against the material's own table. The curve
(training seconds from the checkpoint's own clock, step, mean held-out log-RMSE) is
printed with the time at which it *stops improving*: the first evaluation after which no
later one is more than ``--tol`` (relative) better than the best so far.

Limits (``docs/notes/performance.md``): the evaluator shares the CPU with the training process
(one torch thread, a few seconds per evaluation), so the training clock runs a little
slow; a checkpoint overwritten before the evaluator got to it is skipped; synthetic
materials are easier and fewer than MERL's 80, so the times say how fast ``fit`` gets
somewhere on this machine, not how long a paper-quality model takes; the cosine
schedule decays over the ``--minutes`` budget, so the curve flattens partly because the
learning rate does. Image PSNR is not used (BRDF-space error needs no renderer).

Usage::

    python benchmarks/time_to_quality.py [--minutes 5] [--materials 12] [--held-out 3]
                                         [--checkpoint-minutes 0.25] [--json out.json]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time

import common


def stops_improving(curve, tol):
    """Index of the first point after which no later point beats the best so far by more
    than ``tol`` (relative); ``curve`` is ``[(t, step, err), ...]`` in time order."""
    for i in range(len(curve)):
        best = min(c[2] for c in curve[: i + 1])
        later = [c[2] for c in curve[i + 1:]]
        if not later or min(later) >= best * (1 - tol):
            return i
    return len(curve) - 1


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--minutes", type=float, default=5.0)
    p.add_argument("--materials", type=int, default=12)
    p.add_argument("--held-out", type=int, default=3)
    p.add_argument("--checkpoint-minutes", type=float, default=0.25)
    p.add_argument("--n", type=int, default=400)
    p.add_argument("--tol", type=float, default=0.02)
    p.add_argument("--json", default=None)
    args = p.parse_args(argv)

    import numpy as np
    import torch

    torch.set_num_threads(1)
    from brdfkit import api
    from brdfkit.materials import synthetic
    from brdfkit.hypernet.training.checkpoint import load_checkpoint
    from brdfkit.errors import BrdfkitError
    from brdfkit.hypernet.network import HyperBRDF, HyperConfig
    from brdfkit.io.merl import read_merl
    from brdfkit.evaluation.metrics import brdf_log_rmse
    from brdfkit.hypernet.network_file import weights_digest
    from brdfkit.hypernet.loaded import LoadedNetwork
    from brdfkit.acquisition.sampling import draw_samples
    from brdfkit.hypernet.mapping import median_reference

    curve = []
    with tempfile.TemporaryDirectory() as tmp:
        lib = os.path.join(tmp, "lib")
        paths = synthetic.write_library(lib, args.materials, seed=0)
        names = [os.path.basename(x)[:-len(".binary")] for x in paths]
        stiff = {m.name for m in synthetic.STIFF}
        held = [n for n in names if n not in stiff][-args.held_out:]
        train = sorted(n for n in names if n not in held)
        tables = {n: read_merl(os.path.join(lib, n + ".binary")) for n in names}
        # The training reference, exactly as TrainingSet computes it.
        stack = np.stack([tables[n].astype(np.float32).reshape(-1) for n in train])
        rho_ref = median_reference(stack)
        del stack
        samples = {n: draw_samples(tables[n], args.n, seed=0) for n in held}

        out = os.path.join(tmp, "model.safetensors")
        ckpt = out + ".ckpt"
        cmd = [os.path.join(os.path.dirname(sys.executable), "brdfkit"), "fit", lib, "-o", out, "-q",
               "--minutes", str(args.minutes), "--checkpoint-minutes", str(args.checkpoint_minutes)]
        for n in held:
            cmd += ["--exclude", n]
        t0 = time.monotonic()
        proc = subprocess.Popen(cmd, stderr=subprocess.PIPE, text=True)
        seen = None
        try:
            while True:
                done = proc.poll() is not None
                mtime = os.stat(ckpt).st_mtime_ns if os.path.exists(ckpt) else None
                if mtime is not None and mtime != seen:
                    seen = mtime
                    try:
                        state = load_checkpoint(ckpt)
                    except BrdfkitError:
                        time.sleep(0.5)  # caught mid-rename on a slow file system: retry
                        seen = None
                        continue
                    cfg = HyperConfig.from_json(state["config"])
                    net = HyperBRDF(cfg)
                    net.load_state_dict(state["net"])
                    net.eval()
                    model = LoadedNetwork(net, cfg, rho_ref, weights_digest(net), {}, torch.device("cpu"), ckpt)
                    errs = []
                    for n in held:
                        table, _ = api.sparse(samples[n], model)
                        errs.append(brdf_log_rmse(table, tables[n]))
                    point = (float(state["elapsed"]), int(state["step"]), float(np.mean(errs)))
                    curve.append(point)
                    print(f"  train {point[0]:6.1f} s  step {point[1]:5d}  held-out log-RMSE at N={args.n} "
                          f"{point[2]:.4f}  (load {common.load_average()[0]:.1f})", flush=True)
                if done:
                    break
                time.sleep(1.0)
        finally:
            if proc.poll() is None:
                proc.terminate()
                proc.wait()
        wall = time.monotonic() - t0
        err = proc.stderr.read()
        if proc.returncode != 0:
            raise SystemExit(f"brdfkit fit failed ({proc.returncode}): {err.strip()[-500:]}")

    i = stops_improving(curve, args.tol) if curve else None
    data = {"machine": common.machine(), "materials": args.materials, "train": train, "held_out": held,
            "n_samples": args.n, "minutes": args.minutes, "tol": args.tol, "process_wall_s": wall,
            "curve": [{"train_s": t, "step": s, "log_rmse": e} for t, s, e in curve],
            "stops_improving": None if i is None else {"train_s": curve[i][0], "step": curve[i][1],
                                                         "log_rmse": curve[i][2]},
            "best_log_rmse": min(c[2] for c in curve) if curve else None,
            "first_log_rmse": curve[0][2] if curve else None}
    rows = [[f"{t:.0f}", s, e, "<- stops improving" if k == i else ""] for k, (t, s, e) in enumerate(curve)]
    common.report("time_to_quality", f"Time to quality: {len(train)} synthetic materials, held-out "
                  f"log-RMSE at N = {args.n} ({', '.join(held)})",
                  ["training s", "step", "held-out brdf_log_rmse", ""], rows, data, args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
