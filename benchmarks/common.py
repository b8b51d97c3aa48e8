"""Helpers shared by the benchmarks: machine description, best-of-k timing interleaved with
a bound, plain-``mm`` reference chains, the JSON + table report every performance
benchmark prints (issue 7), a run's record written with its machine and load
(``write_record``), reference-scene renders of tables, and untrained models (the paper's
architecture or the tiny one of the test suite).

Benchmarks run as ``python benchmarks/NAME.py`` from the repository root with brdfkit
installed; Python puts the script's folder on ``sys.path``, so ``import common`` finds
this module. The studies of ``benchmarks/studies/`` put this folder on ``sys.path``
themselves. Benchmarks import nothing from ``tests/``.

Every figure a benchmark reports sits beside a *bound* measured in the same process, in
the same rounds (measurement and bound alternate, ``best-of-k`` of each), so that the
load other jobs put on a shared machine affects both alike. Not part of the test suite.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)


def load_average() -> list[float]:
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except OSError:
        return []


def machine() -> dict:
    """CPU model (``lscpu``), cores, load average, torch version and threads."""
    model = platform.processor() or ""
    try:
        out = subprocess.run(["lscpu"], capture_output=True, text=True, timeout=10).stdout
        for line in out.splitlines():
            if line.lower().startswith("model name"):
                model = line.split(":", 1)[1].strip()
    except (OSError, subprocess.SubprocessError):
        pass
    info = {"cpu_model": model, "cpus": os.cpu_count(), "load_average": load_average(),
            "python": platform.python_version(), "time_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
    if "torch" in sys.modules:
        torch = sys.modules["torch"]
        info["torch"] = torch.__version__
        info["torch_threads"] = torch.get_num_threads()
    return info


def write_record(record: dict, path: str | None, load_start: list[float], t0: float) -> dict:
    """Complete a run's ``record`` with the machine (:func:`machine`), the load average at
    its start (``load_start``) and now, and the wall seconds since ``t0`` (``time.time()``),
    then write it to ``path`` when given: indented JSON through a temporary file and a
    rename, so that a run that writes after each job keeps its last whole record. Returns
    ``record``."""
    record.update(machine=machine(), load_start=load_start, load_end=load_average(),
                  seconds=round(time.time() - t0, 1))
    if path:
        with open(path + ".tmp", "w") as f:
            json.dump(record, f, indent=1)
            f.write("\n")
        os.replace(path + ".tmp", path)
    return record


def best_of(fns: dict, k: int, warmup: int = 1) -> dict:
    """Best (minimum) wall time in seconds of each callable, over ``k`` interleaved rounds.

    Interleaving (``a, b, a, b, ...``) rather than ``a x k, b x k`` puts a measurement and
    its bound under the same background load. Also returns the median per callable
    under ``"<name>_median"``.
    """
    for _ in range(warmup):
        for fn in fns.values():
            fn()
    times = {n: [] for n in fns}
    for _ in range(k):
        for n, fn in fns.items():
            t = time.perf_counter()
            fn()
            times[n].append(time.perf_counter() - t)
    out = {}
    for n, ts in times.items():
        ts = sorted(ts)
        out[n] = ts[0]
        out[n + "_median"] = ts[len(ts) // 2]
    return out


def mm_chain(layer_shapes, rows: int, block: int, device="cpu", feature_major: bool = True):
    """A plain ``torch.mm`` chain with the FLOP count of an MLP, run in row blocks.

    Parameters
    ----------
    layer_shapes
        ``[(in, out), ...]`` of the MLP's layers.
    rows
        Rows (samples, cells) pushed through it.
    block
        Rows per block (``rows`` for one unblocked pass).
    feature_major
        Activations ``(features, block)`` and ``W^T h`` (as the dense decode keeps
        them), else ``(block, features)`` and ``h W``.

    Returns
    -------
    tuple
        ``(fn, flops)``: a callable running the whole chain once (no bias, no
        activation function, preallocated outputs: nothing but the matrix products), and
        its floating-point operation count ``2 sum(rows in out)``.
    """
    import torch

    g = torch.Generator().manual_seed(0)
    ws = [torch.randn(i, o, generator=g).to(device) / i ** 0.5 for i, o in layer_shapes]
    if feature_major:
        ws = [w.t().contiguous() for w in ws]
    x = torch.randn(rows, layer_shapes[0][0], generator=g).to(device)
    if feature_major:
        x = x.t().contiguous()
    b = min(block, rows)
    bufs = [torch.empty((o, b) if feature_major else (b, o), device=device) for _, o in layer_shapes]
    tail = rows % b
    tail_bufs = [torch.empty((o, tail) if feature_major else (tail, o), device=device)
                 for _, o in layer_shapes] if tail else None

    def run():
        with torch.inference_mode():
            for s in range(0, rows, b):
                e = min(rows, s + b)
                out = bufs if e - s == b else tail_bufs
                h = x[:, s:e] if feature_major else x[s:e]
                for w, o in zip(ws, out):
                    h = torch.mm(w, h, out=o) if feature_major else torch.mm(h, w, out=o)
        if device != "cpu" and torch.cuda.is_available():
            torch.cuda.synchronize()

    flops = 2 * rows * sum(i * o for i, o in layer_shapes)
    return run, flops


def peak_gemm(device="cpu", n: int = 256, reps: int = 40, k: int = 5) -> float:
    """fp32 FLOP/s of a cache-resident square ``mm`` (``n x n x n``), best of ``k``: the
    compute ceiling of this machine under its current load, for context."""
    import torch

    a = torch.randn(n, n, device=device)
    b = torch.randn(n, n, device=device)
    c = torch.empty(n, n, device=device)

    def run():
        for _ in range(reps):
            torch.mm(a, b, out=c)

    t = best_of({"mm": run}, k)["mm"]
    return 2.0 * n ** 3 * reps / t


def report(name: str, title: str, columns: list[str], rows: list[list], data: dict,
           json_path: str | None = None) -> None:
    """Print a Markdown table, then the JSON (one line, prefixed ``JSON``); also write the
    JSON to ``json_path`` when given."""
    print(f"## {title}")
    print()
    print("| " + " | ".join(columns) + " |")
    print("|" + "|".join([" --- "] * len(columns)) + "|")
    for r in rows:
        print("| " + " | ".join(_fmt(v) for v in r) + " |")
    print()
    data = {"benchmark": name, **data}
    text = json.dumps(data, sort_keys=True)
    print("JSON " + text)
    sys.stdout.flush()
    if json_path:
        with open(json_path, "w") as f:
            f.write(json.dumps(data, indent=1, sort_keys=True) + "\n")


def _fmt(v) -> str:
    if isinstance(v, float):
        if v != v:
            return "-"
        if abs(v) >= 100:
            return f"{v:,.0f}"
        if abs(v) >= 1:
            return f"{v:.3g}"
        return f"{v:.3g}"
    return str(v)


def table_renderer(px: int):
    """``img(table)``: the quadrature render of a ``(90, 90, 180, 3)`` table (1/sr) in the
    reference scene at ``px`` pixels square, float32 ``(px, px, 3)``, on the CPU: what
    the benchmarks' and studies' render PSNRs compare."""
    from brdfkit.render.renderable import TableBRDF
    from brdfkit.render.envmap import reference_envmap
    from brdfkit.render.quadrature import render
    from brdfkit.render.scene import Scene

    scene, env = Scene(resolution=px), reference_envmap()
    return lambda table: render(TableBRDF(table, device="cpu"), scene, env=env)[0]


def timing_parser(doc: str, repeat: int) -> argparse.ArgumentParser:
    """The command line of a timing benchmark: the first paragraph of ``doc`` as its
    description, and the options they share, ``--threads`` (torch threads, default 1),
    ``--repeat`` (rounds, default ``repeat``) and ``--json`` (also write the report's
    JSON there); the benchmark adds its own."""
    ap = record_options(argparse.ArgumentParser(description=doc.split("\n\n")[0]))
    ap.add_argument("--repeat", type=int, default=repeat, help="rounds (best of)")
    return ap


def record_options(ap: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """``ap`` with the two options of every script that writes a record: ``--threads``
    (torch threads, default 1; :func:`set_threads`) and ``--json`` (also write the JSON
    there; :func:`write_record`)."""
    ap.add_argument("--threads", type=int, default=1, help="torch threads")
    ap.add_argument("--json", default=None, help="also write the JSON here")
    return ap


def set_threads(n: int | None):
    import torch

    if n:
        torch.set_num_threads(n)
    return torch.get_num_threads()


# The test suite's tiny models (``tests/conftest.py``; copied, not imported): a hypernetwork
# whose dense encode or decode takes a fraction of a second, and ``fit`` options that train
# one in seconds on one core, with latent dimension ``TINY_LATENT``.
TINY_CONFIG = dict(latent_dim=7, encoder_hidden=(16, 16), hypo_hidden=8, hypo_layers=2,
                   decoder_hidden=16, decoder_layers=1)
TINY = dict(query_size=512, context_min=50, context_max=400, hypo_hidden=32, decoder_hidden=64,
            encoder_hidden=(64, 64), lr=2e-3, warmup_steps=20, lr_schedule="constant")
TINY_LATENT = 8


def untrained_model(tmpdir: str, latent_dim: int = 40, device="cpu", config: dict | None = None,
                    name: str = "untrained.safetensors"):
    """A model with random weights (speed does not depend on the weights) and the
    reference table of a synthetic material (``stiff-white``), whose measured cells are
    the 1,111,432 cells above the horizon of a MERL table; saved and loaded through the
    model file like a trained one.

    The paper's default architecture with ``latent_dim``, or the ``HyperConfig`` fields
    ``config`` (e.g. :data:`TINY_CONFIG`). Returns ``(model, path, reference table)``.
    """
    import torch

    from brdfkit import api
    from brdfkit.materials import synthetic
    from brdfkit.hypernet.network import HyperBRDF, HyperConfig
    from brdfkit.hypernet.network_file import save_network

    table = synthetic.table(synthetic.STIFF[2])
    torch.manual_seed(0)
    path = os.path.join(tmpdir, name)
    cfg = HyperConfig(**config) if config is not None else HyperConfig(latent_dim=latent_dim)
    save_network(path, HyperBRDF(cfg), table, {"materials": ["stiff-white"], "steps": 0})
    return api.load_model(path, device=device), path, table
