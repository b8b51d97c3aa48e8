"""Errors of predicted BRDF files or images against references: the work of
``brdfkit metrics``.

A BRDF file (MERL ``.binary``, RGL ``.bsdf``, or ``.emb`` with its model) is rendered in the reference
scene by the quadrature renderer (:func:`brdfkit.files.render_file.render_brdf_file`); an
``.exr`` is taken as it is. Each pair is scored by :func:`brdfkit.evaluation.metrics.score`, the
same function the benchmark uses. Two folders are compared file by file, matched by
file stem.
"""

from __future__ import annotations

import collections
import dataclasses
import hashlib
import os

from brdfkit.files.brdf_file import EmbeddingDecoders, read_table
from brdfkit.errors import InputError
from brdfkit.io.digest import file_digest

__all__ = ["SUFFIXES", "FileLoader", "RenderCounts", "compare_files", "compare_folders", "mean_scores"]

SUFFIXES = (".binary", ".bsdf", ".emb", ".exr")
TABLE_SUFFIXES = (".binary", ".bsdf")  # BRDF files that hold a table (read once per loader)
KEYS = ("psnr", "delta_e", "ssim", "brdf_log_rmse")
# Dense tables a FileLoader keeps (35 MB each): the pair being compared, and the
# reference of the next pair in a folder.
TABLES_KEPT = 3


def _kind(path: str) -> str:
    ext = os.path.splitext(path)[1].lower()
    if ext == ".exr":
        return "image"
    if ext in (".binary", ".bsdf", ".emb"):
        return "brdf"
    raise InputError(f"{path}: not a BRDF (.binary, .bsdf, .emb) or an image (.exr)")


@dataclasses.dataclass
class RenderCounts:
    """What a :class:`FileLoader` rendered.

    Attributes
    ----------
    passes
        Quadrature passes made (a pair of BRDF files is rendered in one).
    renders
        BRDF files rendered.
    cached
        Renders taken from the loader's cache instead (same file content, same scene).
    """

    passes: int = 0
    renders: int = 0
    cached: int = 0


class FileLoader:
    """Reads inputs: images, reference-scene renders and dense tables; loads the decoders
    of ``.emb`` inputs once, on first need.

    A BRDF file's render is kept in memory, keyed by the SHA-256 of the file's bytes (an
    ``.emb`` records its decoder's digest) and the scene settings, so a reference
    scored against several predictions is rendered once per loader (``counts`` says how
    often that happened).

    Parameters
    ----------
    model_path
        Decoder file (or built-in name) of ``.emb`` inputs; ``None``: the installed
        built-in part whose digest each ``.emb`` records, else an ``.emb`` is an error.
    resolution
        Render size of BRDF inputs (``None``: the reference scene's 256).
    progress
        Show render progress on stderr.
    before_torch
        Called once, before the first decoder that runs in torch is loaded (a
        hypernetwork's): ``brdfkit metrics`` sizes torch's thread pool there, so that
        nothing else imports torch.
    keep
        Dense tables kept (35 MB each; default :data:`TABLES_KEPT`): a sheet keeps all of
        its inputs', which it reads again for each step (fewer, and each is read anew).
    """

    def __init__(self, model_path=None, resolution: int | None = None, progress: bool = True,
                 before_torch=None, keep: int = TABLES_KEPT):
        self.model_path = model_path
        self.resolution = resolution
        self.progress = progress
        self._before_torch = before_torch
        self._models = EmbeddingDecoders(model_path, before_load=self._torch_needed)
        self._renders: dict = {}
        self._tables: collections.OrderedDict = collections.OrderedDict()
        self.keep = max(1, int(keep))
        self.counts = RenderCounts()

    def _torch_needed(self):
        if self._before_torch is not None:
            hook, self._before_torch = self._before_torch, None
            hook()

    def image(self, path, resolution=None, scene: str = "reference"):
        """An ``.exr`` as it is, a BRDF file rendered in ``scene`` (a suite scene's name)."""
        from brdfkit.render.image import read_exr

        if _kind(path) == "image":
            return read_exr(path)
        return self.renders([path], resolution, scene)[0]

    def _render_key(self, path, settings, scene: str) -> str:
        return hashlib.sha256("\n".join([file_digest(path), repr(settings), scene]).encode()).hexdigest()

    def renders(self, paths, resolution=None, scene: str = "reference") -> list:
        """Renders of BRDF files in a suite scene (:mod:`brdfkit.render.scene_suite`):
        float32 ``(R, R, 3)`` each; the ones not cached are rendered together in one
        quadrature pass."""
        from brdfkit.files import render_file as files

        settings = files.reference_scene(resolution or self.resolution)
        keys = [self._render_key(p, settings, scene) for p in paths]
        todo = {}
        for key, path in zip(keys, paths):
            if key not in self._renders:
                todo.setdefault(key, path)
        self.counts.cached += len(paths) - len(todo)
        if todo:
            # A .bsdf is rendered from the file itself, as Mitsuba renders it (its table is
            # reciprocal, the file is not); .binary tables are read once per loader.
            tables = {p: self.table(p) for p in todo.values() if p.lower().endswith(".binary")}
            images = files.render_brdf_files(list(todo.values()), resolution=settings.resolution,
                                             progress=self.progress, model=self._models, tables=tables, scene=scene)
            self._renders.update(zip(todo, images))
            self.counts.passes += 1
            self.counts.renders += len(todo)
        return [self._renders[k].copy() for k in keys]

    def remember(self, path, image, resolution=None, scene: str = "reference") -> None:
        """Keep ``image`` as the render of the BRDF file ``path`` in ``scene`` (made
        elsewhere, of the same table at the same settings): :meth:`renders` returns it
        instead of rendering the file again."""
        from brdfkit.files import render_file as files

        settings = files.reference_scene(resolution or self.resolution)
        self._renders[self._render_key(path, settings, scene)] = image

    def check(self, path):
        """Read ``path`` (and the decoder an ``.emb`` needs) without rendering: a bad
        reference must not cost a render of the prediction first (a 256 px render is
        minutes on a busy 2-core machine; docs/stability.md)."""
        if _kind(path) == "image":
            from brdfkit.render.image import read_exr

            read_exr(path)
        elif path.lower().endswith(".emb"):
            self._models.open(path)
        else:
            self.table(path)

    def table(self, path):
        """The dense table of a BRDF file; a table file (``.binary``, ``.bsdf``) is read once per loader (the
        check, the render and the BRDF-space error all need it), the last :attr:`keep`
        kept."""
        if path.lower().endswith(TABLE_SUFFIXES):
            st = os.stat(path)
            key = (os.path.realpath(path), st.st_ino, st.st_size, st.st_mtime_ns)  # a rewritten file is read again
            if key not in self._tables:
                table = read_table(path)
                table.setflags(write=False)  # shared by the check, the render and the scores
                self._tables[key] = table
                while len(self._tables) > self.keep:
                    self._tables.popitem(last=False)
            self._tables.move_to_end(key)
            return self._tables[key]
        return read_table(path, self._models)


def compare_files(loader: FileLoader, pred: str, ref: str, scenes=None, highlights: bool = False) -> dict:
    """:func:`brdfkit.evaluation.metrics.score` of one prediction against one reference; a BRDF
    compared with an image is rendered at the image's size.

    Parameters
    ----------
    scenes
        Suite scene names (:func:`brdfkit.render.scene_suite.scene_names`) to score two
        BRDF files in; ``None``: the reference scene, as before the suite.
    highlights
        Also check the peak region of two BRDF files (``"highlights"``).

    Returns
    -------
    dict
        ``{"psnr", "delta_e", "ssim", "brdf_log_rmse"}``, with ``highlights`` and two BRDF
        files ``"highlights"`` (:func:`brdfkit.evaluation.metrics.highlights`: the peak
        region's brightness against the reference's); with ``scenes``, the image scores are their
        means over the scenes, and ``"scenes"`` holds ``{name: {"psnr", "delta_e", "ssim"}}``.
    """
    from brdfkit.atomic import check_input_file
    from brdfkit.evaluation.metrics import brdf_log_rmse, highlights as peak_check, score

    check_input_file(pred)
    check_input_file(ref)
    kp, kr = _kind(pred), _kind(ref)
    loader.check(pred)
    loader.check(ref)
    both = kp == kr == "brdf"
    if scenes is not None:
        if not both:
            raise InputError(f"{pred if kp == 'image' else ref}: --scenes renders BRDF files; an image has no scene")
        per = {}
        for name in scenes:
            img_p, img_r = loader.renders([pred, ref], None, name)  # one pass for the pair
            per[name] = {k: v for k, v in score(img_p, img_r).items() if k != "brdf_log_rmse"}
        out = mean_scores(list(per.values()))
        out["brdf_log_rmse"] = brdf_log_rmse(loader.table(pred), loader.table(ref))
        out["scenes"] = per
    else:
        img_p, img_r = _image_pair(loader, pred, ref, kp, kr)
        out = score(img_p, img_r, loader.table(pred) if both else None, loader.table(ref) if both else None)
    if both and highlights:
        out["highlights"] = peak_check(loader.table(pred), loader.table(ref))
    return out


def _image_pair(loader: FileLoader, pred: str, ref: str, kp: str, kr: str):
    """The two images a reference-scene comparison scores: given images as they are,
    BRDF files rendered (at a given image's size)."""
    size = None
    img_r = loader.image(ref) if kr == "image" else None
    img_p = loader.image(pred) if kp == "image" else None
    for img, path in ((img_r, ref), (img_p, pred)):
        if img is not None and size is None:
            if img.shape[0] != img.shape[1]:
                if kp != kr:
                    raise InputError(f"{path}: a {img.shape[1]}x{img.shape[0]} image cannot be compared "
                                     "with a reference-scene render (square)")
            size = img.shape[0]
    if img_p is None and img_r is None:
        img_p, img_r = loader.renders([pred, ref], size)  # one pass for the pair
    elif img_p is None:
        img_p = loader.image(pred, size)
    elif img_r is None:
        img_r = loader.image(ref, size)
    if img_p.shape != img_r.shape:
        raise InputError(f"{pred}, {ref}: image sizes differ ({img_p.shape[1]}x{img_p.shape[0]} "
                         f"and {img_r.shape[1]}x{img_r.shape[0]})")
    return img_p, img_r


def _stems(folder: str) -> dict:
    found = {}
    for name in sorted(os.listdir(folder)):
        stem, ext = os.path.splitext(name)
        if ext.lower() in SUFFIXES and os.path.isfile(os.path.join(folder, name)):
            found.setdefault(stem, os.path.join(folder, name))
    return found


def compare_folders(loader: FileLoader, pred: str, ref: str, on_file=None, on_skip=None, scenes=None,
                    highlights: bool = False) -> dict:
    """Compare the files of two folders matched by stem: ``{stem: scores}`` (``scenes``
    and ``highlights`` as :func:`compare_files` takes them).

    ``on_skip(stem, folder)`` is called first for each stem only one folder holds,
    ``on_file(i, n, stem)`` before each pair.
    """
    a, b = _stems(pred), _stems(ref)
    common = [s for s in a if s in b]
    if not common:
        raise InputError(f"{pred}, {ref}: no file stems in common (files must be .binary, .bsdf, .emb or .exr)")
    for stem in sorted(set(a) ^ set(b)):
        if on_skip is not None:
            on_skip(stem, pred if stem in a else ref)
    rows = {}
    for i, stem in enumerate(common, 1):
        if on_file is not None:
            on_file(i, len(common), stem)
        rows[stem] = compare_files(loader, a[stem], b[stem], scenes, highlights)
    return rows


def mean_scores(rows: list) -> dict:
    """Mean of each score over the rows that have it (``None`` where none has); rows
    scored in scenes also get the mean of each scene's scores under ``"scenes"``."""
    out = {}
    for key in KEYS:
        vals = [r[key] for r in rows if r.get(key) is not None]
        out[key] = float(sum(vals) / len(vals)) if vals else None
    names = [n for n in (rows[0].get("scenes") or {})] if rows else []
    if names:
        out["scenes"] = {n: mean_scores([r["scenes"][n] for r in rows]) for n in names}
        for m in out["scenes"].values():
            m.pop("brdf_log_rmse", None)
    return out
