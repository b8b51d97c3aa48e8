"""Dense decode of a whole MERL table from an embedding, against a plain-``mm`` bound.

Issue 7, item 1. Measures, per torch thread count:

* ``decode compute``: ``NeuralBRDF.to_table()`` (hyponet on the 1,111,432 measured cells,
  inverse mapping, the float64 ``(90, 90, 180, 3)`` table);
* ``decode + write``: ``api.decode`` then ``merl.write_merl`` of a real 34,992,012-byte
  MERL file (to a temporary folder), as ``brdfkit decode`` does after loading;
* ``write_merl`` alone;
* the **bound**: a plain ``torch.mm`` chain with the hyponet's shapes (``6 -> 60 x 4 ->
  3``, hence the same FLOP count) over the same cells in the same cache-sized blocks
  (:data:`brdfkit.neural.DECODE_BLOCK`), nothing else: no bias, ReLU, mapping or table;
* for context: the same chain unblocked (one ``(60, 1.1 M)`` activation: memory-bound)
  and the fp32 rate of a cache-resident 256^3 ``mm``.

Best of ``--repeat`` interleaved rounds (decode, bound, decode, bound, ...). Goal: decode
compute under 0.3 s on 2 cores and within 1.5x of the blocked bound.

Usage::

    python benchmarks/decode_bound.py [--threads 1,2] [--repeat 7] [--multi-repeat 2] [--json out.json]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile

import common


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--threads", default="1,2", help="comma-separated torch thread counts")
    p.add_argument("--repeat", type=int, default=7)
    p.add_argument("--multi-repeat", type=int, default=0,
                   help="rounds for thread counts above 1 (decode, bound and naive only); 0: --repeat, all")
    p.add_argument("--json", default=None)
    args = p.parse_args(argv)

    import numpy as np
    import torch

    from brdfkit import api, neural
    from brdfkit.embedding import Embedding
    from brdfkit.hypernet import hyponet_shapes
    from brdfkit.merl import write_merl

    rows, results = [], []
    with tempfile.TemporaryDirectory() as tmp:
        model, _, _ = common.untrained_model(tmp)
        rng = np.random.default_rng(0)
        emb = Embedding((0.1 * rng.normal(size=model.cfg.latent_dim)).astype(np.float32), model.fingerprint)
        nb = neural.NeuralBRDF.from_embedding(model, emb)
        cells = int(np.isfinite(model.rho_ref).all(-1).sum())
        shapes = hyponet_shapes(model.cfg)
        out_path = os.path.join(tmp, "decoded.binary")
        table = nb.to_table()

        for threads in [int(t) for t in args.threads.split(",") if t]:
            common.set_threads(threads)
            blocked, flops = common.mm_chain(shapes, cells, neural.DECODE_BLOCK)
            naive, _ = common.mm_chain(shapes, cells, cells)
            load_before = common.load_average()
            fns = {"decode": nb.to_table, "bound": blocked,
                   "decode_write": lambda: write_merl(out_path, api.decode(model, emb)),
                   "write": lambda: write_merl(out_path, table), "naive": naive}
            if threads > 1 and args.multi_repeat:
                # Extra threads on a busy machine take seconds per call: decode and bound only.
                fns = {k: fns[k] for k in ("decode", "bound", "naive")}
            t = common.best_of(fns, args.multi_repeat if threads > 1 and args.multi_repeat else args.repeat)
            t.setdefault("decode_write", float("nan"))
            t.setdefault("write", float("nan"))
            peak = common.peak_gemm()
            r = {"threads": threads, "cells": cells, "flops": flops, "block": neural.DECODE_BLOCK,
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


if __name__ == "__main__":
    sys.exit(main())
