"""Dense decode of a whole MERL table from an embedding, against a plain-``mm`` bound; and
per-operation wall and CPU times of decode, dense encode and ``eval_dirs``.

Issue 7, item 1. By default measures, per torch thread count:

* ``decode compute``: ``NeuralBRDF.to_table()`` (hyponet on the 1,111,432 measured cells,
  inverse mapping, the float64 ``(90, 90, 180, 3)`` table);
* ``decode + write``: ``api.decode`` then ``merl.write_merl`` of a real 34,992,012-byte
  MERL file (to a temporary folder), as ``brdfkit decode`` does after loading;
* ``write_merl`` alone;
* the **bound**: a plain ``torch.mm`` chain with the hyponet's shapes (``6 -> 60 x 4 ->
  3``, hence the same FLOP count) over the same cells in the same cache-sized blocks
  (:data:`brdfkit.hypernet.kernels.DECODE_BLOCK`), nothing else: no bias, ReLU, mapping or table;
* for context: the same chain unblocked (one ``(60, 1.1 M)`` activation: memory-bound)
  and the fp32 rate of a cache-resident 256^3 ``mm``.

Best of ``--repeat`` interleaved rounds (decode, bound, decode, bound, ...). Goal: decode
compute under 0.3 s on 2 cores and within 1.5x of the blocked bound.

``--per-operation`` instead times, per thread count, the dense decode
(``NeuralBRDF.to_table``), the dense encode of one table, and ``NeuralBRDF.eval_dirs`` on
262,144 random direction pairs (a 512 x 512 image's worth): the minimum and median wall
time and process CPU time over ``--repeat`` runs, after one warm-up run (which fills the
per-process caches). CPU time is the figure to quote on a shared machine: wall time there
depends on what else runs.

Without ``--model`` an untrained model of the paper's default architecture is built
(speed does not depend on the weights) with the reference table of a synthetic material,
so the measured cells are the 1,111,432 cells above the horizon of a MERL table.

Usage::

    python benchmarks/decode.py [--threads 1,2] [--repeat 7] [--multi-repeat 2] [--json out.json]
    python benchmarks/decode.py --per-operation [--threads 1] [--repeat 9]
    # both: [--model MODEL.safetensors] [--device cpu] [--decode-block B] [--encode-chunk C]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time

import common


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--threads", default=None,
                   help="comma-separated torch thread counts (default 1,2; with --per-operation torch's choice)")
    p.add_argument("--repeat", type=int, default=None, help="rounds (default 7; 9 with --per-operation)")
    p.add_argument("--multi-repeat", type=int, default=0,
                   help="rounds for thread counts above 1 (decode, bound and naive only); 0: --repeat, all")
    p.add_argument("--per-operation", action="store_true",
                   help="wall and CPU times of decode, dense encode and eval_dirs instead of the bound")
    p.add_argument("--model", help="model file; default: an untrained default-architecture model")
    p.add_argument("--device", default="cpu")
    p.add_argument("--decode-block", type=int, default=None, help="override kernels.DECODE_BLOCK")
    p.add_argument("--encode-chunk", type=int, default=None, help="override kernels.ENCODE_CHUNK")
    p.add_argument("--json", default=None)
    args = p.parse_args(argv)
    if args.repeat is None:
        args.repeat = 9 if args.per_operation else 7

    from brdfkit.hypernet import kernels

    if args.decode_block:
        kernels.DECODE_BLOCK = args.decode_block
    if args.encode_chunk:
        kernels.ENCODE_CHUNK = args.encode_chunk
    if args.threads is None:  # 0: leave torch's choice
        args.threads = "0" if args.per_operation else "1,2"
    threads = [int(t) for t in args.threads.split(",") if t]
    with tempfile.TemporaryDirectory() as tmp:
        if args.model:
            from brdfkit import api
            from brdfkit.materials import synthetic

            model, table = api.load_model(args.model, device=args.device), synthetic.table(synthetic.STIFF[2])
        else:
            model, _, table = common.untrained_model(tmp, device=args.device)
        if args.per_operation:
            return per_operation(model, table, threads, args.repeat)
        return against_bound(model, threads, args, tmp)


def _embedding(model):
    import numpy as np

    from brdfkit.io.embedding import Embedding

    rng = np.random.default_rng(0)
    return Embedding((0.1 * rng.normal(size=model.cfg.latent_dim)).astype(np.float32), "hypernet", model.digest)


def against_bound(model, thread_counts, args, tmp) -> int:
    import numpy as np

    from brdfkit import api
    from brdfkit.hypernet import kernels
    from brdfkit.hypernet.neural_brdf import NeuralBRDF
    from brdfkit.hypernet.network import hyponet_shapes
    from brdfkit.io.merl import write_merl

    rows, results = [], []
    emb = _embedding(model)
    nb = NeuralBRDF.from_embedding(model, emb)
    cells = int(np.isfinite(model.rho_ref).all(-1).sum())
    shapes = hyponet_shapes(model.cfg)
    out_path = os.path.join(tmp, "decoded.binary")
    table = nb.to_table()
    device = str(model.device)

    for threads in thread_counts:
        common.set_threads(threads)
        blocked, flops = common.mm_chain(shapes, cells, kernels.DECODE_BLOCK, device=device)
        naive, _ = common.mm_chain(shapes, cells, cells, device=device)
        load_before = common.load_average()
        fns = {"decode": nb.to_table, "bound": blocked,
               "decode_write": lambda: write_merl(out_path, api.decode(emb, model)),
               "write": lambda: write_merl(out_path, table), "naive": naive}
        if threads > 1 and args.multi_repeat:
            # Extra threads on a busy machine take seconds per call: decode and bound only.
            fns = {k: fns[k] for k in ("decode", "bound", "naive")}
        t = common.best_of(fns, args.multi_repeat if threads > 1 and args.multi_repeat else args.repeat)
        t.setdefault("decode_write", float("nan"))
        t.setdefault("write", float("nan"))
        peak = common.peak_gemm(device)
        r = {"threads": threads, "cells": cells, "flops": flops, "block": kernels.DECODE_BLOCK,
             "decode_s": t["decode"], "decode_median_s": t["decode_median"],
             "decode_write_s": t["decode_write"], "write_s": t["write"],
             "bound_blocked_mm_s": t["bound"], "bound_median_s": t["bound_median"],
             "naive_mm_s": t["naive"], "peak_gemm_flops": peak,
             "ratio_to_bound": t["decode"] / t["bound"],
             "bound_gflops": flops / t["bound"] / 1e9,
             "decode_gflops": flops / t["decode"] / 1e9,
             "naive_gflops": flops / t["naive"] / 1e9,
             "load_average_before": load_before, "load_average_after": common.load_average()}
        results.append(r)
        rows.append([threads, t["decode"], t["bound"], f"{r['ratio_to_bound']:.2f}x",
                     t["decode_write"], t["write"], t["naive"],
                     f"{r['bound_gflops']:.1f} / {r['naive_gflops']:.1f} / {peak / 1e9:.1f}",
                     " ".join(f"{x:.1f}" for x in r["load_average_after"])])
    data = {"machine": common.machine(), "goal": {"decode_s": 0.3, "ratio_to_bound": 1.5},
            "hyponet": [list(s) for s in shapes], "results": results}
    common.report("decode", f"Dense decode, {cells:,} cells (best of {args.repeat})",
                  ["threads", "decode s", "bound (blocked mm) s", "ratio", "decode+write s", "write_merl s",
                   "naive mm s", "GFLOP/s blocked / naive / 256^3 peak", "load 1/5/15"],
                  rows, data, args.json)
    return 0


def per_operation(model, table, thread_counts, repeat) -> int:
    import numpy as np
    import torch

    from brdfkit import api
    from brdfkit.hypernet import kernels
    from brdfkit.hypernet.neural_brdf import NeuralBRDF

    def timed(fn):
        fn()  # warm-up: caches, allocator, lazy init
        wall, cpu = [], []
        for _ in range(repeat):
            if model.device.type == "cuda":
                torch.cuda.synchronize()
            t, c = time.perf_counter(), time.process_time()
            fn()
            if model.device.type == "cuda":
                torch.cuda.synchronize()
            wall.append(time.perf_counter() - t)
            cpu.append(time.process_time() - c)
        return wall, cpu

    rng = np.random.default_rng(0)
    nb = NeuralBRDF.from_embedding(model, _embedding(model))
    cells = int(np.isfinite(model.rho_ref).all(-1).sum())
    v = rng.normal(size=(2, 262144, 3))
    v[..., 2] = np.abs(v[..., 2])
    wi, wo = torch.tensor(v / np.linalg.norm(v, axis=-1, keepdims=True), dtype=torch.float32)
    for threads in thread_counts:
        common.set_threads(threads)
        load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
        print(f"device {model.device}, torch threads {torch.get_num_threads()}, "
              f"{os.cpu_count()} CPUs, load average {load:.1f}; hyponet {model.cfg.hypo_hidden} x "
              f"{model.cfg.hypo_layers}, latent {model.cfg.latent_dim}, decode block {kernels.DECODE_BLOCK}, "
              f"encode chunk {kernels.ENCODE_CHUNK}")
        for name, n, fn in (("decode (to_table)", f"{cells:,} cells", nb.to_table),
                            ("encode dense table", f"{cells:,} cells", lambda: api.encode(table, model)),
                            ("eval_dirs", "262,144 pairs", lambda: nb.eval_dirs(wi, wo))):
            wall, cpu = timed(fn)
            print(f"{name:18s} {n:>15s}: wall min {min(wall):.3f} s, median {statistics.median(wall):.3f} s;"
                  f" CPU min {min(cpu):.3f} s, median {statistics.median(cpu):.3f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
