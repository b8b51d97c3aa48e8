"""The inputs of a page, read: BRDF files as tables (or, live, as embeddings the shader
decodes) and sample files as points.

=================== ===============================================================
input               on the page
=================== ===============================================================
MERL ``.binary``    its table
RGL ``.bsdf``       its table at the MERL grid's directions, made reciprocal
                    (:func:`brdfkit.io.rgl_bsdf.read_bsdf_table`; ``brdfkit render``
                    instead evaluates the file conditioned on the view)
``.emb``            decoded to its table by its decoder (``-m``, or the installed
                    built-in part it names); with ``live``, a basis or residual
                    embedding (of at most 30 components a channel) is its ``3 K``
                    numbers and the shader decodes it
sample file         its samples, as points (``.csv``, ``.brdf``:
                    :func:`brdfkit.io.sample_files.read_sample_file`)
=================== ===============================================================
"""

from __future__ import annotations

import dataclasses
import os

import numpy as np

from brdfkit.errors import InputError

__all__ = ["PageInput", "read_inputs", "sample_rows"]


@dataclasses.dataclass
class PageInput:
    """One input of a page.

    Attributes
    ----------
    label
        Its name on the page (the file stem, unique).
    path
        The file.
    kind
        ``"table"``, ``"live"`` or ``"samples"``.
    table
        ``(90, 90, 180, 3)`` 1/sr, NaN where unmeasured (``table``).
    live
        :func:`brdfkit.view.live.live_material` (``live``).
    samples
        :class:`brdfkit.io.samples.SampleSet` (``samples``).
    """

    label: str
    path: str
    kind: str
    table: np.ndarray | None = None
    live: dict | None = None
    samples: object = None


def _labels(paths):
    from brdfkit.figures.brdf_plot import input_labels

    return input_labels(paths)


def _classify(path: str) -> str:
    from brdfkit.files.brdf_file import FILE_TYPES, file_type
    from brdfkit.io.sample_files import SAMPLE_SUFFIXES, is_sample_file

    if is_sample_file(path):
        return "samples"
    if os.path.splitext(path)[1].lower() in FILE_TYPES:
        return file_type(path)
    raise InputError(f"{path}: brdfkit view takes BRDF files ({', '.join(FILE_TYPES)}) and sample files "
                     f"({', '.join(SAMPLE_SUFFIXES)})")


def read_inputs(paths, model_path=None, live: bool = False, progress=None) -> list[PageInput]:
    """Read the inputs of a page, in order (every name checked before anything is read).

    Parameters
    ----------
    paths
        BRDF and sample files.
    model_path
        The decoder of ``.emb`` inputs (a built-in's name or a file; default: the built-in
        part each names).
    live
        Basis and residual embeddings stay embeddings (their shader decodes them); other
        kinds are decoded to tables all the same.
    progress
        Optional ``progress(message)``.
    """
    from brdfkit.atomic import check_input_file
    from brdfkit.files.brdf_file import EmbeddingDecoders, read_table
    from brdfkit.view.live import LIVE_KINDS, MAX_COMPONENTS, live_material

    paths = [os.fspath(p) for p in paths]
    if not paths:
        raise InputError("view: no input (give MERL .binary, RGL .bsdf, .emb or sample files)")
    kinds = [_classify(p) for p in paths]
    for p in paths:
        check_input_file(p)
    models = EmbeddingDecoders(model_path)
    out = []
    for label, path, kind in zip(_labels(paths), paths, kinds):
        if progress is not None:
            progress(f"reading {path}")
        if kind == "samples":
            from brdfkit.io.sample_files import read_sample_file

            out.append(PageInput(label, path, "samples", samples=read_sample_file(path)))
            continue
        if kind == "embedding" and live:
            from brdfkit.io.embedding import read_embedding

            emb = read_embedding(path)
            decoder = models.decoder(emb, path)
            if decoder.kind in LIVE_KINDS and emb.size // 3 <= MAX_COMPONENTS:
                out.append(PageInput(label, path, "live", live=live_material(emb, decoder, path)))
                continue
        out.append(PageInput(label, path, "table", table=read_table(path, models)))
    if not any(i.kind != "samples" for i in out):
        raise InputError("view: no BRDF among the inputs (sample files are shown beside a BRDF)")
    return out


def sample_rows(samples) -> np.ndarray:
    """float32 ``(N, 6)`` of a sample set, what the page draws: ``theta_h``, ``theta_d``
    (degrees), the luminance (1/sr; NaN unmeasured), and the pair's ``theta_i``, signed
    ``theta_o`` (negative: on the light's side) and its angle off the plane of incidence
    (degrees: ``wo``'s angle to the plane of ``wi`` and the normal), for the lobe plot's
    points."""
    from brdfkit.geometry import io_from_half_diff

    th, td, pd = (np.asarray(a, np.float64) for a in (samples.theta_h, samples.theta_d, samples.phi_d))
    wi, wo = io_from_half_diff(th, td, pd)
    lum = np.asarray(samples.rgb, np.float64) @ np.array([0.2126, 0.7152, 0.0722])
    ti = np.degrees(np.arccos(np.clip(wi[:, 2], -1, 1)))
    to = np.degrees(np.arccos(np.clip(wo[:, 2], -1, 1)))
    # In the plane of incidence wo's azimuth is wi's plus pi (past the normal, theta_o > 0)
    # or wi's own (back towards the light, theta_o < 0); off it by the azimuths' gap.
    gap = np.angle(np.exp(1j * (np.arctan2(wo[:, 1], wo[:, 0]) - np.arctan2(wi[:, 1], wi[:, 0]))))
    back = np.abs(gap) < np.pi / 2
    off = np.where(back, np.abs(gap), np.pi - np.abs(gap))
    off = np.degrees(np.arcsin(np.clip(np.sin(np.radians(to)) * np.sin(off), 0.0, 1.0)))  # wo's angle to the plane
    return np.column_stack([np.degrees(th), np.degrees(td), lum, ti, np.where(back, -to, to), off]).astype(np.float32)
