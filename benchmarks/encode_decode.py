"""Encode and decode of basis and residual embeddings as a user runs them, against the
hardware bound measured in the same run, and where the rest of the time goes.

Issue 44, item 5. For each case (default: the default built-in's basis at 39 and 9
numbers, ``merl80-l40``'s residual at 39 and 9) and one table (``--table``, default the
``teflon`` proxy, else a synthetic material):

* **processes**: ``brdfkit encode TABLE -m MODEL --kind K --size S`` and ``brdfkit decode``
  of what it wrote, each a fresh process as a user runs it: wall time and the child's
  CPU time (user + system), best of ``--repeat``;
* **stages**, in this process (CPU time, best of ``--repeat``; the caches a process
  keeps, the objective scenes' pairs and the model, are cleared before each round, so a
  stage costs what it costs a process): reading the table, loading the model, the
  projection, the objective scenes' pairs, the table's views of them (lookups, pair
  draws), the sparse maps of the refinement, the fit through the correction (residual),
  the refinement (its iterations and held-out checks, the candidates' held-out errors);
  decode: the decode and the MERL file written;
* **the bound**: the plain matrix products of the same sizes, in NumPy, measured in the
  same run (best of ``--repeat``): for a decode, the mapped values ``(P, K) x (K, 3)`` at
  the basis's ``P`` cells (and for a residual its hyponet's products at every cell,
  ``6 -> W -> W -> 1`` a channel); for an encode, the projection's ``(K, P) x (P, K)`` and
  ``(K, P) x (P, 3)`` (and for a residual the hyponet's products, with its ``K`` tangents,
  at the fit's cells, once an iteration).

The record holds, per case, the process times, the stages sorted by cost with their
share of the in-process total, the bound, and the ratio of the process to the bound:
what is left is start-up, file reading and writing, and the refinement's small sparse
products, which no dense product bounds (``docs/notes/performance.md``).

Usage::

    python benchmarks/encode_decode.py [--repeat 3] [--table T.binary] [--cases merl-rgl-l40:basis-39,...]
                                       [--json out.json]
"""

from __future__ import annotations

import os
import resource
import subprocess
import sys
import tempfile
import time

import common

DEFAULT_CASES = "default:basis-39,default:basis-9,merl80-l40:residual-39,merl80-l40:residual-9"


def _process(args, cwd):
    """``(wall, cpu)`` seconds of ``brdfkit ARGS`` in a fresh process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t = time.perf_counter()
    r = subprocess.run([sys.executable, "-c", "import sys; from brdfkit.cli import main; sys.argv[0]='brdfkit'; "
                        "main()", *map(str, args)], cwd=cwd, capture_output=True, text=True)
    wall = time.perf_counter() - t
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if r.returncode:
        raise SystemExit(f"brdfkit {' '.join(map(str, args))} failed: {r.stderr[-500:]}")
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def _best(fn, repeat):
    best = float("inf")
    for _ in range(repeat):
        t = time.process_time()
        fn()
        best = min(best, time.process_time() - t)
    return best


def _clear():
    from brdfkit.embeddings import decoders
    from brdfkit.render import quadrature, screen

    decoders._loaded.cache_clear()
    screen._SCREENS.clear()
    quadrature.clear_cache()


def _stages(table_path, model, kind, size, repeat):
    """CPU seconds of each stage of an encode and a decode (module docstring)."""
    import numpy as np

    from brdfkit.basis.refine_on_screen import prepare_screens, refine_coefficients
    from brdfkit.embeddings import choose_decoder
    from brdfkit.io.merl import read_merl, write_merl
    from brdfkit.render.objective import ObjectiveConfig, objective_views
    from brdfkit.render.scene_suite import scene_env
    from brdfkit.render import screen as screen_mod
    from brdfkit.runtime import blas_threads

    cfg = ObjectiveConfig(steps=8)
    out = {}
    out["read table"] = _best(lambda: read_merl(table_path), repeat)
    table = read_merl(table_path)

    def load():
        _clear()
        return choose_decoder(kind, model, size=size)

    out["load model"] = _best(load, repeat)
    dec = load()
    basis = dec.obj.basis if kind == "residual" else dec.obj
    part = basis.leading(size // 3)
    with blas_threads(1):
        out["projection"] = _best(lambda: part.project(table), repeat)
        c0 = part.project(table)

        def screens():
            screen_mod._SCREENS.clear()
            return [screen_mod.screen(None, cfg.resolution, env=scene_env(s)) for s in cfg.scenes]

        out["objective scenes' pairs"] = _best(screens, repeat)
        out["views (lookups, draws)"] = _best(lambda: objective_views(table, cfg), repeat)
        out["refinement maps"] = _best(lambda: prepare_screens(part, table, cfg), repeat) - out["views (lookups, draws)"]
        sc = prepare_screens(part, table, cfg)
        if kind == "residual":
            from brdfkit.residual.encoding import fit_through

            out["fit through the correction"] = _best(
                lambda: fit_through(dec.obj, part.mapped_table(table), c0), repeat)
        out["refinement (iterations, held-out checks)"] = _best(
            lambda: refine_coefficients(part, table, c0, cfg, screens=sc), repeat)
    c, _ = refine_coefficients(part, table, c0, cfg, screens=sc)
    gain = 1.0 if kind == "residual" else None
    decode = (lambda: dec.obj.decode(c, gain)) if gain else (lambda: part.decode(c))
    dec_out = {"decode": _best(decode, repeat)}
    with tempfile.TemporaryDirectory() as tmp:
        t = decode()
        dec_out["write MERL file"] = _best(lambda: write_merl(os.path.join(tmp, "x.binary"), t), repeat)
    dec_out["load model"] = out["load model"]
    return out, dec_out, (dec, part, np.asarray(c))


def _bounds(dec, part, kind, repeat):
    """CPU seconds of the plain products a decode and an encode cannot do without."""
    import numpy as np

    rng = np.random.default_rng(0)
    k, p = part.n_components, part.cells.size
    comp = rng.standard_normal((p, k)).astype(np.float32)
    c = rng.standard_normal((k, 3)).astype(np.float32)
    b = rng.standard_normal((p, 3)).astype(np.float64)
    comp64 = comp.T.astype(np.float64)
    decode = [lambda: comp @ c]
    encode = [lambda: comp64 @ comp64.T, lambda: comp64 @ b]
    if kind == "residual":
        from brdfkit.residual.encoding import FIT_CELLS

        _, cfg, _ = dec.obj.net_for(k)
        w = cfg.width
        ws = [rng.standard_normal(s).astype(np.float32) for s in ((6, w), (w, w), (w, 1))]
        block = 16384

        def chain(rows, tangents=0):
            x = rng.standard_normal((block, 6)).astype(np.float32)
            for s in range(0, rows, block):
                h = x @ ws[0]
                h = h @ ws[1]
                if tangents:
                    np.repeat(h, tangents, axis=0).reshape(-1, w) @ ws[1]
                h @ ws[2]

        for _ in range(3):  # a channel each
            decode.append(lambda: chain(p))
            encode.append(lambda: chain(FIT_CELLS, k))
    return _best(lambda: [f() for f in decode], repeat), _best(lambda: [f() for f in encode], repeat)


def _case(spec, table_path, repeat, tmp):
    from brdfkit.models.builtin import default_bundle

    model, kind_size = spec.split(":")
    model = default_bundle().name if model == "default" else model
    kind, size = kind_size.rsplit("-", 1)
    size = int(size)
    enc_args = ["encode", table_path, "-m", model, "--kind", kind, "--size", size, "-o", tmp]
    emb = os.path.join(tmp, os.path.splitext(os.path.basename(table_path))[0] + ".emb")
    dec_args = ["decode", emb, "-o", os.path.join(tmp, "decoded.binary")]
    enc_p = min((_process(enc_args, tmp) for _ in range(repeat)), key=lambda x: x[0])
    dec_p = min((_process(dec_args, tmp) for _ in range(repeat)), key=lambda x: x[0])
    stages, dec_stages, (dec, part, _) = _stages(table_path, model, kind, size, repeat)
    bound_dec, bound_enc = _bounds(dec, part, kind, repeat)
    row = {"case": f"{model}:{kind}-{size}", "encode_wall_s": enc_p[0], "encode_cpu_s": enc_p[1],
           "decode_wall_s": dec_p[0], "decode_cpu_s": dec_p[1], "encode_bound_s": bound_enc,
           "decode_bound_s": bound_dec, "encode_to_bound": enc_p[0] / bound_enc, "decode_to_bound": dec_p[0] / bound_dec}
    for name, st in (("encode", stages), ("decode", dec_stages)):
        total = sum(st.values())
        row[f"{name}_stages_s"] = {k: round(v, 4) for k, v in sorted(st.items(), key=lambda kv: -kv[1])}
        row[f"{name}_stages_share"] = {k: round(v / total, 3) for k, v in row[f"{name}_stages_s"].items()}
    return row


def main(argv=None):
    ap = common.timing_parser(__doc__, 3)
    ap.add_argument("--table", default=os.path.join("proxies", "merl", "teflon.binary"))
    ap.add_argument("--cases", default=DEFAULT_CASES, help="MODEL:KIND-SIZE entries, comma-separated")
    a = ap.parse_args(argv)
    load0, t0 = common.load_average(), time.time()
    with tempfile.TemporaryDirectory() as tmp:
        table_path = os.path.abspath(a.table)
        if not os.path.exists(table_path):  # no proxies: a synthetic material
            from brdfkit.io.merl import write_merl
            from brdfkit.materials import synthetic

            table_path = os.path.join(tmp, "synthetic.binary")
            write_merl(table_path, synthetic.table(synthetic.STIFF[1]))
        results = [_case(spec, table_path, a.repeat, tmp) for spec in a.cases.split(",")]
    cols = ["case", "encode wall s", "encode CPU s", "bound s", "x bound", "decode wall s", "decode CPU s", "bound s",
            "x bound", "encode: largest stages"]
    table = [[r["case"], r["encode_wall_s"], r["encode_cpu_s"], r["encode_bound_s"], r["encode_to_bound"],
              r["decode_wall_s"], r["decode_cpu_s"], r["decode_bound_s"], r["decode_to_bound"],
              ", ".join(f"{k} {v:.0%}" for k, v in list(r["encode_stages_share"].items())[:3])] for r in results]
    record = common.write_record({"cases": results, "table": os.path.relpath(table_path) if a.table in table_path
                                  else "synthetic"}, None, load0, t0)
    common.report("encode_decode", "Encode and decode against the bound (issue 44 item 5)", cols, table, record,
                  a.json)


if __name__ == "__main__":
    main()
