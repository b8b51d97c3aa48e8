"""Training throughput of ``fit``'s step against the GEMM rate of the same shapes.

Issue 7, item 3 (first half). One training step as :func:`brdfkit.hypernet.training.loop.fit` runs it
(``BatchSampler.draw``, forward, ``hyper_loss``, backward, gradient clipping, Adam; the
lines below mirror the loop body of ``brdfkit/hypernet/training/loop.py``) on an in-memory
:class:`~brdfkit.hypernet.training.dataset.TrainingSet` of synthetic materials, default options (8
materials x 4096 query cells per step) and the default architecture, with the context
size fixed at 860 (the mean of the default log-uniform draw over 40 ... 4000) so that
every step does the same work.

The **bound** is the same step's matrix products as plain ``mm`` / ``bmm`` into
preallocated outputs: forward and backward (input gradient, except for the network
inputs, and weight gradient) of the set encoder on ``B x C`` rows, the ten decoder MLPs
on ``B`` latents, and the ``B`` hyponets on ``B x Q`` query cells. Throughput is query
samples per second (what ``fit`` prints); goal at least 60% of the bound's.

Usage::

    python benchmarks/train_throughput.py [--threads 1] [--repeat 10] [--json out.json]
"""

from __future__ import annotations

import argparse
import sys

import common

CONTEXT = 860


def gemm_bound(cfg, batch, context, query):
    """``(fn, flops)``: the forward + backward matrix products of one step as plain
    ``mm``/``bmm`` calls with preallocated outputs."""
    import torch

    from brdfkit.hypernet.network import hyponet_shapes

    g = torch.Generator().manual_seed(0)
    ops = []  # (kind, A, B, out)

    def add(kind, lead, m, k, n):
        shape = (lambda *s: (lead, *s)) if kind == "bmm" else (lambda *s: s)
        ops.append((kind, torch.randn(shape(m, k), generator=g), torch.randn(shape(k, n), generator=g),
                    torch.empty(shape(m, n))))
        return 2 * (lead if kind == "bmm" else 1) * m * k * n

    def layers(kind, lead, rows, sizes, input_grad=False):
        f = 0
        for i, (a, b) in enumerate(zip(sizes[:-1], sizes[1:])):
            f += add(kind, lead, rows, a, b)          # forward   h W
            f += add(kind, lead, a, rows, b)          # dL/dW  =  h^T dY
            if i > 0 or input_grad:
                f += add(kind, lead, rows, b, a)      # dL/dh  =  dY W^T (not for data inputs)
        return f

    flops = layers("mm", 1, batch * context, [9, *cfg.encoder_hidden, cfg.latent_dim])
    hidden = [cfg.decoder_hidden] * cfg.decoder_layers
    for fi, fo in hyponet_shapes(cfg):
        for numel in (fi * fo, fo):
            # z needs its gradient: the encoder is trained through the decoder.
            flops += layers("mm", 1, batch, [cfg.latent_dim, *hidden, numel], input_grad=True)
    widths = [6] + [cfg.hypo_hidden] * cfg.hypo_layers + [3]
    flops += layers("bmm", batch, query, widths)

    def run():
        for kind, a, b, out in ops:
            (torch.bmm if kind == "bmm" else torch.mm)(a, b, out=out)

    return run, flops


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--threads", default="1", help="comma-separated torch thread counts")
    p.add_argument("--repeat", type=int, default=10)
    p.add_argument("--json", default=None)
    args = p.parse_args(argv)

    import numpy as np
    import torch

    from brdfkit.materials import synthetic
    from brdfkit.geometry import N_CELLS
    from brdfkit.hypernet.mapping import median_reference, to_mapped
    from brdfkit.hypernet import network as hypernet
    from brdfkit.hypernet.training.loop import TrainOptions
    from brdfkit.hypernet.training.dataset import BatchSampler, TrainingSet

    opts = TrainOptions()
    cfg = hypernet.HyperConfig()
    mats = synthetic.library(2, seed=0, stiff=False)
    tables = [synthetic.table(m).astype(np.float32) for m in mats]
    names = [f"m{i}" for i in range(opts.batch_materials)]
    stack = np.stack([tables[i % 2].reshape(-1) for i in range(len(names))])
    rho_ref = median_reference(stack)
    cells = np.flatnonzero(np.isfinite(stack.reshape(len(names), N_CELLS, 3)).all(axis=(0, 2)))
    ref = rho_ref.reshape(N_CELLS, 3)[cells].astype(np.float64)
    values = np.stack([to_mapped(t.reshape(N_CELLS, 3)[cells].astype(np.float64), ref).astype(np.float32)
                       for t in (tables[i % 2] for i in range(len(names)))])
    del stack
    tset = TrainingSet(names, names, rho_ref, cells, range(len(names)), values)
    device = torch.device("cpu")

    rows, results = [], []
    for threads in [int(t) for t in args.threads.split(",") if t]:
        common.set_threads(threads)
        torch.manual_seed(0)
        net = hypernet.HyperBRDF(cfg).to(device)
        net.train()
        opt = torch.optim.Adam(net.parameters(), lr=opts.lr)
        sampler = BatchSampler(tset, device, opts.batch_materials, opts.query_size, CONTEXT, CONTEXT, 0)
        state = {"step": 0}
        batch = sampler.draw(0)

        def step():
            # Mirrors the loop body of brdfkit/hypernet/training/loop.py (one process, no DDP).
            ctx_hd, ctx_val, q_hd, q_val, q_cos = sampler.draw(state["step"])
            opt.zero_grad(set_to_none=True)
            pred, weights, z = net(ctx_hd, ctx_val, q_hd)
            total, mse = hypernet.hyper_loss(pred, q_val, q_cos, weights, z, cfg)
            total.backward()
            torch.nn.utils.clip_grad_norm_(net.parameters(), opts.grad_clip)
            opt.step()
            state["step"] += 1

        def model_only():
            ctx_hd, ctx_val, q_hd, q_val, q_cos = batch
            opt.zero_grad(set_to_none=True)
            pred, weights, z = net(ctx_hd, ctx_val, q_hd)
            total, _ = hypernet.hyper_loss(pred, q_val, q_cos, weights, z, cfg)
            total.backward()

        bound, flops = gemm_bound(cfg, sampler.batch, CONTEXT, opts.query_size)
        t = common.best_of({"step": step, "bound": bound, "draw": lambda: sampler.draw(state["step"]),
                            "fwd_bwd": model_only}, args.repeat, warmup=2)
        q = sampler.batch * opts.query_size
        r = {"threads": threads, "batch_materials": sampler.batch, "query": opts.query_size,
             "context": CONTEXT, "step_s": t["step"], "step_median_s": t["step_median"],
             "draw_s": t["draw"], "forward_backward_s": t["fwd_bwd"], "bound_gemm_s": t["bound"],
             "flops": flops, "samples_per_s": q / t["step"], "bound_samples_per_s": q / t["bound"],
             "fraction_of_bound": t["bound"] / t["step"], "bound_gflops": flops / t["bound"] / 1e9,
             "load_average": common.load_average()}
        results.append(r)
        rows.append([threads, f"{r['samples_per_s']:,.0f}", f"{r['bound_samples_per_s']:,.0f}",
                     f"{100 * r['fraction_of_bound']:.0f}%", t["step"] * 1e3, t["draw"] * 1e3,
                     t["fwd_bwd"] * 1e3, t["bound"] * 1e3, f"{r['bound_gflops']:.1f}",
                     " ".join(f"{v:.1f}" for v in r["load_average"])])
    data = {"machine": common.machine(), "goal": {"fraction_of_bound_min": 0.6}, "results": results}
    common.report("train", f"Training step throughput (8 x 4096 query cells, context {CONTEXT}, best of {args.repeat})",
                  ["threads", "query samples/s", "bound samples/s", "of bound", "step ms", "draw ms",
                   "fwd+bwd ms", "bound ms", "bound GFLOP/s", "load 1/5/15"], rows, data, args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
