"""Encode and decode of basis and residual embeddings as a user runs them: the whole
process, every second of it in a named stage, against the hardware bound measured in the
same run; and a batch of tables.

For each case (default: teflon with the default built-in and with ``merl80-l40``, a
residual embedding at 39 and 9 numbers, and the default's basis embedding at 39) and one
table (``--table``, default the ``teflon`` proxy, else a synthetic material):

* **processes**: ``brdfkit encode TABLE -m MODEL --kind K --size S`` and ``brdfkit decode``
  of what it wrote, each a fresh process as a user runs it (no thread variable, bytecode
  caches written): wall time and the child's CPU time (user + system), best of
  ``--repeat`` by wall time (every run's in ``encode_runs``, ``decode_runs``);
* **stages of the whole process** (the best run's): the process writes its stages
  (``$BRDFKIT_PROFILE``, :func:`brdfkit.runtime.stage`) and this script adds the two it
  cannot see, so that the stages sum to the wall time measured from outside: ``start``
  (from the fork before the interpreter starts to brdfkit's first line), every stage of
  the command (each first import is ``.../import``), and ``exit`` (from the end of the
  command, the file renamed and the summary printed, to the parent seeing the process
  end: the interpreter's teardown). Each stage has wall and CPU seconds (CPU of every
  thread: a stage on two cores can show up to twice its wall time);
* **the bound**: the plain matrix products of the same sizes, in NumPy, measured in the
  same run (best of ``--repeat``): for a decode, the mapped values ``(P, K) x (K, 3)`` at
  the basis's ``P`` cells (and for a residual its hyponet's products at every cell,
  ``6 -> W -> W -> 1`` a channel); for an encode, the projection's ``(K, P) x (P, K)`` and
  ``(K, P) x (P, 3)`` (and for a residual the hyponet's products, with its ``K`` tangents,
  at the fit's cells, once an iteration);
* **a batch** (``--batch-list``, default ``../shared/data/merl-test.txt``'s 20 materials
  in ``--proxies``; skipped when absent): ``brdfkit encode`` of all of them in one process
  with the default model, with each ``--batch-jobs`` count: seconds a table, wall and CPU
  (every process of the batch).

Wall times follow the machine's load; the record holds the load average at its start and
end. On a loaded machine compare CPU times, and compare them within one run:
``--baseline DIR`` (another revision's ``brdfkit`` package, ``git archive REV brdfkit |
tar -x -C DIR``) runs each process of that revision just before the same one of this
checkout, and records both.

Usage::

    python benchmarks/encode_decode.py [--repeat 3] [--table T.binary] [--cases merl-rgl-l40:basis-39,...]
                                       [--batch-list LIST --proxies DIR --batch-jobs 1 2] [--baseline DIR]
                                       [--json out.json]
"""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
import tempfile
import time

import common

DEFAULT_CASES = ("default:residual-39,default:residual-9,merl80-l40:residual-39,merl80-l40:residual-9,"
                 "default:basis-39")
# A user's shell: no thread count chosen, and Python writes its bytecode caches.
USER_UNSET = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "PYTHONDONTWRITEBYTECODE")


def _process(args, cwd, profile: bool = True, baseline: str | None = None) -> dict:
    """``brdfkit ARGS`` in a fresh process, as a user runs it (no thread variable set):
    ``{"wall_s", "cpu_s", "stages"}``, the stages summing to ``wall_s`` (module
    docstring); ``baseline``: a folder holding another revision's ``brdfkit`` package,
    run instead (first on ``PYTHONPATH``)."""
    env = {k: v for k, v in os.environ.items() if k not in USER_UNSET}
    if baseline:
        env["PYTHONPATH"] = os.pathsep.join([baseline] + ([env["PYTHONPATH"]] if env.get("PYTHONPATH") else []))
    prof = os.path.join(cwd, "stages.json")
    if profile:
        env["BRDFKIT_PROFILE"] = prof
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.time()
    r = subprocess.run([sys.executable, "-c", "import sys; from brdfkit.cli import main; sys.argv[0]='brdfkit'; "
                        "main()", *map(str, args)], cwd=cwd, capture_output=True, text=True, env=env)
    t1 = time.time()
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if r.returncode:
        raise SystemExit(f"brdfkit {' '.join(map(str, args))} failed: {r.stderr[-500:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    out = {"wall_s": t1 - t0, "cpu_s": cpu}
    if profile and os.path.exists(prof):  # (a brdfkit from before $BRDFKIT_PROFILE writes none)
        with open(prof, encoding="utf-8") as f:
            out["stages"] = _whole(json.load(f), t0, t1, cpu)
        os.remove(prof)
    return out


def _whole(rec: dict, t0: float, t1: float, cpu: float) -> list:
    """The process's own stages with its start and exit added: the first stage runs from
    ``t0`` (before the fork) to brdfkit's first line, ``exit`` from the command's end to
    ``t1``; the CPU seconds the process did not see (its teardown) are ``exit``'s."""
    stages = [dict(s) for s in rec["stages"]]
    first_cut = rec["ended"] - sum(s["wall_s"] for s in stages[1:])  # brdfkit's first line
    stages[0]["stage"], stages[0]["wall_s"] = "start: fork, interpreter, brdfkit's first line", first_cut - t0
    stages.append({"stage": "exit: interpreter teardown", "wall_s": t1 - rec["ended"],
                   "cpu_s": max(0.0, cpu - rec["cpu_s"]), "entries": 1})
    for s in stages:
        s["wall_s"], s["cpu_s"] = round(s["wall_s"], 4), round(s["cpu_s"], 4)
    return stages


def _best(fn, repeat):
    best = float("inf")
    for _ in range(repeat):
        t = time.process_time()
        fn()
        best = min(best, time.process_time() - t)
    return best


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
    from brdfkit.runtime import blas_threads

    with blas_threads(1):  # one thread's products, as the encode's own (CPU seconds of one core)
        return _best(lambda: [f() for f in decode], repeat), _best(lambda: [f() for f in encode], repeat)


def _runs(args, tmp, repeat, baseline) -> tuple:
    """``(runs, baseline runs)``: ``repeat`` runs of ``brdfkit ARGS``, each after a run of
    the baseline when there is one (interleaved: both under the same load)."""
    runs, base = [], []
    for _ in range(repeat):
        if baseline:
            base.append(_process(args, tmp, baseline=baseline))
        runs.append(_process(args, tmp))
    return runs, base


def _pairs(runs) -> list:
    return [[round(r["wall_s"], 3), round(r["cpu_s"], 3)] for r in runs]


def _case(spec, table_path, repeat, tmp, baseline=None):
    from brdfkit.embeddings import choose_decoder
    from brdfkit.models.builtin import default_bundle

    model, kind_size = spec.split(":")
    model = default_bundle().name if model == "default" else model
    kind, size = kind_size.rsplit("-", 1)
    size = int(size)
    enc_args = ["encode", table_path, "-m", model, "--kind", kind, "--size", size, "-o", tmp]
    emb = os.path.join(tmp, os.path.splitext(os.path.basename(table_path))[0] + ".emb")
    dec_args = ["decode", emb, "-o", os.path.join(tmp, "decoded.binary")]
    enc_runs, enc_base = _runs(enc_args, tmp, repeat, baseline)
    dec_runs, dec_base = _runs(dec_args, tmp, repeat, baseline)  # the current revision's .emb
    enc, dec_p = (min(runs, key=lambda x: x["wall_s"]) for runs in (enc_runs, dec_runs))
    dec = choose_decoder(kind, model, size=size)
    basis = dec.obj.basis if kind == "residual" else dec.obj
    bound_dec, bound_enc = _bounds(dec, basis.leading(size // 3), kind, repeat)
    return {"case": f"{model}:{kind}-{size}", "encode_wall_s": enc["wall_s"], "encode_cpu_s": enc["cpu_s"],
            "encode_runs": _pairs(enc_runs), "decode_runs": _pairs(dec_runs),
            **({"baseline_encode_runs": _pairs(enc_base), "baseline_decode_runs": _pairs(dec_base),
                "baseline_encode_cpu_s": min(r["cpu_s"] for r in enc_base),
                "baseline_decode_cpu_s": min(r["cpu_s"] for r in dec_base),
                "encode_cpu_s_min": min(r["cpu_s"] for r in enc_runs),
                "decode_cpu_s_min": min(r["cpu_s"] for r in dec_runs)} if baseline else {}),
            "decode_wall_s": dec_p["wall_s"], "decode_cpu_s": dec_p["cpu_s"], "encode_bound_s": bound_enc,
            "decode_bound_s": bound_dec, "encode_to_bound": enc["wall_s"] / bound_enc,
            "decode_to_bound": dec_p["wall_s"] / bound_dec, "encode_stages": enc.get("stages"),
            "decode_stages": dec_p.get("stages"),
            "accounted": round(sum(s["wall_s"] for s in enc["stages"]) / enc["wall_s"], 4) if "stages" in enc else None}


def _batch(list_path, proxies, jobs_counts, tmp, baseline=None) -> list:
    """Seconds a table of one ``brdfkit encode`` of every listed table, per ``--jobs`` (the
    baseline's run before each, when there is one)."""
    with open(list_path, encoding="utf-8") as f:
        names = f.read().split()
    paths = [os.path.abspath(os.path.join(proxies, f"{n}.binary")) for n in names]
    if not all(os.path.exists(p) for p in paths):
        print(f"batch skipped: not every table of {list_path} is in {proxies}", file=sys.stderr)
        return []
    out = []
    for jobs in jobs_counts:
        args = ["encode", *paths, "-o", os.path.join(tmp, f"batch{jobs}"), "--jobs", jobs]
        base = _process(args, tmp, profile=False, baseline=baseline) if baseline else None
        r = _process(args, tmp, profile=jobs == 1)
        row = {"tables": len(paths), "jobs": jobs, "wall_s_a_table": r["wall_s"] / len(paths),
               "cpu_s_a_table": r["cpu_s"] / len(paths), "wall_s": r["wall_s"], "cpu_s": r["cpu_s"]}
        if base:
            row.update(baseline_wall_s_a_table=base["wall_s"] / len(paths),
                       baseline_cpu_s_a_table=base["cpu_s"] / len(paths))
        if "stages" in r:
            row["stages"] = r["stages"]
        out.append(row)
    return out


def _top(stages, n=4) -> str:
    """The ``n`` costliest stages by wall time, with their share."""
    total = sum(s["wall_s"] for s in stages)
    top = sorted(stages, key=lambda s: -s["wall_s"])[:n]
    return ", ".join(f"{s['stage'].replace('encode/', '')} {s['wall_s'] / total:.0%}" for s in top)


def main(argv=None):
    ap = common.timing_parser(__doc__, 3)
    ap.add_argument("--table", default=os.path.join("proxies", "merl", "teflon.binary"))
    ap.add_argument("--cases", default=DEFAULT_CASES, help="MODEL:KIND-SIZE entries, comma-separated")
    ap.add_argument("--batch-list", default=os.path.join("..", "shared", "data", "merl-test.txt"),
                    help="names of the batch's tables, one a line ('' for no batch)")
    ap.add_argument("--proxies", default=os.path.join("proxies", "merl"), help="folder of the batch's NAME.binary")
    ap.add_argument("--batch-jobs", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--baseline", default=None,
                    help="a folder holding another revision's brdfkit package (git archive REV brdfkit | tar -x -C "
                         "DIR): each process of it runs just before the same one of this checkout, and both are "
                         "recorded (a before/after comparison under the same load)")
    ap.add_argument("--baseline-label", default=None, help="what the record calls the baseline (its revision)")
    a = ap.parse_args(argv)
    load0, t0 = common.load_average(), time.time()
    with tempfile.TemporaryDirectory() as tmp:
        table_path = os.path.abspath(a.table)
        if not os.path.exists(table_path):  # no proxies: a synthetic material
            from brdfkit.io.merl import write_merl
            from brdfkit.materials import synthetic

            table_path = os.path.join(tmp, "synthetic.binary")
            write_merl(table_path, synthetic.table(synthetic.STIFF[1]))
        base = os.path.abspath(a.baseline) if a.baseline else None
        results = [_case(spec, table_path, a.repeat, tmp, base) for spec in a.cases.split(",")]
        batch = _batch(a.batch_list, a.proxies, a.batch_jobs, tmp, base) if a.batch_list and os.path.exists(
            a.batch_list) else []
    cols = ["case", "encode wall s", "encode CPU s", "bound s", "decode wall s", "decode CPU s", "bound s",
            "encode: largest stages (wall)"]
    table = [[r["case"], r["encode_wall_s"], r["encode_cpu_s"], r["encode_bound_s"], r["decode_wall_s"],
              r["decode_cpu_s"], r["decode_bound_s"], _top(r["encode_stages"]) if r["encode_stages"] else ""]
             for r in results]
    table += [[f"batch of {b['tables']}, --jobs {b['jobs']} (a table)", b["wall_s_a_table"], b["cpu_s_a_table"],
               "", "", "", "", _top(b["stages"]) if "stages" in b else ""] for b in batch]
    if base:
        cols += ["baseline encode CPU s (best)", "this encode CPU s (best)", "baseline decode CPU s", "this decode CPU s"]
        for row, r in zip(table, results):
            row += [r["baseline_encode_cpu_s"], r["encode_cpu_s_min"], r["baseline_decode_cpu_s"],
                    r["decode_cpu_s_min"]]
        for row, b in zip(table[len(results):], batch):
            row += [b["baseline_cpu_s_a_table"], b["cpu_s_a_table"], "", ""]
    label = a.baseline_label or (os.path.basename(os.path.normpath(a.baseline)) if a.baseline else None)
    record = common.write_record({"cases": results, "batch": batch, "baseline": label,
                                  "table": os.path.relpath(table_path) if a.table in table_path else "synthetic"},
                                 None, load0, t0)
    common.report("encode_decode", "Encode and decode as whole processes, every second in a stage", cols, table,
                  record, a.json)


if __name__ == "__main__":
    main()
