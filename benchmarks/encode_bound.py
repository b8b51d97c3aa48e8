"""Sparse samples to hyponet weights, per N, against a plain-``mm`` bound; and the whole
``brdfkit sparse`` process with its import cost.

Issue 7, item 2. Per sample count ``N`` (40 ... 4000), best of ``--repeat`` interleaved
rounds, one torch thread unless ``--threads``:

* ``network``: the library's encoder on ``N`` samples (mapping of the sample values,
  set encoder, mean) and the hypernetwork decoder to the hyponet weights
  (``kernels.encode_mean``, ``kernels.hyponet_weights``): the part the goal (under
  2 ms for ``N <= 4000``) is about; ``HyperBRDF modules``: the same through the
  ``nn.Module`` definition (``net.encoder``, ``net.hyponet_weights``), for comparison;
* ``library``: ``api.encode(model, SampleSet)`` then ``NeuralBRDF.from_embedding``: the
  same plus the reference lookup at the sample angles and the forward mapping;
* the **bound**: the same matrix products as plain ``torch.mm`` (encoder
  ``9 -> 128 -> 128 -> 40`` on ``N`` rows; each of the ten decoder MLPs
  ``40 -> 128 -> 128 -> numel`` on one row), nothing else.

Then the command line, as a user runs it (``brdfkit sparse S.csv -m M -o out.binary``,
400 samples, untrained default model): whole-process wall time, best of
``--cli-repeat``, with the thread choice of :mod:`brdfkit.runtime` and with torch's
default of one thread per core (``OMP_NUM_THREADS=<cores>``, the behaviour before it);
and ``python -X importtime`` of the same command: total import time and the largest
top-level packages.

Usage::

    python benchmarks/encode_bound.py [--repeat 20] [--cli-repeat 3] [--json out.json]
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import tempfile
import time

import common

NS = (40, 100, 400, 1000, 4000)


def _decoder_shapes(cfg):
    from brdfkit.hypernet.network import hyponet_shapes

    hidden = [cfg.decoder_hidden] * cfg.decoder_layers
    nets = []
    for fi, fo in hyponet_shapes(cfg):
        for numel in (fi * fo, fo):
            sizes = [cfg.latent_dim, *hidden, numel]
            nets.append(list(zip(sizes[:-1], sizes[1:])))
    return nets


def _process_time(cmd, env, k):
    best = float("inf")
    for _ in range(k):
        t = time.perf_counter()
        r = subprocess.run(cmd, env=env, capture_output=True, text=True)
        dt = time.perf_counter() - t
        if r.returncode != 0:
            raise RuntimeError(f"{' '.join(cmd)} failed: {r.stderr.strip()[-400:]}")
        best = min(best, dt)
    return best


def _importtime(cmd, env):
    """Cumulative import microseconds of each top-level module, from -X importtime."""
    r = subprocess.run([sys.executable, "-X", "importtime", *cmd], env=env, capture_output=True, text=True)
    top = {}
    for line in r.stderr.splitlines():
        m = re.match(r"import time:\s+(\d+) \|\s+(\d+) \|( *)(\S+)", line)
        if m and len(m.group(3)) == 1:
            top[m.group(4)] = top.get(m.group(4), 0) + int(m.group(2))
    return top


def main(argv=None):
    p = common.timing_parser(__doc__, repeat=20)
    p.add_argument("--cli-repeat", type=int, default=3)
    args = p.parse_args(argv)

    import numpy as np
    import torch

    common.set_threads(args.threads)
    from brdfkit import api
    from brdfkit.hypernet import kernels
    from brdfkit.hypernet.neural_brdf import NeuralBRDF
    from brdfkit.io.samples import write_samples
    from brdfkit.acquisition.sampling import draw_samples

    rows, results = [], []
    with tempfile.TemporaryDirectory() as tmp:
        model, model_path, table = common.untrained_model(tmp)
        net = model.net
        dec_shapes = _decoder_shapes(model.cfg)
        enc_shapes = [(9, 128), (128, 128), (128, model.cfg.latent_dim)]
        for n in NS:
            s = draw_samples(table, n, seed=1)
            rng = np.random.default_rng(n)
            x = torch.from_numpy(rng.normal(size=(n, 9)).astype(np.float32))

            def module():
                with torch.inference_mode():
                    z = net.encoder.net(x).mean(dim=0, keepdim=True)
                    return net.hyponet_weights(z)

            hd = s.hd()
            rgb = np.asarray(s.rgb, dtype=np.float64)
            ref = model.reference_at(s.theta_h, s.theta_d, s.phi_d)

            def network():
                z = kernels.encode_mean(model, hd, rgb, ref)
                with torch.inference_mode():
                    return kernels.hyponet_weights(model, torch.from_numpy(z)[None])

            enc_chain, enc_flops = common.mm_chain(enc_shapes, n, n, feature_major=False)
            dec = [common.mm_chain(sh, 1, 1, feature_major=False) for sh in dec_shapes]

            def bound():
                enc_chain()
                for fn, _ in dec:
                    fn()

            flops = enc_flops + sum(f for _, f in dec)
            t = common.best_of({"network": network, "bound": bound, "module": module,
                                "library": lambda: NeuralBRDF.from_embedding(model, api.encode(s, model))},
                               args.repeat, warmup=2)
            r = {"n": n, "network_s": t["network"], "bound_mm_s": t["bound"], "library_s": t["library"],
                 "model_definition_s": t["module"],
                 "network_median_s": t["network_median"], "bound_median_s": t["bound_median"],
                 "ratio_to_bound": t["network"] / t["bound"], "flops": flops,
                 "load_average": common.load_average()}
            results.append(r)
            rows.append([n, t["network"] * 1e3, t["bound"] * 1e3, f"{r['ratio_to_bound']:.2f}x",
                         t["module"] * 1e3, t["library"] * 1e3, f"{flops / 1e6:.1f}",
                         " ".join(f"{v:.1f}" for v in r["load_average"])])

        # The command line, whole process.
        csv = os.path.join(tmp, "s400.csv")
        write_samples(csv, draw_samples(table, 400, seed=1))
        exe = os.path.join(os.path.dirname(sys.executable), "brdfkit")
        cmd = ["sparse", csv, "-m", model_path, "-o", os.path.join(tmp, "out.binary")]
        env = {k: v for k, v in os.environ.items() if k not in ("OMP_NUM_THREADS", "MKL_NUM_THREADS")}
        cpus = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
        from brdfkit.runtime import threads_for_load
        chosen = threads_for_load(cpus, os.getloadavg()[0])
        cli = {"auto_threads_s": _process_time([exe, *cmd], env, args.cli_repeat),
               "auto_threads_would_choose": chosen, "cpus": cpus}
        cli["one_thread_per_core_s"] = _process_time([exe, *cmd], {**env, "OMP_NUM_THREADS": str(cpus)},
                                                     args.cli_repeat)
        imports = _importtime(["-c", "import sys; from brdfkit.cli import main; sys.argv[0] = 'brdfkit'; "
                               "main(sys.argv[1:])", *cmd], env)
        total = sum(imports.values())
        cli["import_total_s"] = total / 1e6
        cli["import_top_s"] = {k: v / 1e6 for k, v in sorted(imports.items(), key=lambda kv: -kv[1])[:8]}
        cli["imports_rich"] = any(k == "rich" for k in imports)
        cli["load_average"] = common.load_average()
    data = {"machine": common.machine(), "goal": {"network_s_max": 0.002}, "results": results, "cli_sparse": cli}
    common.report("encode", f"Encode: N samples -> hyponet weights, {args.threads} thread(s), best of {args.repeat}",
                  ["N", "network ms", "bound (plain mm) ms", "ratio", "HyperBRDF modules ms",
                   "library (encode + weights) ms",
                   "MFLOP", "load 1/5/15"], rows, data, args.json)
    top = ", ".join(f"{k} {v:.2f}" for k, v in cli["import_top_s"].items())
    print(f"brdfkit sparse, 400 samples, whole process (best of {args.cli_repeat}): "
          f"{cli['auto_threads_s']:.2f} s with the load-based thread choice ({chosen} thread(s)), "
          f"{cli['one_thread_per_core_s']:.2f} s with OMP_NUM_THREADS={cpus}; imports {cli['import_total_s']:.2f} s "
          f"({top}); rich imported: {cli['imports_rich']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
