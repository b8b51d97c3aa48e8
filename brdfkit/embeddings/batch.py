"""Many BRDF files encoded in one command (``brdfkit encode merl/*.binary``): each part of
the model loaded once, the next table read while the current one is encoded, and, with
``jobs > 1``, worker processes.

The work of one file is the same whatever the batch: its table, the decoder (loaded once
per process), its encode (in fixed pieces of work, with NumPy's BLAS on a fixed thread
count, :data:`brdfkit.render.objective.THREADS`), its ``.emb`` written atomically. An
output's bytes do not depend on ``jobs`` nor on the tables encoded before it in the
process: the 20 MERL test proxies give the same bytes each alone in a fresh process, in
one batch and with ``jobs=2`` (``tests/test_batch_bytes.py``; a compact basis whose
components an earlier table restored used to compute on them, and changed the last bits
of chrome-steel, black-oxidized-steel, violet-rubber and aluminium).
A process keeps what every table shares: the decoder, the objective scenes' pairs
(:func:`brdfkit.render.screen.screen`) and, per basis, the held-out pixels' maps.

Examples
--------
>>> target_of("merl/teflon.binary", None), target_of("a/b.csv", "out")
('merl/teflon.emb', 'out/b.emb')
"""

from __future__ import annotations

import dataclasses
import os

__all__ = ["EncodeJob", "Outcome", "Reader", "target_of", "plan_targets", "encode_files"]


def target_of(path: str, output_dir: str | None) -> str:
    """The ``.emb`` an input is encoded into: ``<stem>.emb`` in ``output_dir``, or beside
    the input."""
    stem = os.path.splitext(os.path.basename(path))[0]
    return os.path.join(output_dir if output_dir else os.path.dirname(path) or ".", stem + ".emb")


@dataclasses.dataclass(frozen=True)
class EncodeJob:
    """What every file of a batch is encoded with: the ``-m`` value, ``--kind``, ``--size``,
    ``--steps``, ``--refine`` and ``--max-seconds`` of ``brdfkit encode``, the output
    folder (``None``: beside each input), and the two functions of the layer above that do
    the work (module-level, so that a worker process receives them by name):
    ``read(path, source)`` -> ``(data, source)`` and ``encode(data, decoder, **options)``
    -> an :class:`~brdfkit.io.embedding.Embedding` (:func:`brdfkit.api.load_input`,
    :func:`brdfkit.api.encode`)."""

    model: str | None = None
    kind: str | None = None
    size: int | None = None
    steps: int | None = None
    refine: bool = True
    max_seconds: float | None = None
    output_dir: str | None = None
    read: object = None
    encode: object = None

    def decoders(self, tables: bool, samples: bool) -> tuple:
        """``(for tables, for sample sets)``: the decoders (loaded once per process;
        ``None`` where there is no such input)."""
        from brdfkit.embeddings.decoders import choose_decoder
        from brdfkit.embeddings.registry import kind_of_part

        dec = choose_decoder(self.kind, self.model, size=self.size) if tables else None
        lat = choose_decoder(kind_of_part("network").name, self.model) if samples else None
        return dec, lat


@dataclasses.dataclass
class Outcome:
    """One file's result: its ``target``, and either what was written (``kind``, ``size``,
    the decoder's ``label``, the ``refinement`` record) or the one-line ``error``."""

    path: str
    target: str
    kind: str = ""
    size: int = 0
    label: str = ""
    refinement: dict | None = None
    error: str | None = None


def plan_targets(paths, output_dir) -> tuple[list, list]:
    """``([(index, path, target)], [(index, Outcome with an error)])``: each input's
    ``.emb``, a target that an earlier input already takes refused (one line naming both)."""
    taken: dict = {}
    plan, refused = [], []
    for i, path in enumerate(paths):
        target = target_of(path, output_dir)
        key = os.path.realpath(target)
        if key in taken:
            refused.append((i, Outcome(path, target, error=f"{path}: would write {target}, already written for "
                                                           f"{taken[key]}; rename one of them")))
            continue
        taken[key] = path
        plan.append((i, path, target))
    return plan, refused


def _encode_one(path, target, data, job: EncodeJob, decoders, inputs) -> Outcome:
    """Encode one read input and write its ``.emb`` (errors as the outcome's line)."""
    from brdfkit.atomic import refuse_overwrite_of_inputs
    from brdfkit.errors import BrdfkitError
    from brdfkit.io.embedding import write_embedding
    from brdfkit.runtime import stage

    samples = path.lower().endswith(".csv")
    dec = decoders[1] if samples else decoders[0]
    try:
        if isinstance(data, BaseException):
            raise data
        refuse_overwrite_of_inputs(target, [*inputs, dec.path])
        with stage("encode"):
            emb = job.encode(data[0], dec, size=None if samples else job.size, refine=job.refine, steps=job.steps,
                             max_seconds=job.max_seconds, source=data[1] or os.path.basename(path))
        with stage("write embedding"):
            write_embedding(target, emb)
    except (BrdfkitError, OSError) as e:
        return Outcome(path, target, error=str(e) if isinstance(e, BrdfkitError) else f"{path}: {e.strerror or e}")
    return Outcome(path, target, emb.kind, emb.size, dec.label, emb.refinement)


def _read_safely(path, job: EncodeJob):
    """The data of an input (a dense table or a sample set), or the error reading it."""
    from brdfkit.errors import BrdfkitError

    try:
        return job.read(path, "")
    except (BrdfkitError, OSError) as e:
        return e


class Reader:
    """Inputs read on a thread, one ahead of the encode (``job.read``): :meth:`start` a
    file's read (the command starts the first one before the model loads), :meth:`take`
    its data or the error reading it."""

    def __init__(self, job: EncodeJob):
        from concurrent.futures import ThreadPoolExecutor

        self.job, self.pool, self.pending = job, ThreadPoolExecutor(max_workers=1), {}

    def start(self, path: str) -> None:
        path = os.fspath(path)
        if path not in self.pending:
            self.pending[path] = self.pool.submit(_read_safely, path, self.job)

    def take(self, path: str):
        self.start(path)
        return self.pending.pop(os.fspath(path)).result()

    def close(self) -> None:
        self.pool.shutdown(wait=False, cancel_futures=True)


def _serial(plan: list, job: EncodeJob, decoders, inputs, on_done, reader: Reader | None = None):
    """Encode in this process, reading the next input on a thread meanwhile."""
    from brdfkit.runtime import stage

    reader = reader or Reader(job)
    out = []
    try:
        for n, (i, path, target) in enumerate(plan):
            with stage("read table (waiting for the reader)"):
                data = reader.take(path)
            if n + 1 < len(plan):
                reader.start(plan[n + 1][1])
            out.append((i, _encode_one(path, target, data, job, decoders, inputs)))
            if on_done is not None:
                on_done(out[-1][1])
    finally:
        reader.close()
    return out


_WORKER: dict = {}


def _worker_init(job: EncodeJob, tables: bool, samples: bool, inputs) -> None:
    from brdfkit.runtime import set_cpu_threads

    set_cpu_threads(1)  # the processes share the cores
    _WORKER.update(job=job, decoders=job.decoders(tables, samples), inputs=inputs)


def _worker_one(item) -> tuple:
    i, path, target = item
    return i, _encode_one(path, target, _read_safely(path, _WORKER["job"]), _WORKER["job"], _WORKER["decoders"], _WORKER["inputs"])


def encode_files(paths, job: EncodeJob, *, jobs: int = 1, on_done=None, reader: Reader | None = None) -> list[Outcome]:
    """Encode BRDF files (MERL ``.binary``, RGL ``.bsdf``, ``.csv`` sample sets) into their
    ``.emb`` (:func:`target_of`), in order; a bad input is an outcome with its error, and
    the others go on.

    Parameters
    ----------
    paths
        The inputs.
    job
        :class:`EncodeJob`.
    jobs
        Processes: 1 encodes here (the next input read on a thread meanwhile); more start
        that many workers, each loading the model once (the outputs are the same bytes).
    on_done
        Called with each :class:`Outcome` as it is made.
    reader
        A :class:`Reader` that may have started reading the first input already (in
        this process: ``jobs`` 1, or one input); closed when done.

    Returns
    -------
    list
        An :class:`Outcome` per input, in the order given.
    """
    paths = [os.fspath(p) for p in paths]
    plan, refused = plan_targets(paths, job.output_dir)
    tables = any(not p.lower().endswith(".csv") for _, p, _ in plan)
    samples = any(p.lower().endswith(".csv") for _, p, _ in plan)
    if job.output_dir:
        os.makedirs(job.output_dir, exist_ok=True)
    for _, r in refused:
        if on_done is not None:
            on_done(r)
    if jobs <= 1 or len(plan) <= 1:
        done = _serial(plan, job, job.decoders(tables, samples), paths, on_done, reader)
    else:
        if reader is not None:
            reader.close()
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        done = []
        ctx = multiprocessing.get_context("spawn")  # no forked threads (the reader, BLAS)
        with ProcessPoolExecutor(max_workers=min(jobs, len(plan)), mp_context=ctx, initializer=_worker_init,
                                 initargs=(job, tables, samples, paths)) as pool:
            for i, outcome in pool.map(_worker_one, plan):
                done.append((i, outcome))
                if on_done is not None:
                    on_done(outcome)
    return [o for _, o in sorted(done + refused, key=lambda x: x[0])]
