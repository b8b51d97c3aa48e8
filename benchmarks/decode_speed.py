"""Time the dense decode (``NeuralBRDF.to_table``), the dense encode of one table, and
``NeuralBRDF.eval_dirs`` on 262,144 random direction pairs (a 512 x 512 image's worth).

Usage::

    python benchmarks/decode_speed.py [--model MODEL.safetensors] [--threads N] [--repeat 9]
                                      [--decode-block B] [--encode-chunk C]

Without ``--model`` an untrained model of the paper's default architecture is built
(speed does not depend on the weights) with the reference table of a synthetic material,
so the measured cells are the 1,111,432 cells above the horizon of a MERL table. Reports
the minimum and median wall time and process CPU time over ``--repeat`` runs, after one
warm-up run (which fills the per-process caches). CPU time is the figure to quote on a
shared machine: wall time there depends on what else runs.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--model", help="model file; default: an untrained default-architecture model")
    p.add_argument("--threads", type=int, default=None, help="torch threads (default: torch's choice)")
    p.add_argument("--repeat", type=int, default=9)
    p.add_argument("--device", default="cpu")
    p.add_argument("--decode-block", type=int, default=None, help="override neural.DECODE_BLOCK")
    p.add_argument("--encode-chunk", type=int, default=None, help="override neural.ENCODE_CHUNK")
    args = p.parse_args(argv)

    import numpy as np
    import torch

    if args.threads:
        torch.set_num_threads(args.threads)
    from brdfkit import api, synthetic
    from brdfkit.embedding import Embedding
    from brdfkit.hypernet import HyperBRDF, HyperConfig
    from brdfkit.modelfile import save_model
    from brdfkit import neural
    from brdfkit.neural import NeuralBRDF

    if args.decode_block:
        neural.DECODE_BLOCK = args.decode_block
    if args.encode_chunk:
        neural.ENCODE_CHUNK = args.encode_chunk

    table = synthetic.table(synthetic.STIFF[2])
    with tempfile.TemporaryDirectory() as tmp:
        path = args.model
        if path is None:
            torch.manual_seed(0)
            path = os.path.join(tmp, "untrained.safetensors")
            save_model(path, HyperBRDF(HyperConfig()), table)
        model = api.load_model(path, device=args.device)
    rng = np.random.default_rng(0)
    emb = Embedding((0.1 * rng.normal(size=model.cfg.latent_dim)).astype(np.float32), model.fingerprint)

    def timed(fn):
        fn()  # warm-up: caches, allocator, lazy init
        wall, cpu = [], []
        for _ in range(args.repeat):
            if model.device.type == "cuda":
                torch.cuda.synchronize()
            t, c = time.perf_counter(), time.process_time()
            fn()
            if model.device.type == "cuda":
                torch.cuda.synchronize()
            wall.append(time.perf_counter() - t)
            cpu.append(time.process_time() - c)
        return wall, cpu

    nb = NeuralBRDF.from_embedding(model, emb)
    cells = int(np.isfinite(model.rho_ref).all(-1).sum())
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"device {model.device}, torch threads {torch.get_num_threads()}, "
          f"{os.cpu_count()} CPUs, load average {load:.1f}; hyponet {model.cfg.hypo_hidden} x "
          f"{model.cfg.hypo_layers}, latent {model.cfg.latent_dim}, decode block {neural.DECODE_BLOCK}, "
          f"encode chunk {neural.ENCODE_CHUNK}")
    v = rng.normal(size=(2, 262144, 3))
    v[..., 2] = np.abs(v[..., 2])
    wi, wo = torch.tensor(v / np.linalg.norm(v, axis=-1, keepdims=True), dtype=torch.float32)
    for name, n, fn in (("decode (to_table)", f"{cells:,} cells", nb.to_table),
                        ("encode dense table", f"{cells:,} cells", lambda: api.encode(model, table)),
                        ("eval_dirs", "262,144 pairs", lambda: nb.eval_dirs(wi, wo))):
        wall, cpu = timed(fn)
        print(f"{name:18s} {n:>15s}: wall min {min(wall):.3f} s, median {statistics.median(wall):.3f} s;"
              f" CPU min {min(cpu):.3f} s, median {statistics.median(cpu):.3f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
