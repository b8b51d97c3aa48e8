"""Error against run time: the sparse-reconstruction and compression benchmark.

What is measured (Gokbudak et al. 2024, Sec. 4, on whatever tables are given)
--------------------------------------------------------------------------------
**Sparse reconstruction.** For every test material, every ``N`` in :data:`DEFAULT_N`
and every seed ``s = 0 .. K-1``, ``N`` samples are drawn from the material's table
(:func:`brdfkit.samples.draw_samples`, uniform over the Rusinkiewicz angles, the seed
derived from ``(s, N, material name)`` so all methods see the *same* draw), and every
method of :mod:`brdfkit.baselines` reconstructs a dense table from them. Each
reconstruction is scored:

* ``time_s``: wall time of ``Method.reconstruct`` alone (samples in, dense
  ``(90, 90, 180, 3)`` table out: encode + dense decode for the hypernetwork, ridge fit +
  decode for IPCA, the whole per-material fit + decode for NBRDF); model files are loaded
  once beforehand and each method makes one untimed warm-up reconstruction per process;
* ``log_rmse``: :func:`brdfkit.metrics.brdf_log_rmse` against the material's table;
* ``psnr``, ``delta_e``, ``ssim``: :func:`brdfkit.metrics.image_metrics` between the
  reference-scene renders (:func:`brdfkit.render.quadrature.render`, the deterministic
  quadrature renderer, at ``resolution`` pixels square, whole image) of the reconstruction
  and of the material's own table. The reference render of a material is made once and
  cached on disk (EXR, keyed by the file's SHA-256 and the scene settings).

**Compression.** For every material of the compression data and every compression model,
the full table is encoded and decoded (:func:`brdfkit.api.encode`, :func:`brdfkit.api.decode`)
and scored the same way (``time_s`` = encode + decode); with a PCA basis, its best
reconstruction (:meth:`brdfkit.baselines.ipca.IpcaModel.project` then ``decode``) too.

A failure of one reconstruction (or of reading one material) is recorded with its
message and left out of the means; the run goes on.

Outputs (in ``OUTDIR``)
-----------------------
``bench.json`` (configuration, environment, every record, summaries; rewritten after
every material, so an interrupted run keeps what it finished), ``bench.md`` (tables),
``error_vs_n.png``, ``error_vs_time.png`` (each method one curve through its ``N``
points, log time axis) and ``compression.png``; reference renders in ``cache/``.

Summaries: for each (method, N) the mean over materials and seeds of each metric; the
spread is the standard deviation, over seeds, of the per-seed mean over materials
(how much the result depends on the draw), and the standard deviation over materials of
the per-material mean over seeds (``*_sd_materials``).
"""

from __future__ import annotations

import dataclasses
import datetime
import hashlib
import json
import math
import os
import platform
import sys
import time
import zlib

import numpy as np

from .atomic import atomic_open, atomic_path, check_input_file
from .errors import InputError

__all__ = ["BenchConfig", "run_bench", "merge_results", "summarise", "DEFAULT_N", "DEFAULT_METHODS",
           "DEFAULT_RESOLUTION", "METRICS", "list_materials", "sample_seed"]

DEFAULT_N = (40, 160, 400, 2000, 4000)
DEFAULT_METHODS = ("hypernet", "ipca", "nbrdf")
DEFAULT_RESOLUTION = 128
"""Render size for the image metrics: 128 x 128 keeps a reference-scene render near a
second of CPU time per reconstruction (the scene's own 256 takes four times as long)."""

METRICS = ("psnr", "delta_e", "ssim", "log_rmse")
_LABELS = {"psnr": "PSNR (dB)", "delta_e": "Delta E 2000", "ssim": "SSIM",
           "log_rmse": "BRDF log RMSE", "time_s": "time (s)", "cpu_s": "CPU time (s)"}
_FORMAT_VERSION = 1


@dataclasses.dataclass
class BenchConfig:
    """What to run (the options of ``brdfkit bench``).

    Attributes
    ----------
    output
        Output folder.
    data, test_list
        Folder of MERL tables for the sparse benchmark and an optional file of material
        names (one a line, ``#`` comments) selecting the test materials; ``data=None``
        skips the sparse benchmark.
    model, ipca
        Hypernetwork model and PCA basis files (needed by the methods that use them).
    n, seeds, first_seed, methods
        Sample counts, number of draws per (material, N) (seeds ``first_seed ..
        first_seed + seeds - 1``; a later run with other seeds can be merged, see
        :func:`merge_results`), methods.
    compression_models, compression_data
        Hypernetwork models to test on encode -> decode of every table in
        ``compression_data`` (plus the PCA basis, when ``ipca`` is given).
    resolution
        Reference-scene render size (pixels square) for the image metrics.
    jobs, threads
        Worker processes (one material at a time each) and torch threads per process
        (default: torch's own choice with one process, ``cpu_count // jobs`` otherwise).
    device
        Torch device (``None``: CUDA when present).
    nbrdf_steps, ipca_lambda
        Method options (``None``: the methods' defaults).
    group_by_prefix
        Also summarise per material family, the family being the name up to its first
        ``-`` (e.g. ``merl-`` / ``rgl-`` prefixed file names).
    cache
        Folder of cached reference renders (default ``output/cache``).
    """

    output: str
    data: str | None = None
    test_list: str | None = None
    model: str | None = None
    ipca: str | None = None
    n: tuple = DEFAULT_N
    seeds: int = 3
    first_seed: int = 0
    methods: tuple = DEFAULT_METHODS
    compression_models: tuple = ()
    compression_data: str | None = None
    resolution: int = DEFAULT_RESOLUTION
    jobs: int = 1
    threads: int | None = None
    device: str | None = None
    nbrdf_steps: int | None = None
    ipca_lambda: float | None = None
    group_by_prefix: bool = False
    cache: str | None = None
    command: str = ""

    def seed_list(self) -> list[int]:
        return list(range(self.first_seed, self.first_seed + self.seeds))

    def validate(self) -> None:
        """:class:`InputError` for a configuration that cannot run."""
        from .baselines import get_method

        if self.data is None and not self.compression_models:
            raise InputError("nothing to run: give --data (sparse benchmark) and/or "
                             "--compression-models with --compression-data")
        if self.data is not None:
            if not self.methods:
                raise InputError("--methods: no method given")
            for m in self.methods:
                get_method(m)
            if len(set(self.methods)) != len(self.methods):
                raise InputError(f"--methods: a method is named twice ({','.join(self.methods)})")
            if not self.n or any(int(k) < 1 for k in self.n):
                raise InputError(f"--n: sample counts must be positive integers, got {self.n}")
            if self.seeds < 1:
                raise InputError(f"--seeds must be at least 1, got {self.seeds}")
            if self.first_seed < 0:
                raise InputError(f"--first-seed must be at least 0, got {self.first_seed}")
            if "hypernet" in self.methods and not self.model:
                raise InputError("method 'hypernet' needs --model MODEL.safetensors")
            if "ipca" in self.methods and not self.ipca:
                raise InputError("method 'ipca' needs --ipca BASIS.safetensors "
                                 "(made by `brdfkit fit --method ipca`)")
        if self.nbrdf_steps is not None and self.nbrdf_steps < 1:
            raise InputError(f"--nbrdf-steps must be at least 1, got {self.nbrdf_steps}")
        if self.ipca_lambda is not None and not (self.ipca_lambda >= 0 and math.isfinite(self.ipca_lambda)):
            raise InputError(f"--ipca-lambda must be a finite number >= 0, got {self.ipca_lambda}")
        if self.compression_models and not self.compression_data:
            raise InputError("--compression-models needs --compression-data DIR")
        if self.compression_data and not self.compression_models:
            raise InputError("--compression-data needs --compression-models")
        if self.resolution < 7:
            raise InputError(f"--resolution must be at least 7 (the SSIM window), got {self.resolution}")
        if self.jobs < 1:
            raise InputError(f"--jobs must be at least 1, got {self.jobs}")
        if self.threads is not None and self.threads < 1:
            raise InputError(f"--threads must be at least 1, got {self.threads}")
        for f in [self.model, self.ipca, self.test_list, *self.compression_models]:
            if f:
                check_input_file(f)
        for d in (self.data, self.compression_data):
            if d is not None and not os.path.isdir(d):
                raise InputError(f"{d}: not a folder of MERL tables")


# ---------------------------------------------------------------------------------------
# inputs


def list_materials(folder: str, names=None) -> list[tuple[str, str]]:
    """``(name, path)`` of the MERL tables in ``folder`` (``*.binary``, sorted by name),
    restricted to ``names`` (file stems) when given; InputError naming any missing."""
    files = {}
    for f in sorted(os.listdir(folder)):
        if f.endswith(".binary") and not f.startswith("."):
            files[f[:-len(".binary")]] = os.path.join(folder, f)
    if not files:
        raise InputError(f"{folder}: folder holds no .binary files")
    if names is None:
        return sorted(files.items())
    wanted = [n[:-len(".binary")] if n.endswith(".binary") else n for n in names]
    missing = [n for n in wanted if n not in files]
    if missing:
        raise InputError(f"{folder}: no table for test material(s) {', '.join(missing)}")
    if not wanted:
        raise InputError("the test list names no material")
    return [(n, files[n]) for n in dict.fromkeys(wanted)]


def sample_seed(seed: int, n: int, name: str) -> int:
    """Seed of the draw of ``n`` samples of material ``name`` for repetition ``seed``:
    distinct per (seed, N, material), the same for every method."""
    return int(np.random.SeedSequence([int(seed), int(n), zlib.crc32(name.encode())]).generate_state(1)[0])


def _file_digest(path: str) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 22), b""):
            h.update(block)
    return h.hexdigest()


def _renderer_digest() -> str:
    """SHA-256 of the source of the modules a reference render depends on, so a changed
    renderer never reuses a cached render."""
    import importlib

    h = hashlib.sha256()
    for mod in ("render.quadrature", "render.scene", "render.envmap", "render.brdf", "geometry"):
        h.update(open(importlib.import_module(f"brdfkit.{mod}").__file__, "rb").read())
    return h.hexdigest()


def _family(name: str) -> str:
    return name.split("-", 1)[0] if "-" in name else name


def _failed_records(cfg: BenchConfig, kind: str, name: str, error: str, compressors=()) -> list[dict]:
    """The records of every reconstruction of one material, all failed with ``error``
    (``compressors``: the ``(label, latent)`` of the compression methods)."""
    if kind == "sparse":
        return [{"kind": kind, "material": name, "method": m, "n": int(k), "seed": s, "error": error}
                for m in cfg.methods for k in cfg.n for s in cfg.seed_list()]
    return [{"kind": kind, "material": name, "method": label, "latent": dim, "error": error}
            for label, dim in compressors]


def _error_text(e: BaseException) -> str:
    return f"{type(e).__name__}: {e}".splitlines()[0][:300]


# ---------------------------------------------------------------------------------------
# per-process state and work


class _Worker:
    """Everything one process needs: loaded models, the scene, the environment."""

    def __init__(self, cfg: BenchConfig):
        import torch

        self.cfg = cfg
        if cfg.threads is not None:
            torch.set_num_threads(cfg.threads)
        self.device = torch.device(cfg.device) if cfg.device else \
            torch.device("cuda" if torch.cuda.is_available() else "cpu")
        from .baselines import get_method
        from .render.envmap import reference_envmap
        from .render.scene import Scene

        self.scene = Scene(resolution=cfg.resolution)
        self.env = reference_envmap()
        self.methods, self.models, self.options = {}, {}, {}
        if cfg.data is not None:
            for name in cfg.methods:
                m = get_method(name)
                self.methods[name] = m
                path = {"hypernet": cfg.model, "ipca": cfg.ipca}.get(name)
                self.models[name] = m.load(path, self.device) if m.needs_model else None
                opts = {}
                if name == "nbrdf" and cfg.nbrdf_steps is not None:
                    opts["steps"] = int(cfg.nbrdf_steps)
                if name == "ipca" and cfg.ipca_lambda is not None:
                    opts["lam"] = float(cfg.ipca_lambda)
                self.options[name] = opts
        self.compressors = []
        self.trained = {}  # compression label -> names of the materials it was trained on
        if cfg.compression_models:
            from .api import load_model

            for path in cfg.compression_models:
                model = load_model(path, device=self.device)
                stem = os.path.splitext(os.path.basename(path))[0]
                self.compressors.append((f"hypernet {model.cfg.latent_dim}-D ({stem})",
                                         model.cfg.latent_dim, model))
                self.trained[self.compressors[-1][0]] = set(model.meta.get("materials") or ())
            if cfg.ipca:
                from .baselines.ipca import load_ipca

                basis = load_ipca(cfg.ipca)
                self.compressors.append((f"ipca {basis.n_components} components", basis.n_components, basis))
                self.trained[self.compressors[-1][0]] = set(basis.materials)
        self.warm = set()

    # -- scoring

    def render(self, table):
        from .render.brdf import TableBRDF
        from .render.quadrature import render

        img, _ = render(TableBRDF(table, device=self.device), self.scene, env=self.env)
        return img

    def reference(self, name: str, path: str, table):
        """The cached reference render of a material (rendered on first use)."""
        from .render.image import read_exr, write_exr

        cache = self.cfg.cache or os.path.join(self.cfg.output, "cache")
        # The key is the table's content and everything the render depends on (scene,
        # quadrature, environment, the renderer's code), not the name: a table reached under another name
        # (a symlink in a second folder) reuses its render.
        key = hashlib.sha256("\n".join([_file_digest(path), repr(self.scene), self.env.fingerprint(),
                                        repr(self.env.bright), _renderer_digest()]).encode()).hexdigest()[:16]
        suffix = f"-{self.cfg.resolution}px-{key}.exr"
        file = os.path.join(cache, name + suffix)
        found = [f for f in (os.listdir(cache) if os.path.isdir(cache) else []) if f.endswith(suffix)]
        for f in sorted(found, key=lambda f: f != name + suffix):
            try:
                img = read_exr(os.path.join(cache, f))
                if img.shape == (self.cfg.resolution, self.cfg.resolution, 3):
                    return img
            except InputError:
                pass  # a damaged cache file is simply rendered again
        img = self.render(table)
        os.makedirs(cache, exist_ok=True)
        write_exr(file, img)
        return img

    def score(self, table, ref_table, ref_img) -> dict:
        from .metrics import PSNR_CAP, brdf_log_rmse, image_metrics

        out = {"log_rmse": brdf_log_rmse(table, ref_table)}
        t0 = time.perf_counter()
        img = self.render(table)
        out["render_s"] = time.perf_counter() - t0
        m = image_metrics(img, ref_img)
        m["psnr"] = min(m["psnr"], PSNR_CAP)
        out.update(m)
        return out

    # -- timed reconstructions

    def _warm_up(self, method: str, table) -> None:
        """One untimed reconstruction per method and process: first calls pay for lazy
        imports, allocator growth and cached grids, which no user pays twice."""
        if method in self.warm:
            return
        from .samples import draw_samples

        opts = dict(self.options[method])
        if method == "nbrdf":
            opts["steps"] = min(20, opts.get("steps", 20))
        try:
            self.methods[method].reconstruct(draw_samples(table, 40, seed=12345), self.models[method],
                                             seed=0, device=self.device, **opts)
        except Exception:
            pass  # the timed call will record the failure
        self.warm.add(method)

    def sparse_material(self, name: str, path: str) -> list[dict]:
        from .merl import read_merl
        from .samples import draw_samples

        cfg = self.cfg
        base = {"kind": "sparse", "material": name}
        try:
            table = read_merl(path)
            ref_img = self.reference(name, path, table)
        except Exception as e:
            return _failed_records(cfg, "sparse", name, _error_text(e))
        records = []
        for k in cfg.n:
            for s in cfg.seed_list():
                draw = sample_seed(s, k, name)
                try:
                    samples = draw_samples(table, int(k), seed=draw, source=name)
                except Exception as e:
                    records += [dict(base, method=m, n=int(k), seed=s, error=_error_text(e))
                                for m in cfg.methods]
                    continue
                for m in cfg.methods:
                    rec = dict(base, method=m, n=int(k), seed=s, sample_seed=draw)
                    try:
                        self._warm_up(m, table)
                        t0, c0 = time.perf_counter(), time.process_time()
                        recon = self.methods[m].reconstruct(samples, self.models[m], seed=s,
                                                            device=self.device, **self.options[m])
                        rec["time_s"] = time.perf_counter() - t0
                        rec["cpu_s"] = time.process_time() - c0
                        rec.update(self.score(recon, table, ref_img))
                    except Exception as e:
                        rec["error"] = _error_text(e)
                    records.append(rec)
        return records

    def compression_material(self, name: str, path: str) -> list[dict]:
        from .merl import read_merl

        base = {"kind": "compression", "material": name}
        try:
            table = read_merl(path)
            ref_img = self.reference(name, path, table)
        except Exception as e:
            return _failed_records(self.cfg, "compression", name, _error_text(e),
                                   [(label, dim) for label, dim, _ in self.compressors])
        records = []
        for label, dim, model in self.compressors:
            rec = dict(base, method=label, latent=dim, trained_on=name in self.trained.get(label, ()))
            try:
                if label.startswith("ipca"):
                    t0, c0 = time.perf_counter(), time.process_time()
                    recon = model.decode(model.project(table))
                else:
                    from .api import decode, encode

                    t0, c0 = time.perf_counter(), time.process_time()
                    recon = decode(model, encode(model, table, source=name))
                rec["time_s"] = time.perf_counter() - t0
                rec["cpu_s"] = time.process_time() - c0
                rec.update(self.score(recon, table, ref_img))
            except Exception as e:
                rec["error"] = _error_text(e)
            records.append(rec)
        return records


_WORKER: _Worker | None = None


def _init_worker(cfg_dict: dict) -> None:
    global _WORKER
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent handles Ctrl-C
    _WORKER = _Worker(BenchConfig(**cfg_dict))


def _run_task(kind: str, name: str, path: str) -> list[dict]:
    fn = _WORKER.sparse_material if kind == "sparse" else _WORKER.compression_material
    return fn(name, path)


# ---------------------------------------------------------------------------------------
# summaries


def _mean(values):
    v = [x for x in values if x is not None and math.isfinite(x)]
    return float(np.mean(v)) if v else None


def _sd(values):
    v = [x for x in values if x is not None and math.isfinite(x)]
    return float(np.std(v, ddof=1)) if len(v) > 1 else None


def _summary_rows(records, keys) -> list[dict]:
    """One row per distinct ``keys`` value tuple: means, spreads, counts."""
    groups: dict = {}
    for r in records:
        groups.setdefault(tuple(r.get(k) for k in keys), []).append(r)
    rows = []
    for gk, recs in groups.items():
        ok = [r for r in recs if "error" not in r]
        row = dict(zip(keys, gk))
        row.update(count=len(ok), failures=len(recs) - len(ok),
                   materials=len({r["material"] for r in ok}))
        for m in METRICS + ("time_s", "cpu_s"):
            row[m] = _mean([r.get(m) for r in ok])
            by_seed, by_mat = {}, {}
            for r in ok:
                by_seed.setdefault(r.get("seed", 0), []).append(r.get(m))
                by_mat.setdefault(r["material"], []).append(r.get(m))
            row[m + "_sd_seeds"] = _sd([_mean(v) for v in by_seed.values()])
            row[m + "_sd_materials"] = _sd([_mean(v) for v in by_mat.values()])
        row["time_s_median"] = (float(np.median([r["time_s"] for r in ok])) if ok else None)
        rows.append(row)
    return rows


def summarise(records: list[dict], group_by_prefix: bool = False) -> dict:
    """Summaries of bench records: ``{"sparse": rows, "compression": rows}``; each row
    holds the keys (method, N / latent, and ``family`` with ``group_by_prefix``), the mean
    of every metric and its spreads (see the module doc), counts and failures."""
    sparse = [r for r in records if r["kind"] == "sparse"]
    comp = [r for r in records if r["kind"] == "compression"]
    out = {"sparse": _summary_rows(sparse, ("method", "n")),
           "compression": _summary_rows(comp, ("method", "latent")),
           "compression_by_training": _summary_rows(comp, ("method", "latent", "trained_on"))}
    if group_by_prefix:
        for r in records:
            r["family"] = _family(r["material"])
        out["sparse_by_family"] = _summary_rows(sparse, ("family", "method", "n"))
        out["compression_by_family"] = _summary_rows(comp, ("family", "method", "latent"))
    for key in out:
        out[key].sort(key=lambda row: tuple(str(row.get(k)) if not isinstance(row.get(k), (int, float))
                                            else f"{row.get(k):012.3f}" for k in
                                            ("family", "method", "n", "latent", "trained_on") if k in row))
    return out


# ---------------------------------------------------------------------------------------
# outputs


def _fmt(x, digits):
    return "n/a" if x is None else f"{x:.{digits}f}"


def _pm(row, m, digits):
    s = row.get(m + "_sd_seeds")
    return _fmt(row.get(m), digits) + ("" if s is None else f" ± {s:.{digits}f}")


_DIGITS = {"psnr": 2, "delta_e": 2, "ssim": 4, "log_rmse": 4, "time_s": 3}


def write_markdown(path: str, result: dict) -> None:
    """The human-readable tables of a bench result (``bench.md``)."""
    cfg, env, summ = result["config"], result["environment"], result["summary"]
    lines = ["# brdfkit bench", "",
             f"- command: `{cfg.get('command') or 'brdfkit bench'}`",
             f"- started {result['started']}, {result['elapsed_s']:.0f} s wall; "
             f"{'complete' if result['complete'] else 'INCOMPLETE (interrupted)'}"
             + (f"; merged from {len(result['merged_from'])} runs" if result.get("merged_from") else ""),
             *([f"- materials dropped because not every merged run covered them: "
                f"{', '.join(result['dropped_materials'])}"] if result.get("dropped_materials") else []),
             f"- machine: {env['machine']}, {env['cpus']} CPUs, torch {env['torch']} "
             f"({env['threads']} thread(s) per process, {cfg['jobs']} process(es)), device {env['device']}",
             f"- renders: reference scene, quadrature renderer, {cfg['resolution']} x {cfg['resolution']} "
             f"pixels, whole image; PSNR capped at 100 dB", ""]
    if summ["sparse"]:
        lines += ["## Sparse reconstruction", "",
                  f"{result['materials']['sparse_count']} test material(s) from `{cfg['data']}`, "
                  f"{_seed_text(cfg)} each; mean over materials and draws ± standard deviation "
                  f"over draws of the per-draw mean; wall time of one reconstruction: mean (median); "
                  f"CPU time: mean, all threads of the process.", "",
                  "| method | N | PSNR (dB) | Delta E 2000 | SSIM | BRDF log RMSE | wall time (s) | CPU time (s) | "
                  "ok / failed |",
                  "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
        for row in summ["sparse"]:
            lines.append(f"| {row['method']} | {row['n']} | {_pm(row, 'psnr', 2)} | {_pm(row, 'delta_e', 2)} | "
                         f"{_pm(row, 'ssim', 4)} | {_pm(row, 'log_rmse', 4)} | {_fmt(row['time_s'], 3)} "
                         f"({_fmt(row['time_s_median'], 3)}) | {_fmt(row['cpu_s'], 3)} | "
                         f"{row['count']} / {row['failures']} |")
        lines += ["", "### Per material: PSNR (dB), mean over draws", ""]
        lines += _per_material_table(result["records"], "psnr", 2)
        lines += ["", "### Per material: BRDF log RMSE, mean over draws", ""]
        lines += _per_material_table(result["records"], "log_rmse", 4)
    if summ.get("sparse_by_family"):
        lines += ["", "### Sparse, per family", "", "| family | method | N | PSNR (dB) | Delta E 2000 | SSIM | "
                  "BRDF log RMSE | materials |", "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: |"]
        for row in summ["sparse_by_family"]:
            lines.append(f"| {row['family']} | {row['method']} | {row['n']} | {_fmt(row['psnr'], 2)} | "
                         f"{_fmt(row['delta_e'], 2)} | {_fmt(row['ssim'], 4)} | {_fmt(row['log_rmse'], 4)} | "
                         f"{row['materials']} |")
    if summ["compression"]:
        lines += ["", "## Compression (encode the full table, decode)", "",
                  f"{result['materials']['compression_count']} material(s) from `{cfg['compression_data']}`; "
                  f"mean ± standard deviation over materials; time = encode + decode.", "",
                  "| model | latent / components | PSNR (dB) | Delta E 2000 | SSIM | BRDF log RMSE | wall time (s) | "
                  "CPU time (s) | ok / failed |", "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
        for row in summ["compression"]:
            lines.append(f"| {row['method']} | {row['latent']} | {_pmm(row, 'psnr', 2)} | {_pmm(row, 'delta_e', 2)} | "
                         f"{_pmm(row, 'ssim', 4)} | {_pmm(row, 'log_rmse', 4)} | {_fmt(row['time_s'], 3)} | "
                         f"{_fmt(row['cpu_s'], 3)} | {row['count']} / {row['failures']} |")
    if summ.get("compression_by_training") and any(r.get("trained_on") for r in summ["compression_by_training"]):
        lines += ["", "### Compression: training materials against held-out ones", "",
                  "| model | material in its training set | PSNR (dB) | Delta E 2000 | SSIM | BRDF log RMSE | "
                  "materials |", "| --- | --- | ---: | ---: | ---: | ---: | ---: |"]
        for row in summ["compression_by_training"]:
            lines.append(f"| {row['method']} | {'yes' if row['trained_on'] else 'no'} | {_pmm(row, 'psnr', 2)} | "
                         f"{_pmm(row, 'delta_e', 2)} | {_pmm(row, 'ssim', 4)} | {_pmm(row, 'log_rmse', 4)} | "
                         f"{row['materials']} |")
    if summ.get("compression_by_family"):
        lines += ["", "### Compression, per family", "", "| family | model | PSNR (dB) | Delta E 2000 | SSIM | "
                  "BRDF log RMSE | materials |", "| --- | --- | ---: | ---: | ---: | ---: | ---: |"]
        for row in summ["compression_by_family"]:
            lines.append(f"| {row['family']} | {row['method']} | {_pmm(row, 'psnr', 2)} | {_pmm(row, 'delta_e', 2)} | "
                         f"{_pmm(row, 'ssim', 4)} | {_pmm(row, 'log_rmse', 4)} | {row['materials']} |")
    failures = [r for r in result["records"] if "error" in r]
    if failures:
        lines += ["", f"## Failures ({len(failures)})", ""]
        seen = set()
        for r in failures:
            key = (r["material"], r["method"], r["error"])
            if key not in seen:
                seen.add(key)
                lines.append(f"- {r['material']}, {r['method']}: {r['error']}")
    lines.append("")
    with atomic_open(path, "w", encoding="utf-8") as f:
        f.write("\n".join(lines))


def _seed_text(cfg) -> str:
    seeds = cfg.get("seed_values") or list(range(cfg.get("first_seed", 0), cfg.get("first_seed", 0) + cfg["seeds"]))
    return f"{len(seeds)} draw(s) (seeds {', '.join(map(str, seeds))})"


def _pmm(row, m, digits):
    s = row.get(m + "_sd_materials")
    return _fmt(row.get(m), digits) + ("" if s is None else f" ± {s:.{digits}f}")


def _per_material_table(records, metric, digits) -> list[str]:
    sparse = [r for r in records if r["kind"] == "sparse"]
    methods = list(dict.fromkeys(r["method"] for r in sparse))
    ns = sorted({r["n"] for r in sparse})
    cols = [(m, k) for k in ns for m in methods]
    cell: dict = {}
    for r in sparse:
        if "error" not in r:
            cell.setdefault((r["material"], r["method"], r["n"]), []).append(r[metric])
    better = max if metric in ("psnr", "ssim") else min
    out = ["| material | " + " | ".join(f"{m} {k}" for m, k in cols) + " |",
           "| --- | " + " | ".join("---:" for _ in cols) + " |"]
    for mat in dict.fromkeys(r["material"] for r in sparse):
        vals = {c: _mean(cell.get((mat,) + c, [])) for c in cols}
        best = {}
        for k in ns:
            got = [vals[(m, k)] for m in methods if vals[(m, k)] is not None]
            best[k] = better(got) if got else None
        out.append(f"| {mat} | " + " | ".join(
            ("**" + _fmt(vals[c], digits) + "**") if vals[c] is not None and vals[c] == best[c[1]]
            else _fmt(vals[c], digits) for c in cols) + " |")
    return out


def write_plots(folder: str, result: dict) -> list[str]:
    """``error_vs_n.png``, ``error_vs_time.png`` (sparse) and ``compression.png``; returns
    the files written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    written = []
    rows = result["summary"]["sparse"]
    methods = list(dict.fromkeys(r["method"] for r in rows))
    for xkey, fname, xlabel in (("n", "error_vs_n.png", "number of samples N"),
                                ("time_s", "error_vs_time.png", "wall time per reconstruction (s)"),
                                ("cpu_s", "error_vs_cpu_time.png", "CPU time per reconstruction (s, all threads)")):
        if not rows:
            break
        fig, axes = plt.subplots(2, 2, figsize=(9, 7), constrained_layout=True)
        for ax, metric in zip(axes.flat, METRICS):
            for m in methods:
                pts = [r for r in rows if r["method"] == m and r[metric] is not None and r[xkey] is not None]
                pts.sort(key=lambda r: r["n"])
                if not pts:
                    continue
                x = [r[xkey] for r in pts]
                y = [r[metric] for r in pts]
                err = [r[metric + "_sd_seeds"] or 0.0 for r in pts]
                ax.errorbar(x, y, yerr=err, marker="o", capsize=3, label=m)
                if xkey != "n":
                    for r in pts:
                        ax.annotate(str(r["n"]), (r[xkey], r[metric]), textcoords="offset points",
                                    xytext=(4, 4), fontsize=7)
            ax.set_xscale("log")
            # labels at 1, 2, 5 x 10^k in plain numbers; matplotlib's default labels the
            # minor ticks of a short log axis so that they overlap
            ax.xaxis.set_major_locator(matplotlib.ticker.LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
            ax.xaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(lambda v, _: f"{v:g}"))
            ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
            ax.set_xlabel(xlabel)
            ax.set_ylabel(_LABELS[metric])
            ax.grid(True, which="both", alpha=0.3)
        axes.flat[0].legend()
        title = {"n": "error against N", "time_s": "error against wall time (points labelled with N)",
                 "cpu_s": "error against CPU time (points labelled with N)"}[xkey]
        fig.suptitle(f"brdfkit bench: {title}; {result['materials']['sparse_count']} materials, "
                     f"{_seed_text(result['config'])}", fontsize=10)
        out = os.path.join(folder, fname)
        with atomic_path(out) as tmp:
            fig.savefig(tmp, dpi=80, format="png")
        plt.close(fig)
        written.append(out)
    comp = [r for r in result["records"] if r["kind"] == "compression" and "error" not in r]
    if comp:
        labels = list(dict.fromkeys(r["method"] for r in comp))
        fig, axes = plt.subplots(1, 2, figsize=(9, 3.5), constrained_layout=True)
        for ax, metric in zip(axes, ("psnr", "log_rmse")):
            ax.boxplot([[r[metric] for r in comp if r["method"] == lab] for lab in labels])
            ax.set_xticks(range(1, len(labels) + 1), [lab.replace(" (", "\n(") for lab in labels], fontsize=7)
            ax.set_ylabel(_LABELS[metric])
            ax.grid(True, alpha=0.3)
        fig.suptitle("compression: encode the full table, decode (per material)", fontsize=10)
        out = os.path.join(folder, "compression.png")
        with atomic_path(out) as tmp:
            fig.savefig(tmp, dpi=80, format="png")
        plt.close(fig)
        written.append(out)
    return written


def _environment(cfg: BenchConfig) -> dict:
    import torch

    dev = cfg.device or ("cuda" if torch.cuda.is_available() else "cpu")
    threads = cfg.threads or (torch.get_num_threads() if cfg.jobs == 1 else max(1, (os.cpu_count() or 1) // cfg.jobs))
    return {"machine": platform.machine() + " " + platform.system(), "cpus": os.cpu_count(),
            "torch": torch.__version__, "threads": threads, "device": dev,
            "gpu": torch.cuda.get_device_name(0) if dev.startswith("cuda") and torch.cuda.is_available() else None,
            "python": sys.version.split()[0], "renderer": _renderer_digest()[:16],
            "method_defaults": _method_defaults()}


def _method_defaults() -> dict:
    """The baselines' default options in this code, recorded with every run (an option
    not given on the command line is one of these)."""
    from .baselines import ipca, nbrdf

    return {"ipca": {"lam": ipca.DEFAULT_LAMBDA},
            "nbrdf": {"steps": nbrdf.DEFAULT_STEPS, "lr": nbrdf.DEFAULT_LR, "patience": nbrdf.DEFAULT_PATIENCE}}


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


def run_bench(cfg: BenchConfig, progress: bool = True) -> dict:
    """Run the benchmark and write its outputs (see the module doc).

    Parameters
    ----------
    cfg
        :class:`BenchConfig`.
    progress
        Show a Rich progress bar on stderr.

    Returns
    -------
    dict
        The content of ``bench.json``: ``config``, ``environment``, ``materials``,
        ``records`` (one per reconstruction: material, method, N, seed, metrics,
        ``time_s``, ``render_s``, or ``error``), ``summary`` (:func:`summarise`),
        ``outputs``.

    Raises
    ------
    InputError
        Bad options, missing files or test materials, unreadable model files.
    """
    cfg.validate()
    os.makedirs(cfg.output, exist_ok=True)
    if cfg.jobs > 1 and cfg.threads is None:
        cfg = dataclasses.replace(cfg, threads=max(1, (os.cpu_count() or 1) // cfg.jobs))
    tasks = []
    if cfg.data is not None:
        names = None
        if cfg.test_list:
            from .trainset import read_exclude_list

            names = read_exclude_list(cfg.test_list)
        tasks += [("sparse", n, p) for n, p in list_materials(cfg.data, names)]
    n_sparse = len(tasks)
    if cfg.compression_models:
        tasks += [("compression", n, p) for n, p in list_materials(cfg.compression_data)]
    per_task = {"sparse": len(cfg.methods) * len(cfg.n) * cfg.seeds,
                "compression": len(cfg.compression_models) + (1 if cfg.ipca else 0)}
    result = {"format": "brdfkit-bench", "version": _FORMAT_VERSION,
              "started": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
              "config": dataclasses.asdict(cfg), "environment": _environment(cfg),
              "materials": {"sparse": [t[1] for t in tasks[:n_sparse]], "sparse_count": n_sparse,
                            "compression": [t[1] for t in tasks[n_sparse:]],
                            "compression_count": len(tasks) - n_sparse},
              "records": [], "complete": False, "elapsed_s": 0.0}
    json_path = os.path.join(cfg.output, "bench.json")
    t_start = time.perf_counter()

    def save(complete=False):
        result["complete"] = complete
        result["elapsed_s"] = time.perf_counter() - t_start
        result["summary"] = summarise(result["records"], cfg.group_by_prefix)
        with atomic_open(json_path, "w", encoding="utf-8") as f:
            json.dump(_json_safe(result), f, indent=1)

    from .console import ProgressBar

    total = sum(per_task[t[0]] for t in tasks)
    with ProgressBar("loading models", total=total, enabled=progress, count=True, transient=False) as bar:

        def done(task, recs):
            result["records"].extend(recs)
            bad = sum("error" in r for r in recs)
            bar.update(advance=per_task[task[0]],
                       description=f"{task[0]} {task[1]}" + (f" ({bad} failed)" if bad else ""))
            save()

        global _WORKER
        # Built here even for worker processes: a model file that does not load is a
        # usage error now, not a failure recorded for every reconstruction.
        _WORKER = _Worker(cfg)
        labels = [(label, dim) for label, dim, _ in _WORKER.compressors]
        if cfg.jobs == 1:
            try:
                for task in tasks:
                    bar.update(description=f"{task[0]} {task[1]}")
                    done(task, _run_task(*task))
            finally:
                _WORKER = None
        else:
            _WORKER = None
            import concurrent.futures
            import multiprocessing

            ctx = multiprocessing.get_context("spawn")  # no fork of a process holding torch threads
            with concurrent.futures.ProcessPoolExecutor(cfg.jobs, mp_context=ctx, initializer=_init_worker,
                                                        initargs=(dataclasses.asdict(cfg),)) as pool:
                try:
                    futures = {pool.submit(_run_task, *t): t for t in tasks}
                    for fut in concurrent.futures.as_completed(futures):
                        task = futures[fut]
                        try:
                            recs = fut.result()
                        except Exception as e:  # the worker died (e.g. out of memory)
                            recs = _failed_records(cfg, task[0], task[1], _error_text(e), labels)
                        done(task, recs)
                except KeyboardInterrupt:
                    pool.shutdown(wait=False, cancel_futures=True)
                    raise
    result["complete"] = True
    result["elapsed_s"] = time.perf_counter() - t_start
    return _finish(result, cfg.output, json_path, cfg.group_by_prefix)


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


def merge_results(paths, output: str, allow_incomplete: bool = False) -> dict:
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
    common, dropped = {}, []
    for kind in ("sparse", "compression"):
        covered = [{r["material"] for r in run["records"] if r["kind"] == kind} for run in runs]
        covered = [c for c in covered if c]
        common[kind] = set.intersection(*covered) if covered else set()
        dropped += sorted(set().union(*covered) - common[kind]) if covered else []
    seen, records = set(), []
    for run in runs:
        for r in run["records"]:
            if r["material"] not in common[r["kind"]]:
                continue
            key = (r["kind"], r["material"], r["method"], r.get("n"), r.get("seed"), r.get("latent"))
            if key in seen:
                raise InputError(f"two runs both hold {r['kind']} {r['material']} {r['method']} "
                                 f"N={r.get('n')} seed={r.get('seed')}; merge runs with other seeds or methods")
            seen.add(key)
            records.append(r)
    first = runs[0]
    cfg = dict(first["config"])
    cfg["seed_values"] = sorted({r["seed"] for r in records if r["kind"] == "sparse" and "seed" in r})
    cfg["seeds"] = len(cfg["seed_values"]) or cfg["seeds"]
    cfg["methods"] = list(dict.fromkeys(m for run in runs for m in run["config"]["methods"]))
    cfg["command"] = " + ".join(run["config"].get("command", "") for run in runs)
    mats = {"sparse": [m for m in dict.fromkeys(m for run in runs for m in run["materials"]["sparse"])
                       if m in common["sparse"]],
            "compression": list(dict.fromkeys(r["material"] for r in records if r["kind"] == "compression"))}
    result = dict(first, config=cfg, records=records, complete=all(run.get("complete") for run in runs),
                  dropped_materials=dropped,
                  elapsed_s=sum(run["elapsed_s"] for run in runs),
                  materials={**mats, "sparse_count": len(mats["sparse"]),
                             "compression_count": len(mats["compression"])},
                  merged_from=[run["started"] for run in runs])
    os.makedirs(output, exist_ok=True)
    return _finish(result, output, os.path.join(output, "bench.json"), cfg.get("group_by_prefix", False))
