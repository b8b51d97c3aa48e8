"""Held-out error: how well a reconstruction predicts measurements it was not given.

With real measurements there is no dense reference table to score a reconstruction
against; what a user can check is the measurements themselves. :func:`holdout` holds
out a fraction of a file's samples (at random, by a seed), reconstructs the material
from ``N`` of the others with each method, and scores each reconstruction at the held-out
directions (:func:`sample_errors`). ``brdfkit validate`` runs it; ``brdfkit metrics
SAMPLES TABLE`` scores any BRDF file at a sample file's directions the same way.

The scores of a prediction ``p`` against measurements ``m`` (linear sRGB, 1/sr), at the
samples where the prediction has a value:

* ``log_rmse``: ``sqrt(mean((ln(1 + p cos_i) - ln(1 + m cos_i))^2))`` over the samples
  and the three channels, the mapping of
  :func:`brdfkit.evaluation.metrics.brdf_log_rmse` at the samples' own directions;
* ``luminance_error``: ``sum |Y(p) - Y(m)| / sum Y(m)``, ``Y`` the luminance (Rec. 709
  weights), the relative error of the luminance over the samples, each weighted by its
  own brightness (highlights count most, as in a render);
* ``luminance_error_median``: the median of ``|Y(p) - Y(m)| / Y(m)`` over the samples
  with ``Y(m) > 0``, each sample alike.

The predictions are the reconstructed tables looked up trilinearly at the samples'
Rusinkiewicz angles (:func:`brdfkit.geometry.trilinear.lookup_trilinear`), as a
renderer reads them. Methods run through the registry (:data:`brdfkit.methods.METHODS`),
each with its model loaded once.

May import: everything below it (the ground floor, geometry, io, methods through the
registry); numpy.
"""

from __future__ import annotations

import dataclasses
import os

import numpy as np

from brdfkit.errors import InputError

__all__ = ["LUMINANCE", "sample_errors", "split", "MethodRun", "method_run", "holdout", "summarise",
           "ValidationReport", "validate_files", "score_at_samples"]

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
"""Luminance of linear sRGB (ITU-R BT.709)."""


def sample_errors(table, samples) -> dict:
    """Scores of a dense table at a sample set's directions (see the module).

    Parameters
    ----------
    table
        ``(90, 90, 180, 3)``, 1/sr, NaN where the method has no value.
    samples
        :class:`brdfkit.io.samples.SampleSet`, the measurements.

    Returns
    -------
    dict
        ``{"samples", "covered", "log_rmse", "luminance_error", "luminance_error_median"}``:
        the samples scored, those the table has a value at, and the scores over those.

    Raises
    ------
    InputError
        No sample where the table has a value.

    Examples
    --------
    >>> import numpy as np
    >>> from brdfkit.io.samples import SampleSet
    >>> from brdfkit.testing.examples import lambertian_table
    >>> s = SampleSet(np.array([0.1, 0.5]), np.array([0.2, 0.7]), np.array([0.3, 1.0]), np.full((2, 3), 0.5 / np.pi))
    >>> e = sample_errors(lambertian_table((0.5, 0.5, 0.5)), s)
    >>> e["covered"], round(e["log_rmse"], 6), round(e["luminance_error"], 6)
    (2, 0.0, 0.0)
    """
    from brdfkit.geometry.trilinear import lookup_trilinear

    pred = np.asarray(lookup_trilinear(np.asarray(table, np.float64), samples.theta_h, samples.theta_d,
                                       samples.phi_d), np.float64)
    meas = np.asarray(samples.rgb, np.float64)
    ok = np.isfinite(pred).all(1) & np.isfinite(meas).all(1)
    if not ok.any():
        raise InputError(f"{samples.source or 'samples'}: the reconstruction has no value at any of the "
                         f"{len(samples)} samples")
    p, m = np.maximum(pred[ok], 0.0), meas[ok]
    cos = samples.cos_i()[ok][:, None]
    log_rmse = float(np.sqrt(np.mean((np.log1p(p * cos) - np.log1p(m * cos)) ** 2)))
    yp, ym = p @ LUMINANCE, m @ LUMINANCE
    total = float(ym.sum())
    lit = ym > 0
    return {"samples": len(samples), "covered": int(ok.sum()), "log_rmse": log_rmse,
            "luminance_error": float(np.abs(yp - ym).sum() / total) if total > 0 else None,
            "luminance_error_median": float(np.median(np.abs(yp[lit] - ym[lit]) / ym[lit])) if lit.any() else None}


def split(n: int, fraction: float, seed: int):
    """Indices ``(rest, held_out)`` of ``n`` samples: ``round(fraction n)`` held out at
    random (``numpy.random.default_rng(seed)``), the rest in the same random order, so
    that the first ``N`` of the rest for a smaller ``N`` are among those of a larger one.

    Raises
    ------
    InputError
        ``fraction`` not in ``(0, 1)``, or leaving no sample on either side.
    """
    if not 0.0 < float(fraction) < 1.0:
        raise InputError(f"--holdout {fraction}: the fraction held out must be between 0 and 1")
    order = np.random.default_rng(int(seed)).permutation(int(n))
    k = int(round(float(fraction) * n))
    if k < 1 or k >= n:
        raise InputError(f"--holdout {fraction} of {n} samples holds out {k}: none would be "
                         f"{'held out' if k < 1 else 'left to reconstruct from'}")
    return order[k:], order[:k]


@dataclasses.dataclass
class MethodRun:
    """A method ready to run: its registry ``name``, ``label`` (for tables), the model
    ``path`` and the ``model`` loaded from it (``None`` for a method without one)."""

    name: str
    label: str
    path: str | None
    model: object = None


def method_run(spec: str) -> MethodRun:
    """A method from ``NAME`` or ``NAME=MODEL`` (``brdfkit validate --method``): ``auto``
    or a :data:`brdfkit.methods.METHODS` name, and a built-in name or a model file
    (:func:`brdfkit.methods.choice.choose`), its model loaded."""
    from brdfkit.methods import METHODS
    from brdfkit.methods.choice import AUTO, choose

    name, _, model = spec.partition("=")
    name = name.strip()
    if name != AUTO and name not in METHODS:
        raise InputError(f"--method {spec}: unknown method {name!r}; known: {AUTO}, {', '.join(sorted(METHODS))}")
    choice = choose(name, model.strip() or None)
    method = METHODS[choice.method]
    label = choice.method + (f" {os.path.splitext(os.path.basename(choice.path))[0]}" if choice.path else "")
    return MethodRun(choice.method, label, choice.path, method.load(choice.path) if method.needs_model else None)


def holdout(samples, runs, *, fraction: float = 0.3, counts=(None,), seeds=(0,), progress=None) -> list:
    """Held-out scores of each method, ``N`` and seed on one sample set.

    Parameters
    ----------
    samples
        :class:`brdfkit.io.samples.SampleSet`.
    runs
        :class:`MethodRun` (:func:`method_run`).
    fraction
        The fraction of the samples held out.
    counts
        ``N``, the samples each reconstruction is given, from those not held out
        (``None``: all of them).
    seeds
        Each seed draws its own held-out set and training samples, and seeds the method.
    progress
        Optional ``progress(row)``, called with each row as it is done.

    Returns
    -------
    list
        One dict per (seed, ``N``, method): ``{"method", "n", "seed", "held_out"}`` and the
        scores of :func:`sample_errors`.

    Raises
    ------
    InputError
        A fraction or ``N`` the samples cannot give.
    """
    from brdfkit.methods import METHODS

    rows = []
    for seed in seeds:
        rest, held = split(len(samples), fraction, seed)
        test = _subset(samples, held)
        for n in counts:
            if n is not None and not 1 <= int(n) <= rest.size:
                raise InputError(f"-n {n}: {rest.size} samples are left after holding out {held.size} "
                                 f"({fraction:g} of {len(samples)})")
            train = _subset(samples, rest if n is None else rest[:int(n)])
            for run in runs:
                table, _ = METHODS[run.name].sparse(train, run.model, seed=int(seed))
                row = {"method": run.label, "n": len(train), "seed": int(seed), "held_out": held.size,
                       **sample_errors(table, test)}
                rows.append(row)
                if progress is not None:
                    progress(row)
    return rows


def _subset(samples, idx):
    from brdfkit.io.samples import SampleSet

    idx = np.asarray(idx, np.int64)
    return SampleSet(samples.theta_h[idx], samples.theta_d[idx], samples.phi_d[idx], samples.rgb[idx],
                     samples.source, samples.note)


def summarise(rows) -> list:
    """The mean and standard deviation over seeds of each score, per (file, method, N):
    one dict each, in the order first met."""
    groups: dict = {}
    for r in rows:
        groups.setdefault((r.get("file"), r["method"], r["n"]), []).append(r)
    out = []
    for (file, method, n), rs in groups.items():
        row = {"file": file, "method": method, "n": n, "seeds": [r["seed"] for r in rs]}
        for key in ("log_rmse", "luminance_error", "luminance_error_median"):
            vals = np.array([r[key] for r in rs if r[key] is not None], np.float64)
            row[key] = float(vals.mean()) if vals.size else None
            row[key + "_sd"] = float(vals.std()) if vals.size > 1 else None
        out.append(row)
    return out


@dataclasses.dataclass
class ValidationReport:
    """What ``brdfkit validate`` found: the settings, every row (per file, seed, ``N``
    and method) and the summary (:func:`summarise`), the last rows with ``file`` None
    the means over the files."""

    settings: dict
    rows: list
    summary: list

    def to_json(self) -> str:
        import json

        return json.dumps({"settings": self.settings, "rows": self.rows, "summary": self.summary}, indent=1)

    def write(self, path) -> None:
        """The JSON report, written atomically."""
        from brdfkit.atomic import atomic_open

        with atomic_open(path, "w") as f:
            f.write(self.to_json() + "\n")

    def print_table(self) -> None:
        """The summary as a table on stdout: a row per file, ``N`` and method, the scores'
        means +- standard deviations over the seeds."""
        from rich.console import Console
        from rich.table import Table

        t = Table(title=f"held-out error: {self.settings['fraction']:g} of each file held out, seed(s) "
                        f"{', '.join(map(str, self.settings['seeds']))}")
        for col in ("file", "N", "method", "log RMSE", "luminance error", "median"):
            t.add_column(col, justify="right" if col in ("N", "log RMSE", "luminance error", "median") else "left")
        last = None
        for r in self.summary:
            file = r["file"] or "[bold]mean of the files[/bold]"
            t.add_row(file if file != last else "", str(r["n"]), r["method"], _pm(r, "log_rmse"),
                      _pm(r, "luminance_error"), _pm(r, "luminance_error_median"))
            last = file
        Console(soft_wrap=True).print(t)


def _pm(row, key):
    v, sd = row.get(key), row.get(key + "_sd")
    if v is None:
        return "-"
    return f"{v:.3f}" + (f" ± {sd:.3f}" if sd is not None else "")


def validate_files(paths, methods=("auto",), *, fraction: float = 0.3, counts=(None,), seeds=(0,),
                   progress: bool = True) -> ValidationReport:
    """:func:`holdout` on each sample file, each method loaded once: ``brdfkit validate``.

    Every file is read (and refused, one line) before any method runs. ``methods``:
    ``NAME`` or ``NAME=MODEL`` (:func:`method_run`). ``progress``: a line per row on
    stderr.
    """
    import os

    from brdfkit.console import console
    from brdfkit.io.sample_files import read_sample_file

    data = {os.path.basename(os.fspath(p)): read_sample_file(p) for p in paths}
    runs = [method_run(m) for m in methods]
    total = len(data) * len(seeds) * len(counts) * len(runs)
    rows = []
    for name, samples in data.items():
        def note(row, name=name):
            row["file"] = name
            if progress:
                console().print(f"[{len(rows) + 1}/{total}] {name}, {row['method']}, N = {row['n']}, seed "
                                f"{row['seed']}: log RMSE {row['log_rmse']:.4f}, luminance error "
                                f"{row['luminance_error']:.4f}", soft_wrap=True)
            rows.append(row)

        holdout(samples, runs, fraction=fraction, counts=counts, seeds=seeds, progress=note)
    summary = summarise(rows)
    if len(data) > 1:
        for r in summarise([{**r, "file": None} for r in rows]):
            summary.append(r)
    settings = {"files": list(data), "fraction": float(fraction), "seeds": [int(s) for s in seeds],
                "counts": [None if n is None else int(n) for n in counts], "methods": [r.label for r in runs],
                "samples": {k: len(v) for k, v in data.items()}}
    return ValidationReport(settings, rows, summary)


def score_at_samples(pred, ref, model_path=None) -> dict:
    """``brdfkit metrics --ref SAMPLES PRED`` (or ``SAMPLES PRED`` in either order): the BRDF
    file ``pred`` (``.binary``, ``.bsdf`` as its reciprocal table, ``.emb`` decoded with
    ``model_path`` or the built-in it names) scored at every sample of the sample file ``ref`` (:func:`sample_errors`). The
    samples are read first: a bad reference costs no decoding."""
    from brdfkit.files.brdf_file import EmbeddingDecoders, read_table
    from brdfkit.io.sample_files import read_sample_file

    samples = read_sample_file(ref)
    return sample_errors(read_table(pred, EmbeddingDecoders(model_path)), samples)
