"""Summaries of benchmark records: means and spreads per (method, sampling, N) and per
model.

For each (method, N) the mean over materials and seeds of each metric; the spread is the
standard deviation, over seeds, of the per-seed mean over materials (how much the result
depends on the draw), and the standard deviation over materials of the per-material mean
over seeds (``*_sd_materials``).
"""

from __future__ import annotations

import math

import numpy as np

from brdfkit.bench.config import METRICS

__all__ = ["summarise", "mean", "family", "record_size"]


def family(name: str) -> str:
    """A material's family: its name up to the first ``-``."""
    return name.split("-", 1)[0] if "-" in name else name


def mean(values):
    v = [x for x in values if x is not None and math.isfinite(x)]
    return float(np.mean(v)) if v else None


def _sd(values):
    v = [x for x in values if x is not None and math.isfinite(x)]
    return float(np.std(v, ddof=1)) if len(v) > 1 else None


def record_size(r: dict):
    """A compression record's ``size`` (numbers per material); ``latent`` in the records
    of runs from before it was called ``size``."""
    return r.get("size", r.get("latent"))


def _summary_rows(records, keys) -> list[dict]:
    """One row per distinct ``keys`` value tuple: means, spreads, counts."""
    groups: dict = {}
    for r in records:
        groups.setdefault(tuple(record_size(r) if k == "size" else r.get(k) for k in keys), []).append(r)
    rows = []
    for gk, recs in groups.items():
        ok = [r for r in recs if "error" not in r]
        row = dict(zip(keys, gk))
        row.update(count=len(ok), failures=len(recs) - len(ok),
                   materials=len({r["material"] for r in ok}))
        for m in METRICS + ("time_s", "cpu_s"):
            row[m] = mean([r.get(m) for r in ok])
            by_seed, by_mat = {}, {}
            for r in ok:
                by_seed.setdefault(r.get("seed", 0), []).append(r.get(m))
                by_mat.setdefault(r["material"], []).append(r.get(m))
            row[m + "_sd_seeds"] = _sd([mean(v) for v in by_seed.values()])
            row[m + "_sd_materials"] = _sd([mean(v) for v in by_mat.values()])
        row["time_s_median"] = (float(np.median([r["time_s"] for r in ok])) if ok else None)
        scenes = list(dict.fromkeys(s for r in ok for s in (r.get("scenes") or {})))
        if scenes:  # each scene's mean, for the suite's per-scene tables
            row["scenes"] = {s: {m: mean([(r.get("scenes") or {}).get(s, {}).get(m) for r in ok])
                                 for m in ("psnr", "delta_e", "ssim")} for s in scenes}
        rows.append(row)
    return rows


def summarise(records: list[dict], group_by_prefix: bool = False) -> dict:
    """Summaries of bench records: ``{"sparse": rows, "compression": rows}``; each row
    holds the keys (method, sampling and N / ``size``, the numbers per material, and
    ``family`` with ``group_by_prefix``; a sparse record without ``sampling``, from a run
    before planned samples, is ``uniform``; a compression record's ``latent``, from a run
    before ``size``, is its ``size``), the mean
    of every metric and its spreads (see the module doc), counts and failures."""
    sparse = [r for r in records if r["kind"] == "sparse"]
    for r in sparse:
        r.setdefault("sampling", "uniform")  # records of runs from before planned samples
    comp = [r for r in records if r["kind"] == "compression"]
    out = {"sparse": _summary_rows(sparse, ("method", "sampling", "n")),
           "compression": _summary_rows(comp, ("method", "size")),
           "compression_by_training": _summary_rows(comp, ("method", "size", "trained_on"))}
    if group_by_prefix:
        for r in records:
            r["family"] = family(r["material"])
        out["sparse_by_family"] = _summary_rows(sparse, ("family", "method", "sampling", "n"))
        out["compression_by_family"] = _summary_rows(comp, ("family", "method", "size"))
    for key in out:
        out[key].sort(key=lambda row: tuple(str(row.get(k)) if not isinstance(row.get(k), (int, float))
                                            else f"{row.get(k):012.3f}" for k in
                                            ("family", "method", "sampling", "n", "size", "trained_on")
                                            if k in row))
    return out

