"""The work of one benchmark process: load the models once, reconstruct, render and
score each material (:func:`brdfkit.evaluation.metrics.score`), cache the reference renders."""

from __future__ import annotations

import functools
import hashlib
import json
import os
import time

from brdfkit.io.digest import file_digest
from brdfkit.errors import InputError
from brdfkit.bench.config import BenchConfig

__all__ = ["Worker", "run_task", "init_process", "failed_records", "error_text", "renderer_digest"]


def renderer_digest() -> str:
    """SHA-256 of the source of the modules a reference render depends on, so a changed
    renderer never reuses a cached render."""
    from brdfkit.geometry import coordinates, grid, trilinear
    from brdfkit.render import envmap, nodes, pairs, quadrature, renderable, scene

    h = hashlib.sha256()
    for mod in (quadrature, scene, envmap, renderable, coordinates, grid, trilinear, nodes, pairs):
        with open(mod.__file__, "rb") as f:
            h.update(f.read())
    return h.hexdigest()


def failed_records(cfg: BenchConfig, kind: str, name: str, error: str, compressors=()) -> list[dict]:
    """The records of every reconstruction of one material, all failed with ``error``
    (``compressors``: the ``(label, size)`` of the compression methods, ``size`` the numbers
    per material)."""
    if kind == "sparse":
        return [{"kind": kind, "material": name, "method": m, "n": int(k), "seed": s, "sampling": sampling,
                 "error": error}
                for m in cfg.methods for k in cfg.n for s in cfg.seed_list() for sampling in cfg.sampling]
    return [{"kind": kind, "material": name, "method": label, "size": dim, "error": error}
            for label, dim in compressors]


def error_text(e: BaseException) -> str:
    return f"{type(e).__name__}: {e}".splitlines()[0][:300]


class Worker:
    """Everything one process needs: loaded models, the scene, the environment."""

    def __init__(self, cfg: BenchConfig):
        from brdfkit.runtime import resolve_device
        from brdfkit.methods import get_method
        from brdfkit.render.scene import Scene
        from brdfkit.render.scene_suite import scene_env

        self.cfg = cfg
        self.device = resolve_device(cfg.device)
        self.scene = Scene(resolution=cfg.resolution)
        self.envs = {name: scene_env(name) for name in cfg.scenes}
        self.methods, self.models, self.options = {}, {}, {}
        self.protocols = {}  # sampling -> brdfkit.acquisition.protocol.SamplingProtocol
        if cfg.data is not None:
            from brdfkit.acquisition.protocol import SamplingProtocol

            for sampling in cfg.sampling:
                self.protocols[sampling] = (SamplingProtocol(sampling, cfg.plan_basis(), cfg.plan_design)
                                            if sampling == "planned" else SamplingProtocol(sampling))
            for name in cfg.methods:
                m = get_method(name)
                self.methods[name] = m
                self.models[name] = m.load(cfg.model_file(name), self.device) if m.needs_model else None
                self.options[name] = cfg.method_options(name)
        # (label, numbers per material, compress(table, name) -> table), see BenchConfig.compressors
        self.compressors = []
        self.trained = {}  # compression label -> names of the materials it was trained on
        for entry, what in cfg.compressors():
            label, size, compress, trained = _compressor(cfg, entry, what, self.device)
            self.compressors.append((label, size, compress))
            self.trained[label] = trained
        self.warm = set()

    # -- scoring

    def render(self, table) -> dict:
        """``{scene: image}`` of a table in every scene of the run."""
        from brdfkit.render.quadrature import render
        from brdfkit.render.renderable import TableBRDF

        brdf = TableBRDF(table, device=self.device)
        return {name: render(brdf, self.scene, env=env)[0] for name, env in self.envs.items()}

    def reference(self, name: str, path: str, table) -> dict:
        """The cached renders of a material in every scene (rendered on first use)."""
        todo = {s: self._cache_file(name, path, s) for s in self.envs}
        out = {s: self._cached(name, f) for s, f in todo.items()}
        if any(img is None for img in out.values()):
            from brdfkit.render.image import write_exr

            out = self.render(table)
            for s, file in todo.items():
                os.makedirs(os.path.dirname(file), exist_ok=True)
                write_exr(file, out[s])
        return out

    def _cache_file(self, name: str, path: str, scene: str) -> str:
        """The cache file of a material's render in ``scene``. The key is the table's
        content and everything the render depends on (scene, quadrature, environment,
        the renderer's code), not the name: a table reached under another name (a symlink
        in a second folder) reuses its render."""
        env = self.envs[scene]
        key = hashlib.sha256("\n".join([file_digest(path), repr(self.scene), env.digest(),
                                        repr(env.bright), renderer_digest()]).encode()).hexdigest()[:16]
        return os.path.join(self.cfg.cache or os.path.join(self.cfg.output, "cache"),
                            f"{name}-{self.cfg.resolution}px-{key}.exr")

    def _cached(self, name: str, file: str):
        """A cached render (``file``, or one of another name with the same key), or ``None``."""
        from brdfkit.render.image import read_exr

        cache, suffix = os.path.dirname(file), file[len(os.path.join(os.path.dirname(file), name)):]
        found = [f for f in (os.listdir(cache) if os.path.isdir(cache) else []) if f.endswith(suffix)]
        for f in sorted(found, key=lambda f: f != os.path.basename(file)):
            try:
                img = read_exr(os.path.join(cache, f))
                if img.shape == (self.cfg.resolution, self.cfg.resolution, 3):
                    return img
            except InputError:
                pass  # a damaged cache file is simply rendered again
        return None

    def score(self, table, ref_table, ref_imgs: dict) -> dict:
        """:func:`brdfkit.evaluation.metrics.score` of a reconstruction (rendered here in
        every scene, the renders timed as ``render_s``); the BRDF log RMSE is recorded as
        ``log_rmse``, the peak region's check as ``highlights``
        (:func:`brdfkit.evaluation.metrics.highlights`). In several scenes, the image scores
        are their means and ``scenes`` holds each scene's. ``darkest_ratio`` is the smallest
        ratio of the reconstruction to the data where the data are at least 1 /sr
        (:func:`brdfkit.evaluation.metrics.darkest_ratio`: below 1e-3, a black corner)."""
        from brdfkit.evaluation.comparison import mean_scores
        from brdfkit.evaluation.metrics import brdf_log_rmse, darkest_ratio, highlights, score

        t0 = time.perf_counter()
        imgs = self.render(table)
        render_s = time.perf_counter() - t0
        per = {s: score(imgs[s], ref_imgs[s]) for s in imgs}
        out = per[next(iter(per))] if len(per) == 1 else mean_scores(list(per.values()))
        out = {k: v for k, v in out.items() if k != "brdf_log_rmse"}
        if len(per) > 1:
            out["scenes"] = {s: {k: v for k, v in r.items() if k != "brdf_log_rmse"} for s, r in per.items()}
        out["log_rmse"] = brdf_log_rmse(table, ref_table)
        out["highlights"] = highlights(table, ref_table)
        out["darkest_ratio"] = darkest_ratio(table, ref_table)
        out["render_s"] = render_s
        return out

    def _timed(self, rec: dict, table, ref_imgs, reconstruct) -> dict:
        """``rec`` with the wall and CPU time of ``reconstruct()`` (``time_s``, ``cpu_s``)
        and the scores of the table it returns, or with the ``error`` it raised."""
        try:
            t0, c0 = time.perf_counter(), time.process_time()
            recon = reconstruct()
            rec["time_s"] = time.perf_counter() - t0
            rec["cpu_s"] = time.process_time() - c0
            rec.update(self.score(recon, table, ref_imgs))
        except Exception as e:
            rec["error"] = error_text(e)
        return rec

    def run(self, kind: str, name: str, path: str) -> list[dict]:
        """The records of one material: ``kind`` ``"sparse"`` or ``"compression"``."""
        fn = self.sparse_material if kind == "sparse" else self.compression_material
        return fn(name, path)

    # -- timed reconstructions

    def _warm_up(self, method: str, table) -> None:
        """One untimed reconstruction per method and process: first calls pay for lazy
        imports, allocator growth and cached grids, which no user pays twice."""
        if method in self.warm:
            return
        from brdfkit.acquisition.sampling import draw_samples

        try:
            self.methods[method].reconstruct(draw_samples(table, 40, seed=12345), self.models[method],
                                             seed=0, device=self.device, options=self.options[method].quick())
        except Exception:
            pass  # the timed call will record the failure
        self.warm.add(method)

    def sparse_material(self, name: str, path: str) -> list[dict]:
        """The records of one material: for each N, draw and sampling, the samples of
        the protocol (:meth:`brdfkit.acquisition.protocol.SamplingProtocol.samples`, what
        ``benchmarks/eval_sparse.py`` takes too), reconstructed by every method."""
        from brdfkit.io.merl import read_merl

        cfg = self.cfg
        base = {"kind": "sparse", "material": name}
        try:
            table = read_merl(path)
            ref_imgs = self.reference(name, path, table)
        except Exception as e:
            return failed_records(cfg, "sparse", name, error_text(e))
        records = []
        for k in cfg.n:
            for s in cfg.seed_list():
                for sampling, protocol in self.protocols.items():
                    try:
                        samples, info = protocol.samples(table, name, int(k), s)
                    except Exception as e:
                        records += [dict(base, method=m, n=int(k), seed=s, sampling=sampling, error=error_text(e))
                                    for m in cfg.methods]
                        continue
                    for m in cfg.methods:
                        self._warm_up(m, table)
                        records.append(self._timed(
                            dict(base, method=m, n=int(k), seed=s, **info), table, ref_imgs,
                            lambda m=m, s=s, samples=samples: self.methods[m].reconstruct(
                                samples, self.models[m], seed=s, device=self.device, options=self.options[m])))
        return records

    def compression_material(self, name: str, path: str) -> list[dict]:
        from brdfkit.io.merl import read_merl

        base = {"kind": "compression", "material": name}
        try:
            table = read_merl(path)
            ref_imgs = self.reference(name, path, table)
        except Exception as e:
            return failed_records(self.cfg, "compression", name, error_text(e),
                                   [(label, dim) for label, dim, _ in self.compressors])
        records = []
        for label, dim, compress in self.compressors:
            records.append(self._timed(
                dict(base, method=label, size=dim, trained_on=name in self.trained.get(label, ())), table,
                ref_imgs, lambda compress=compress: compress(table, name)))
        return records


def _compressor(cfg: BenchConfig, entry: str, what, device) -> tuple:
    """``(label, numbers per material, compress(table, name) -> table, training materials)``
    of one entry of :meth:`BenchConfig.compressors`; the label says what runs: ``basis-39
    (merl80-basis)`` (a basis embedding of 39 numbers), ``hypernet-40 (merl80-l40)``,
    ``basis-13 (39 numbers)`` (the projection onto the ``ipca`` basis's 13 leading
    components), ``basis-8 (24 numbers, basis8)`` (a method's own basis, whole)."""
    if entry == "embedding":
        from brdfkit.embeddings import encode_with, get_kind, load_decoder, open_embedding
        from brdfkit.models.parts import get_part

        path, kind, size = what
        dec = load_decoder(kind, path, device)
        stem = os.path.splitext(os.path.basename(path))[0]
        trained = get_part(get_kind(kind).part).materials(dec.obj)

        def compress(table, name, dec=dec, size=size):
            return open_embedding(encode_with(dec, table, source=name, size=size), dec, name).to_table()

        return f"{kind}-{size} ({stem})", size, compress, trained
    if entry == "basis":  # the ipca basis's K leading components, projected
        from brdfkit.models.builtin import load_part

        basis = load_part(cfg.model_file("ipca"), "basis").leading(what)
        return (f"basis-{what} ({3 * what} numbers)", 3 * what, lambda table, name: basis.decode(basis.project(table)),
                set(basis.materials))
    method, path = what
    model = method.load(path, device)
    label, size, trained = method.describe_fn(model, path)
    return label, size, lambda table, name: method.compress_fn(model, table, name), trained


@functools.lru_cache(maxsize=1)
def _process_worker(cfg_json: str) -> Worker:
    """The :class:`Worker` of a pool process, built on its first task (one
    configuration per process)."""
    from brdfkit.runtime import set_torch_threads

    cfg = BenchConfig(**json.loads(cfg_json))
    if cfg.threads is not None:
        set_torch_threads(cfg.threads)  # a process the benchmark started: its threads are ours
    return Worker(cfg)


def init_process() -> None:
    """Pool initializer: the parent handles Ctrl-C."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)


def run_task(cfg_json: str, kind: str, name: str, path: str) -> list[dict]:
    """One material's records in a pool process (``cfg_json``: the configuration)."""
    return _process_worker(cfg_json).run(kind, name, path)
