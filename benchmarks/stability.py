"""Re-measure the figures of docs/notes/stability.md (stiff materials, extreme inputs).

    python benchmarks/stability.py              # everything, ~3-5 minutes on 2 cores
    python benchmarks/stability.py encode csv   # some sections only

Sections: ``tables`` (the stiff materials), ``mapping`` (round trip), ``encode`` (10^6
samples: time and memory), ``csv`` (a 10^7-row file refused), ``config`` (a crafted
model config refused), ``train`` (a tiny model on mirror + black + white, with and
without gradient clipping, two learning rates), ``extrapolate`` (decoded values for t far
outside [0, 1]). One torch thread, CPU. Run from the repository root.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
import tracemalloc

import numpy as np

import common

MIRROR = dict(name="mirror-0.002", kind="conductor", alpha=0.002)
SECTIONS = ["tables", "mapping", "encode", "csv", "config", "train", "extrapolate"]


def materials():
    from brdfkit.materials import synthetic

    silver = synthetic.METALS["silver"]
    return {"mirror": synthetic.Material(**MIRROR, ior=silver[0], k=silver[1]),
            "black": synthetic.Material("black-0.001", "dielectric", 0.3, albedo=(1e-3,) * 3, ks=0.0),
            "white": synthetic.STIFF[2]}


_tables = {}


def tables():
    from brdfkit.materials import synthetic

    if not _tables:
        for name, m in materials().items():
            _tables[name] = synthetic.table(m)
    return _tables


def section_tables():
    for name, t in tables().items():
        v = t[np.isfinite(t)]
        print(f"  {name:7s} max {v.max():.3g}  min {v.min():.3g}  median {np.median(v):.3g} 1/sr")


def section_mapping():
    from brdfkit.hypernet.mapping import from_mapped, to_mapped

    t = tables()
    for ref_name, ref in (("white", t["white"]), ("mirror", t["mirror"]), ("0", 0.0), ("1e4", 1e4)):
        worst = 0.0
        for name in ("mirror", "black"):
            x = t[name]
            back = from_mapped(to_mapped(x, ref), ref)
            big = np.isfinite(x) & (x > 1e-6)
            worst = max(worst, float((np.abs(back[big] - x[big]) / x[big]).max()))
        print(f"  reference {ref_name:6s}: largest relative round-trip error {worst:.2g}")


def _traced(fn):
    """``(fn(), seconds, peak MB)`` of one call, the peak of what tracemalloc sees (Python's
    and NumPy's allocations, not torch's)."""
    tracemalloc.start()
    t0 = time.perf_counter()
    try:
        out = fn()
        sec = time.perf_counter() - t0
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    return out, sec, peak / 2**20


def section_encode(folder):
    from brdfkit import api
    from brdfkit.acquisition.sampling import draw_samples

    for label, config in (("tiny", common.TINY_CONFIG), ("paper (latent 40)", {})):
        model, _, _ = common.untrained_model(folder, config=config,
                                             name=f"m-{'tiny' if config else 'paper'}.safetensors")
        s = draw_samples(tables()["mirror"], 1_000_000, seed=3)
        api.encode(draw_samples(tables()["mirror"], 10, seed=0), model)  # warm up
        emb, sec, peak = _traced(lambda: api.encode(s, model))
        print(f"  {label:18s} 10^6 samples: {sec:.2f} s, NumPy peak {peak:.0f} MB "
              f"(input {sum(a.nbytes for a in (s.theta_h, s.theta_d, s.phi_d, s.rgb)) / 2**20:.0f} MB), "
              f"finite {bool(np.isfinite(emb.values).all())}")


def section_csv(folder):
    from brdfkit.errors import FormatError
    from brdfkit.io.samples import read_samples, write_samples
    from brdfkit.acquisition.sampling import draw_samples

    path = os.path.join(folder, "million.csv")
    write_samples(path, draw_samples(tables()["mirror"], 1_000_000, seed=3))
    n, sec, peak = _traced(lambda: len(read_samples(path)))
    print(f"  read {n} rows ({os.path.getsize(path) / 1e6:.0f} MB, full precision): {sec:.2f} s, "
          f"peak {peak:.0f} MB traced")
    os.unlink(path)
    path = os.path.join(folder, "rows.csv")
    t0 = time.perf_counter()
    with open(path, "wb") as f:
        f.write(b"theta_h,theta_d,phi_d,r,g,b\n")
        block = b"0.3,0.4,1.0,0.1,0.2,0.3\n" * 100_000
        for _ in range(100):
            f.write(block)
    written = time.perf_counter() - t0
    def outcome():
        try:
            read_samples(path)
            return "ACCEPTED"
        except FormatError as e:
            return str(e).split(": ", 1)[1]

    said, sec, peak = _traced(outcome)
    print(f"  10^7 rows ({os.path.getsize(path) / 1e6:.0f} MB, written in {written:.2f} s): {sec:.2f} s, "
          f"peak {peak:.0f} MB traced: {said}")
    os.unlink(path)


def section_config(folder):
    from brdfkit.errors import FormatError
    from brdfkit.hypernet.network_file import load_network

    _, path, _ = common.untrained_model(folder, config=common.TINY_CONFIG, name="m.safetensors")
    raw = open(path, "rb").read()
    n = int.from_bytes(raw[:8], "little")
    for change in ({"latent_dim": 10**7}, {"decoder_hidden": 20000, "decoder_layers": 30}):
        header = json.loads(raw[8:8 + n])
        cfg = json.loads(header["__metadata__"]["config"])
        cfg.update(change)
        header["__metadata__"]["config"] = json.dumps(cfg)
        new = json.dumps(header).encode()
        new += b" " * (-len(new) % 8)
        crafted = os.path.join(folder, "crafted.safetensors")
        with open(crafted, "wb") as f:
            f.write(len(new).to_bytes(8, "little") + new + raw[8 + n:])
        t0 = time.perf_counter()
        try:
            load_network(crafted, "cpu")
            outcome = "LOADED"
        except FormatError as e:
            outcome = str(e).split(": ", 1)[1]
        print(f"  {change}: {time.perf_counter() - t0:.3f} s: {outcome}")


def _fit(folder, out, steps, **opts):
    from brdfkit import api
    from brdfkit.io.merl import write_merl
    from brdfkit.hypernet.training.loop import fit

    data = os.path.join(folder, "stiff-lib")
    if not os.path.isdir(data):
        os.makedirs(data)
        for name, t in tables().items():
            write_merl(os.path.join(data, f"{name}.binary"), t)
    t0 = time.perf_counter()
    fit(data, out, latent_dim=common.TINY_LATENT, steps=steps, progress=False,
        **{**common.TINY, "batch_materials": 3, **opts})
    return api.load_model(out, "cpu"), time.perf_counter() - t0


def section_train(folder, steps=400):
    import torch

    for opts in ({}, {"grad_clip": 1e12}, {"lr": 1e-2}, {"lr": 1e-2, "grad_clip": 1e12}):
        model, sec = _fit(folder, os.path.join(folder, "t.safetensors"), steps, **opts)
        finite = all(bool(torch.isfinite(p).all()) for p in model.net.parameters())
        big = max(float(p.abs().max()) for p in model.net.parameters())
        m = model.meta
        print(f"  {json.dumps(opts) if opts else 'defaults (clip 1, lr 2e-3)':36s} {steps} steps {sec:5.1f} s: "
              f"skipped {m['skipped_steps']}, final loss {m['final_loss']:.3g} (mapped MSE "
              f"{m['final_mapped_mse']:.3g}), weights finite {finite}, max |w| {big:.3g}")


def section_extrapolate(folder, steps=300):
    import torch

    from brdfkit import api
    from brdfkit.hypernet.mapping import RHO_MAX
    from brdfkit.geometry import grid_hd
    from brdfkit.hypernet.neural_brdf import NeuralBRDF
    from brdfkit.acquisition.sampling import draw_samples

    model, _ = _fit(folder, os.path.join(folder, "x.safetensors"), steps)
    a = api.encode(draw_samples(tables()["mirror"], 400, seed=4), model)
    b = api.encode(draw_samples(tables()["black"], 400, seed=4), model)
    probe = torch.from_numpy(np.ascontiguousarray(grid_hd()[::97]))
    for t in (-1000.0, -100.0, -10.0, -3.0, 0.5, 3.0, 10.0, 100.0, 1000.0):
        nb = NeuralBRDF.from_embedding(model, api.interpolate(a, b, t, allow_extrapolation=True))
        with torch.no_grad():
            peak = float(nb.mapped(probe).max())
        table = nb.to_table()
        v = table[np.isfinite(model.rho_ref).all(-1)]
        print(f"  t = {t:7g}: largest mapped value {peak:8.3g} (expm1 overflows float32 past 88.7), "
              f"decoded max {np.nanmax(v):.3g} 1/sr, at the clamp {int((v == RHO_MAX).sum())} values, "
              f"finite {bool(np.isfinite(v).all())}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("sections", nargs="*", choices=[[]] + SECTIONS, default=[])
    args = ap.parse_args(argv)
    import torch

    torch.set_num_threads(1)
    with tempfile.TemporaryDirectory(prefix="brdfkit-stability-") as folder:
        for name in args.sections or SECTIONS:
            print(f"[{name}]", flush=True)
            fn = globals()[f"section_{name}"]
            fn(folder) if fn.__code__.co_argcount else fn()
            sys.stdout.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main())
