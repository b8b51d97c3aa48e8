"""Running the benchmark: the tasks (one per material), one process or a pool, the
incremental ``bench.json``; merging the results of several runs."""

from __future__ import annotations

import dataclasses
import datetime
import json
import math
import os
import platform
import sys
import time

import numpy as np

from brdfkit.atomic import atomic_open, check_input_file
from brdfkit.errors import InputError
from brdfkit.io.folders import list_materials
from brdfkit.bench.config import BenchConfig
from brdfkit.bench.report import write_markdown, write_plots
from brdfkit.bench.summary import record_size, summarise
from brdfkit.bench.worker import Worker, error_text, failed_records, init_process, renderer_digest, run_task

__all__ = ["run_bench", "merge_results", "FORMAT_VERSION"]

FORMAT_VERSION = 1

def _environment(cfg: BenchConfig) -> dict:
    import torch

    from brdfkit.runtime import resolve_device

    dev = str(resolve_device(cfg.device))
    threads = cfg.threads or (torch.get_num_threads() if cfg.jobs == 1 else max(1, (os.cpu_count() or 1) // cfg.jobs))
    return {"machine": platform.machine() + " " + platform.system(), "cpus": os.cpu_count(),
            "torch": torch.__version__, "threads": threads, "device": dev,
            "gpu": torch.cuda.get_device_name(0) if dev.startswith("cuda") and torch.cuda.is_available() else None,
            "python": sys.version.split()[0], "renderer": renderer_digest()[:16],
            "method_defaults": _method_defaults()}


def _method_defaults() -> dict:
    """The methods' default options in this code, recorded with every run (an option
    not given on the command line is one of these)."""
    from brdfkit.methods import METHODS

    return {name: m.defaults() for name, m in METHODS.items() if m.defaults()}


def _json_safe(obj):
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_json_safe(v) for v in obj]
    if isinstance(obj, np.generic):
        return _json_safe(obj.item())
    return obj


def run_bench(cfg: BenchConfig, progress: bool = True, resume: bool = False) -> dict:
    """Run the benchmark and write its outputs (see the module doc).

    Parameters
    ----------
    cfg
        :class:`BenchConfig`.
    progress
        Show a Rich progress bar on stderr.
    resume
        Go on with an interrupted run in ``cfg.output``: its finished materials are kept
        (their records as written) and only the others run. The earlier run must have
        the same configuration (but for ``command`` and ``jobs``) and renderer.

    Returns
    -------
    dict
        The content of ``bench.json``: ``config`` and ``parts`` (:meth:`BenchConfig.recorded`),
        ``environment``, ``materials``, ``records`` (one per reconstruction: material, method, N, seed, sampling and
        how the samples were made (:meth:`brdfkit.acquisition.protocol.SamplingProtocol.samples`),
        metrics, ``time_s``, ``render_s``, or ``error``), ``summary`` (:func:`summarise`),
        ``outputs``.

    Raises
    ------
    InputError
        Bad options, missing files or test materials, unreadable model files, unknown
        built-in model names; with ``resume``, an earlier run of another configuration or parts.
    """
    given = cfg.with_default_methods()
    cfg = given.resolved()  # built-in names -> their files; the record keeps the names and the parts' digests
    cfg.validate()
    os.makedirs(cfg.output, exist_ok=True)
    if cfg.jobs > 1 and cfg.threads is None:
        cfg = dataclasses.replace(cfg, threads=max(1, (os.cpu_count() or 1) // cfg.jobs))
    recorded, parts = given.recorded(cfg)
    tasks = []
    if cfg.data is not None:
        names = None
        if cfg.test_list:
            from brdfkit.io.folders import read_exclude_list

            names = read_exclude_list(cfg.test_list)
        tasks += [("sparse", n, p) for n, p in list_materials(cfg.data, names)]
    n_sparse = len(tasks)
    if cfg.compression_models:
        tasks += [("compression", n, p) for n, p in list_materials(cfg.compression_data)]
    per_task = {"sparse": len(cfg.methods) * len(cfg.n) * cfg.seeds * len(cfg.sampling),
                "compression": len(cfg.compressors())}
    result = {"format": "brdfkit-bench", "version": FORMAT_VERSION,
              "started": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
              "config": recorded, "parts": parts, "environment": _environment(cfg),
              "materials": {"sparse": [t[1] for t in tasks[:n_sparse]], "sparse_count": n_sparse,
                            "compression": [t[1] for t in tasks[n_sparse:]],
                            "compression_count": len(tasks) - n_sparse},
              "records": [], "complete": False, "elapsed_s": 0.0}
    json_path = os.path.join(cfg.output, "bench.json")
    t_start = time.perf_counter()
    if resume:
        tasks = _resume(result, json_path, tasks)
        t_start -= result["elapsed_s"]

    def save(complete=False):
        result["complete"] = complete
        result["elapsed_s"] = time.perf_counter() - t_start
        result["summary"] = summarise(result["records"], cfg.group_by_prefix)
        with atomic_open(json_path, "w", encoding="utf-8") as f:
            json.dump(_json_safe(result), f, indent=1)

    from brdfkit.console import ProgressBar
    from brdfkit.runtime import torch_threads

    total = sum(per_task[t[0]] for t in tasks)
    if not tasks:
        return _finish(dict(result, complete=True), cfg.output, json_path, cfg.group_by_prefix)
    with ProgressBar("loading models", total=total, enabled=progress, count=True, transient=False) as bar:

        def done(task, recs):
            result["records"].extend(recs)
            bad = sum("error" in r for r in recs)
            bar.update(advance=per_task[task[0]],
                       description=f"{task[0]} {task[1]}" + (f" ({bad} failed)" if bad else ""))
            save()

        with torch_threads(cfg.threads):
            # Built here even for worker processes: a model file that does not load is a
            # usage error now, not a failure recorded for every reconstruction.
            worker = Worker(cfg)
            labels = [(label, dim) for label, dim, _ in worker.compressors]
            if cfg.jobs == 1:
                for task in tasks:
                    bar.update(description=f"{task[0]} {task[1]}")
                    done(task, worker.run(*task))
        if cfg.jobs > 1:
            del worker
            _run_pool(cfg, tasks, labels, done)
    result["complete"] = True
    result["elapsed_s"] = time.perf_counter() - t_start
    return _finish(result, cfg.output, json_path, cfg.group_by_prefix)


_RESUME_FREE = ("command", "jobs")  # config keys that may differ in a resumed run


def _resume(result: dict, json_path: str, tasks: list) -> list:
    """Fill ``result`` with the finished materials of the run in ``json_path``; return
    the tasks still to run. A material's records are written together when it ends,
    so a material with records is finished."""
    if not os.path.exists(json_path):
        return tasks
    try:
        with open(json_path, encoding="utf-8") as f:
            old = json.load(f)
        old_cfg, old_records = old["config"], old["records"]
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise InputError(f"{json_path}: cannot resume from it ({e})") from None
    new_cfg = json.loads(json.dumps(_json_safe(result["config"])))
    differ = sorted(k for k in set(old_cfg) | set(new_cfg)
                    if k not in _RESUME_FREE and old_cfg.get(k) != new_cfg.get(k))
    if differ:
        raise InputError(f"{json_path}: --resume needs the same configuration; these differ: {', '.join(differ)}")
    if old.get("parts", {}) != result["parts"]:
        raise InputError(f"{json_path}: --resume needs the same built-in models; a part of "
                         f"{', '.join(sorted(set(old.get('parts', {})) | set(result['parts'])))} differs")
    if old.get("environment", {}).get("renderer") != result["environment"]["renderer"]:
        raise InputError(f"{json_path}: --resume needs the same renderer; the earlier run used another")
    finished = {(r["kind"], r["material"]) for r in old_records}
    result.update(records=list(old_records), started=old.get("started", result["started"]),
                  elapsed_s=float(old.get("elapsed_s") or 0.0))
    return [t for t in tasks if (t[0], t[1]) not in finished]


def _run_pool(cfg: BenchConfig, tasks: list, labels: list, done) -> None:
    """Run ``tasks`` in ``cfg.jobs`` processes, ``done(task, records)`` as each ends."""
    import concurrent.futures
    import multiprocessing

    cfg_json = json.dumps(dataclasses.asdict(cfg))
    ctx = multiprocessing.get_context("spawn")  # no fork of a process holding torch threads
    with concurrent.futures.ProcessPoolExecutor(cfg.jobs, mp_context=ctx, initializer=init_process) as pool:
        try:
            futures = {pool.submit(run_task, cfg_json, *t): t for t in tasks}
            for fut in concurrent.futures.as_completed(futures):
                task = futures[fut]
                try:
                    recs = fut.result()
                except Exception as e:  # the worker died (e.g. out of memory)
                    recs = failed_records(cfg, task[0], task[1], error_text(e), labels)
                done(task, recs)
        except KeyboardInterrupt:
            pool.shutdown(wait=False, cancel_futures=True)
            raise


def _finish(result: dict, folder: str, json_path: str, group_by_prefix: bool) -> dict:
    """Write the summaries, tables and plots of a finished (or merged) result."""
    outputs = [json_path, os.path.join(folder, "bench.md")]
    result["summary"] = summarise(result["records"], group_by_prefix)
    outputs += write_plots(folder, result)
    result["outputs"] = outputs
    with atomic_open(json_path, "w", encoding="utf-8") as f:
        json.dump(_json_safe(result), f, indent=1)
    write_markdown(outputs[1], result)
    return result


def merge_results(paths, output: str, allow_incomplete: bool = False, replace: bool = False) -> dict:
    """Merge the ``bench.json`` of runs with other seeds (or methods) into one result.

    The runs must share the render resolution; a record that two runs both hold (same
    kind, material, method, N / model and seed) is refused. Sparse (compression) records
    are kept only for the materials that every run with sparse (compression) records
    covered, so that every summary row averages over the same materials (the others are
    listed as dropped). The merged
    ``bench.json``, ``bench.md`` and plots are written into ``output``.

    Parameters
    ----------
    allow_incomplete
        Also merge runs that were interrupted (their finished materials).
    replace
        A method that a later run holds replaces that method's records of the earlier
        runs (one method re-run after a change), instead of a duplicate being refused.

    Raises
    ------
    InputError
        Fewer than two runs, an unreadable or incomplete ``bench.json``, differing
        resolutions, or a duplicated record.
    """
    runs = []
    for p in paths:
        file = os.path.join(p, "bench.json") if os.path.isdir(p) else os.fspath(p)
        file = check_input_file(file)
        try:
            with open(file, encoding="utf-8") as f:
                run = json.load(f)
        except (json.JSONDecodeError, UnicodeDecodeError) as e:
            raise InputError(f"{file}: not a bench.json ({e})") from None
        if not isinstance(run, dict) or run.get("format") != "brdfkit-bench":
            raise InputError(f"{file}: not a brdfkit bench result")
        if not run.get("complete") and not allow_incomplete:
            raise InputError(f"{file}: the run did not finish; merge complete runs only "
                             f"(or pass --allow-incomplete)")
        runs.append(run)
    if len(runs) < 2:
        raise InputError("merging needs at least two bench results")
    res = {r["config"]["resolution"] for r in runs}
    if len(res) > 1:
        raise InputError(f"the runs rendered at different resolutions ({sorted(res)}); their image "
                         f"metrics are not comparable")
    parts = {}
    for run in runs:  # a built-in's name means the same parts in every run merged
        for name, got in run.get("parts", {}).items():
            if parts.setdefault(name, got) != got:
                raise InputError(f"the runs used other parts of the built-in model {name!r}; their figures "
                                 f"are not of one model")
    common, dropped = {}, []
    for kind in ("sparse", "compression"):
        covered = [{r["material"] for r in run["records"] if r["kind"] == kind} for run in runs]
        covered = [c for c in covered if c]
        common[kind] = set.intersection(*covered) if covered else set()
        dropped += sorted(set().union(*covered) - common[kind]) if covered else []
    seen, records = set(), []
    for i, run in enumerate(runs):
        later = {(r["kind"], r["method"]) for other in runs[i + 1:] for r in other["records"]} if replace else set()
        for r in run["records"]:
            if r["material"] not in common[r["kind"]] or (r["kind"], r["method"]) in later:
                continue
            key = (r["kind"], r["material"], r["method"], r.get("n"), r.get("seed"), record_size(r),
                   r.get("sampling", "uniform") if r["kind"] == "sparse" else None)
            if key in seen:
                raise InputError(f"two runs both hold {r['kind']} {r['material']} {r['method']} "
                                 f"N={r.get('n')} seed={r.get('seed')}"
                                 f"{' (' + r['sampling'] + ' sampling)' if r.get('sampling') else ''}; "
                                 f"merge runs with other seeds, methods or samplings "
                                 f"(or --replace: a later run's method replaces an earlier run's)")
            seen.add(key)
            records.append(r)
    first = runs[0]
    cfg = dict(first["config"])
    cfg["seed_values"] = sorted({r["seed"] for r in records if r["kind"] == "sparse" and "seed" in r})
    cfg["seeds"] = len(cfg["seed_values"]) or cfg["seeds"]
    cfg["methods"] = list(dict.fromkeys(m for run in runs for m in run["config"]["methods"]))
    cfg["sampling"] = list(dict.fromkeys(s for run in runs for s in run["config"].get("sampling", ["uniform"])))
    cfg["command"] = " + ".join(run["config"].get("command", "") for run in runs)
    if replace:
        cfg["command"] += "  # merged with --replace: a later run's methods replace the earlier runs' records of them"
    mats = {"sparse": [m for m in dict.fromkeys(m for run in runs for m in run["materials"]["sparse"])
                       if m in common["sparse"]],
            "compression": list(dict.fromkeys(r["material"] for r in records if r["kind"] == "compression"))}
    result = dict(first, config=cfg, parts=dict(sorted(parts.items())), records=records, complete=all(run.get("complete") for run in runs),
                  dropped_materials=dropped,
                  elapsed_s=sum(run["elapsed_s"] for run in runs),
                  materials={**mats, "sparse_count": len(mats["sparse"]),
                             "compression_count": len(mats["compression"])},
                  merged_from=[run["started"] for run in runs])
    os.makedirs(output, exist_ok=True)
    return _finish(result, output, os.path.join(output, "bench.json"), cfg.get("group_by_prefix", False))

