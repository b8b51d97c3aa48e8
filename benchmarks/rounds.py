"""Measuring in rounds against one-shot plans (issue 57): what 8 and 16 samples chosen for
a material in rounds (``brdfkit plan -n K --given SO_FAR``) render against the same
counts planned at once (``brdfkit plan -n K``), 40 uniform samples and IPCA-8.

For each material (``--materials``, or the names of ``--list`` in ``--data``) and the
model ``-m`` (default ``merl80-l40``), each *row* is a set of samples of the material's
table and a reconstruction from it, scored by renders:

* ``planned-4``, ``planned-8``, ``planned-16``: one-shot plans
  (:func:`brdfkit.acquisition.planning.plan_directions`, the default ``render`` design,
  seed 0; the plan does not depend on the material: made once), measured on the table
  (:func:`~brdfkit.acquisition.sampling.measure_samples`);
* ``rounds-4+4``, ``rounds-4+4+4``, ``rounds-4+4+4+4``, ``rounds-8+8``: plan ``K`` ->
  measure -> plan ``K`` given all the samples so far (``plan_directions(..., given=)``)
  -> measure ... (``docs/planning.md``, "Measuring in rounds"); the first round is the
  one-shot plan of ``K``, and each longer run of rounds of 4 continues the shorter one;
* ``uniform-40-sS``: ``brdfkit sample -n 40 --seed S`` (``draw_samples``), ``--seeds``;

each reconstructed by ``brdfkit sparse``'s default (the learnt prior of ``-m``), and
``ipca-planned-16``, ``ipca-rounds-8+8``: IPCA-8 (``--method ipca``, the built-in's basis,
Nielsen's 8 leading components) from those samples. Every reconstruction is rendered at
``--resolution`` pixels in the six judged scenes (``--scenes all``) beside the table's own
(cached) render and scored as ``brdfkit bench`` scores it
(:meth:`brdfkit.bench.worker.Worker.score`: PSNR and Delta E 2000 of each scene, their
means, the BRDF log RMSE).

Seconds are what a user waits, in a process that has planned and fitted once before (the
model loaded, its caches filled): each plan's (``plan_s``, summed over a row's rounds) and
the fit's (``fit_s``), wall and CPU; measuring is the instrument's time and is not
counted. The one-shot plans are timed once each, cold (without the render metric a
process keeps per basis, as the first plan of a ``brdfkit plan`` process computes it),
and counted in every row that uses them, though a lab makes them once for every
material. A whole ``brdfkit plan`` process adds its start, imports and the model's load
(``benchmarks/commands.py``).

The expected screen error the rounds' plans print (``plan.describe()``: before -> after,
:mod:`brdfkit.acquisition.rounds`) is recorded with every given plan, and for every row
of the learnt prior the expected error after the row's samples (``expected``: what
``brdfkit plan --given SAMPLES`` prints first, the ``before``; from a round's plan given
the same samples, else from a plan of one direction), to see whether it tracks the
renders.

``--real FILE`` (default: ``../shared/data/real/cornell/acryl_blue.brdf``; ``--real ''``
skips it) runs the same rows on real measurements, judged by held-out error
(:mod:`brdfkit.evaluation.holdout`: ``--holdout`` of the samples held out by each seed,
the log RMSE at their directions): ``planned-8``, ``planned-16`` (``plan --within`` the
rest), ``rounds-4+4``, ``rounds-8+8``, ``rounds-4+4+4+4`` (``--within`` and ``--given``)
and random subsets of 8, 16 and 40 of the rest (the first ``N`` of its random order, as
``brdfkit validate -n N`` takes them), for each seed.

    python benchmarks/rounds.py --resolution 128 \\
        --json benchmarks/results/2026-12-01-rounds-128.json

Prints the markdown table of the means (of the six scenes, each scene, Delta E, seconds).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import common  # noqa: E402

ROUNDS = {"rounds-4+4": (4, 2), "rounds-4+4+4": (4, 3), "rounds-4+4+4+4": (4, 4), "rounds-8+8": (8, 2)}
"""Row -> (directions a round, rounds)."""


def _materials(a) -> list:
    if a.materials:
        return [m.strip() for m in a.materials.split(",") if m.strip()]
    with open(a.list, encoding="utf-8") as f:
        names = [line.split("#")[0].strip() for line in f]
    names = [n for n in names if n]
    return names[:a.limit] if a.limit else names


def _timed(fn):
    """``(result, wall seconds, CPU seconds)`` of ``fn()``."""
    t0, c0 = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - t0, time.process_time() - c0


def _brief(score: dict) -> dict:
    return {"psnr": score["psnr"], "delta_e": score["delta_e"], "log_rmse": score["log_rmse"],
            "scenes": {s: {"psnr": v["psnr"], "delta_e": v["delta_e"]} for s, v in score["scenes"].items()}}


class Planner:
    """The model's plan target, the learnt prior and IPCA-8, loaded once; plans and fits
    timed."""

    def __init__(self, model: str, device: str):
        from brdfkit.acquisition.planning import plan_target
        from brdfkit.methods import METHODS
        from brdfkit.methods.choice import choose

        self.target = plan_target(model)
        self.prior = self.target.prior
        ipca = choose("ipca", model)
        self.ipca = METHODS["ipca"].load(ipca.path, device)
        self.device = device
        self.one_shot: dict = {}
        self.before: dict = {}  # samples digest -> the expected error a plan given them started from

    def plan(self, n: int, given=None, within=None, cold: bool = False):
        """A plan of ``n`` directions, timed. ``cold``: without the render metric a
        process keeps per basis (``optimal_design._METRICS``), as the first plan of a
        ``brdfkit plan`` process computes it."""
        from brdfkit.acquisition import optimal_design
        from brdfkit.acquisition.planning import plan_directions

        if cold:
            optimal_design._METRICS.clear()
        out = _timed(lambda: plan_directions(self.target, n, given=given, within=within))
        if given is not None and within is None:
            self.before[given.digest()] = float(out[0].expected_error[0])
        return out

    def fit(self, samples, method: str = "prior"):
        from brdfkit import api

        model = self.prior if method == "prior" else self.ipca
        return _timed(lambda: api.sparse(samples, model, method=method, device=self.device)[0])

    def expected(self, samples) -> float:
        """The expected screen error after ``samples`` as ``brdfkit plan -n 1 --given``
        prints it first (before its one direction); taken from a round's plan given the
        same samples when there was one."""
        key = samples.digest()
        if key not in self.before:
            self.plan(1, given=samples)
        return self.before[key]


def _plan_info(plan, wall, cpu) -> dict:
    out = {"n": len(plan), "plan_s": round(wall, 3), "plan_cpu_s": round(cpu, 3), "cells": plan.cells.tolist(),
           "condition_number": plan.condition_number, "describe": plan.describe()}
    if plan.expected_error is not None:
        out["expected_error"] = [float(e) for e in plan.expected_error]
    return out


def sample_sets(p: Planner, table, name: str, seeds) -> list:
    """``[(row, samples, plan seconds, plan CPU seconds, [plan info of each given round])]``
    of one material (module docstring)."""
    from brdfkit.acquisition.sampling import draw_samples, join_samples, measure_samples

    out = []
    for k in (4, 8, 16):
        plan, wall, cpu = p.one_shot[k]
        out.append((f"planned-{k}", measure_samples(table, plan.directions, name), wall, cpu, []))
    done = {}
    for row, (k, count) in ROUNDS.items():
        prev = f"rounds-{'+'.join([str(k)] * (count - 1))}"
        if prev in done:  # a longer run of rounds continues the shorter one
            samples, wall, cpu, infos = done[prev]
            infos = list(infos)
        else:
            plan, wall, cpu = p.one_shot[k]
            samples, infos = measure_samples(table, plan.directions, name), []
        for _ in range(count - 1 - len(infos)):
            plan, w, c = p.plan(k, given=samples)
            infos.append(_plan_info(plan, w, c))
            wall, cpu = wall + w, cpu + c
            samples = join_samples(samples, measure_samples(table, plan.directions, name), source=name)
        done[row] = (samples, wall, cpu, infos)
        out.append((row, samples, wall, cpu, infos))
    for s in seeds:
        out.append((f"uniform-40-s{s}", draw_samples(table, 40, seed=s, source=name), 0.0, 0.0, []))
    return out


def run_material(p: Planner, worker, data: str, name: str, seeds, expected: bool) -> list:
    from brdfkit.io.merl import read_merl

    path = os.path.join(data, name + ".binary")
    table = read_merl(path)
    refs = worker.reference(name, path, table)
    records = []
    sets = sample_sets(p, table, name, seeds)
    by_row = {row: (samples, wall, cpu) for row, samples, wall, cpu, _ in sets}
    jobs = [(row, "prior", row, info) for row, _, _, _, info in sets]
    jobs += [("ipca-planned-16", "ipca", "planned-16", []), ("ipca-rounds-8+8", "ipca", "rounds-8+8", [])]
    for label, method, source, infos in jobs:
        samples, plan_s, plan_cpu = by_row[source]
        recon, fit_s, fit_cpu = p.fit(samples, method)
        rec = {"material": name, "row": label, "method": method, "samples_of": source, "n": len(samples),
               "samples_digest": samples.digest(), "plan_s": round(plan_s, 3), "plan_cpu_s": round(plan_cpu, 3),
               "fit_s": round(fit_s, 3), "fit_cpu_s": round(fit_cpu, 3), "time_s": round(plan_s + fit_s, 3)}
        score = worker.score(recon, table, refs)
        rec.update(_brief(score), render_s=round(score["render_s"], 2))
        if infos:
            rec["rounds"] = infos
        if expected and method == "prior":
            rec["expected"] = p.expected(samples)
        records.append(rec)
    return records


def run_real(p: Planner, path: str, fraction: float, seeds) -> list:
    """Held-out log RMSE of each row on a real measurement file (module docstring)."""
    from brdfkit.acquisition.sampling import join_samples
    from brdfkit.evaluation.holdout import sample_errors, split
    from brdfkit.io.sample_files import read_sample_file

    data = read_sample_file(path)
    rows = []
    for seed in seeds:
        rest_idx, held_idx = split(len(data), fraction, seed)
        rest, held = data.subset(rest_idx), data.subset(held_idx)
        where = {}
        for i, key in enumerate(zip(rest.theta_h.tolist(), rest.theta_d.tolist(), rest.phi_d.tolist())):
            where.setdefault(key, i)

        def measured(plan):  # the rest's samples at the plan's directions (their own angles)
            keys = zip(plan.directions.theta_h.tolist(), plan.directions.theta_d.tolist(),
                       plan.directions.phi_d.tolist())
            return rest.subset(np.array([where[k] for k in keys], np.int64))

        sets = []
        for k in (8, 16):
            plan, wall, cpu = p.plan(k, within=rest, cold=True)
            sets.append((f"planned-{k}", measured(plan), wall, cpu, []))
        for row in ("rounds-4+4", "rounds-8+8", "rounds-4+4+4+4"):
            k, count = ROUNDS[row]
            plan, wall, cpu = p.plan(k, within=rest, cold=True)
            samples, infos = measured(plan), []
            for _ in range(count - 1):
                plan, w, c = p.plan(k, within=rest, given=samples)
                infos.append(_plan_info(plan, w, c))
                wall, cpu = wall + w, cpu + c
                samples = join_samples(samples, measured(plan))
            sets.append((row, samples, wall, cpu, infos))
        for k in (8, 16, 40):
            sets.append((f"random-{k}", rest.subset(np.arange(k)), 0.0, 0.0, []))
        for row, samples, wall, cpu, infos in sets:
            recon, fit_s, fit_cpu = p.fit(samples)
            rec = {"row": row, "seed": int(seed), "n": len(samples), "held_out": int(held_idx.size),
                   "plan_s": round(wall, 3), "plan_cpu_s": round(cpu, 3), "fit_s": round(fit_s, 3),
                   "fit_cpu_s": round(fit_cpu, 3), **sample_errors(recon, held)}
            if infos:
                rec["rounds"] = infos
            rows.append(rec)
            print(f"real {os.path.basename(path)} seed {seed} {row}: held-out log RMSE {rec['log_rmse']:.4f}",
                  flush=True)
    return rows


ROW_ORDER = ["planned-4", "planned-8", "rounds-4+4", "rounds-4+4+4", "planned-16", "rounds-8+8", "rounds-4+4+4+4",
             "uniform-40", "ipca-planned-16", "ipca-rounds-8+8"]


def _group(row: str) -> str:
    return "uniform-40" if row.startswith("uniform-40-s") else row


def summary(records: list, scenes: list) -> list:
    """Means per row over the materials (and, for ``uniform-40``, the seeds)."""
    groups: dict = {}
    for r in records:
        groups.setdefault(_group(r["row"]), []).append(r)
    out = []
    for row in [g for g in ROW_ORDER if g in groups] + [g for g in groups if g not in ROW_ORDER]:
        rs = groups[row]
        s = {"row": row, "method": rs[0]["method"], "n": rs[0]["n"], "count": len(rs),
             "psnr": float(np.mean([r["psnr"] for r in rs])), "delta_e": float(np.mean([r["delta_e"] for r in rs])),
             "log_rmse": float(np.mean([r["log_rmse"] for r in rs])),
             "scenes": {sc: float(np.mean([r["scenes"][sc]["psnr"] for r in rs])) for sc in scenes},
             "plan_s": float(np.mean([r["plan_s"] for r in rs])), "fit_s": float(np.mean([r["fit_s"] for r in rs]))}
        if all("expected" in r for r in rs):
            s["expected"] = float(np.mean([r["expected"] for r in rs]))
        out.append(s)
    return out


def real_summary(rows: list) -> list:
    groups: dict = {}
    for r in rows:
        groups.setdefault(r["row"], []).append(r)
    return [{"row": k, "n": rs[0]["n"], "seeds": [r["seed"] for r in rs],
             "log_rmse": float(np.mean([r["log_rmse"] for r in rs])),
             "log_rmse_sd": float(np.std([r["log_rmse"] for r in rs])),
             "luminance_error_median": float(np.mean([r["luminance_error_median"] for r in rs])),
             "plan_s": float(np.mean([r["plan_s"] for r in rs])), "fit_s": float(np.mean([r["fit_s"] for r in rs]))}
            for k, rs in groups.items()]


def print_tables(summ: list, scenes: list, real: list | None) -> None:
    print("| row | N | PSNR, mean of the scenes (dB) | " + " | ".join(scenes) + " | Delta E | log RMSE | "
          "plan s | fit s | expected error |")
    print("| --- | ---: | ---: | " + " | ".join("---:" for _ in scenes) + " | ---: | ---: | ---: | ---: | ---: |")
    for s in summ:
        exp = f"{s['expected']:.3g}" if "expected" in s else "-"
        print(f"| {s['row']} | {s['n']} | {s['psnr']:.2f} | " + " | ".join(f"{s['scenes'][sc]:.2f}" for sc in scenes)
              + f" | {s['delta_e']:.3f} | {s['log_rmse']:.3f} | {s['plan_s']:.1f} | {s['fit_s']:.2f} | {exp} |")
    if real:
        print()
        print("| real row | N | held-out log RMSE (mean +- sd over seeds) | median luminance error | plan s | fit s |")
        print("| --- | ---: | ---: | ---: | ---: | ---: |")
        for s in real:
            print(f"| {s['row']} | {s['n']} | {s['log_rmse']:.4f} +- {s['log_rmse_sd']:.4f} | "
                  f"{s['luminance_error_median']:.3f} | {s['plan_s']:.1f} | {s['fit_s']:.2f} |")
    sys.stdout.flush()


def main(argv=None):
    ap = common.record_options(argparse.ArgumentParser(description=__doc__.split("\n\n")[0]))
    ap.add_argument("--data", default=os.path.join("proxies", "merl"), help="folder of MERL tables NAME.binary")
    ap.add_argument("--list", default=os.path.join("..", "shared", "data", "merl-test.txt"),
                    help="material names, one a line (default: the 20 MERL test materials)")
    ap.add_argument("--materials", default="", help="names, comma separated (instead of --list)")
    ap.add_argument("--limit", type=int, default=0, help="the first N of --list")
    ap.add_argument("-m", "--model", default="merl80-l40")
    ap.add_argument("--seeds", type=int, nargs="*", default=[0, 1, 2], help="uniform draws (and real holdout seeds)")
    ap.add_argument("--resolution", type=int, default=128)
    ap.add_argument("--scenes", default="all")
    ap.add_argument("--cache", default=os.path.join("runs", "bench-cache"), help="reference renders, shareable")
    ap.add_argument("--no-expected", action="store_true", help="skip the expected error of each row")
    ap.add_argument("--real", default=os.path.join("..", "shared", "data", "real", "cornell", "acryl_blue.brdf"),
                    help="a real measurement file for the held-out rows ('' skips them)")
    ap.add_argument("--holdout", type=float, default=0.3)
    a = ap.parse_args(argv)

    t0, load_start = time.time(), common.load_average()
    threads = common.set_threads(a.threads)
    from brdfkit.bench.config import BenchConfig
    from brdfkit.bench.worker import Worker
    from brdfkit.models.builtin import find_bundle, is_path_spec
    from brdfkit.render.scene_suite import scene_names

    scenes = scene_names(a.scenes)
    worker = Worker(BenchConfig(output=a.cache, data=None, scenes=tuple(scenes), resolution=a.resolution,
                                cache=a.cache, device="cpu"))
    p = Planner(a.model, "cpu")
    # A warm-up: the first plan and fits pay for imports and caches no later round pays again.
    from brdfkit.acquisition.sampling import measure_samples
    from brdfkit.testing.examples import lambertian_table

    from brdfkit.acquisition.planning import plan_directions

    warm = measure_samples(lambertian_table(), plan_directions(None, 4, design="uniform").directions)
    p.plan(2, given=warm)
    p.fit(warm), p.fit(warm, "ipca")
    for k in (4, 8, 16):
        p.one_shot[k] = p.plan(k, cold=True)
    plans = {f"planned-{k}": _plan_info(*v) for k, v in p.one_shot.items()}

    names = _materials(a)
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                                cwd=common.REPO).stdout.strip()
        changed = subprocess.run(["git", "status", "--porcelain", "--", "brdfkit"], capture_output=True, text=True,
                                 cwd=common.REPO).stdout.split("\n")
    except OSError:
        commit, changed = "", []
    parts = {} if is_path_spec(a.model) else {k: v.digest for k, v in find_bundle(a.model).parts.items()}
    record = {"benchmark": "rounds", "issue": 57, "command": "python benchmarks/rounds.py " + " ".join(
        sys.argv[1:] if argv is None else argv), "commit": commit,
        "uncommitted": sorted(line[3:] for line in changed if line.strip()), "model": a.model, "parts": parts,
        "resolution": a.resolution, "scenes": scenes, "seeds": a.seeds, "threads": threads,
        "data": os.path.relpath(a.data), "materials": names, "plans": plans, "records": [], "summary": []}
    path = a.json
    for i, name in enumerate(names):
        recs = run_material(p, worker, a.data, name, a.seeds, not a.no_expected)
        record["records"] += recs
        record["summary"] = summary(record["records"], scenes)
        common.write_record(record, path, load_start, t0)
        print(f"[{i + 1}/{len(names)}] {name}: " + ", ".join(f"{r['row']} {r['psnr']:.2f}" for r in recs)
              + f" (load {common.load_average()})", flush=True)
    real = None
    if a.real:
        rows = run_real(p, a.real, a.holdout, a.seeds)
        real = real_summary(rows)
        record["real"] = {"file": os.path.basename(a.real), "fraction": a.holdout, "seeds": a.seeds,
                          "model": a.model, "rows": rows, "summary": real}
    common.write_record(record, path, load_start, t0)
    print()
    print(f"## Rounds against one-shot plans: {len(names)} materials, {a.model}, {len(scenes)} scenes, "
          f"{a.resolution} px (load {load_start} -> {common.load_average()})")
    print()
    print_tables(record["summary"], scenes, real)


if __name__ == "__main__":
    sys.exit(main())
