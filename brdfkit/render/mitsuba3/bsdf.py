"""The ``brdfkit`` BSDF of Mitsuba 3: a measured or neural BRDF inside a Mitsuba scene.

Registered by name by :func:`brdfkit.render.mitsuba3.loader.load_mitsuba`, so it works
from XML::

    <bsdf type="brdfkit" id="material">
        <string name="filename" value="teflon.binary"/>      <!-- or an .emb ... -->
        <string name="model" value="model.safetensors"/>     <!-- ... with its model -->
    </bsdf>

and from dict scenes (``{"type": "brdfkit", "filename": ...}``, or
``{"type": "brdfkit", "source": register_source(brdf)}`` for a BRDF object already in
memory: a :class:`~brdfkit.render.renderable.TableBRDF` or a
:class:`~brdfkit.hypernet.neural_brdf.NeuralBRDF`).

Evaluation calls the BRDF's ``eval_dirs`` (trilinear table lookup, or the hyponet at the
queried directions; NumPy arrays in and out) once per wavefront through
``dr.wrap(source="drjit", target="torch")``: vectorised, no per-lane Python. Because a Python call cannot be traced into a symbolic
kernel, renders run with Dr.Jit's symbolic loops and calls switched off
(:func:`brdfkit.render.mitsuba3.scenes.render_scene` does this), i.e. in wavefront mode.

Sampling is a fixed mixture, so that diffuse, glossy and near-mirror materials all
converge:

* with probability 0.25, a cosine-weighted hemisphere direction;
* with probability 0.5, the mirror of ``wi`` about a GGX visible normal of roughness
  ``alpha`` (Heitz 2018), ``alpha`` estimated from the BRDF itself (:func:`estimate_alpha`:
  the half-width of its specular peak at small ``theta_d``, clamped to ``[0.002, 0.6]``);
* with probability 0.25, the same with roughness ``min(0.8, 4 alpha)`` for the lobe's tails.

``pdf`` is the exact density of that mixture, ``sample`` returns ``f cos / pdf``.
"""

from __future__ import annotations

import itertools
import math

import numpy as np

from brdfkit.errors import InputError

__all__ = ["LOBE_WEIGHTS", "register_source", "set_file_opener", "estimate_alpha", "open_source", "bsdf_class"]

# Mixture weights: cosine, GGX(alpha), GGX(4 alpha).
LOBE_WEIGHTS = (0.25, 0.5, 0.25)

_sources: dict = {}
_counter = itertools.count()
_classes: dict = {}  # the BSDF class, made once per process
# What opens a BRDF file a scene names: set from above (brdfkit.files.brdf_file registers
# its loader), since opening an embedding needs the layers above rendering.
_opener: list = []


def set_file_opener(opener) -> None:
    """Register ``opener(path, model_path=None, device=None) -> BRDF``, what a BSDF's
    ``filename`` is opened with (:func:`brdfkit.files.brdf_file.load_brdf` registers
    itself when imported)."""
    _opener[:] = [opener]


def register_source(brdf) -> str:
    """Make an in-memory BRDF (with ``eval_dirs``) usable as ``{"type": "brdfkit",
    "source": key}``; returns the key. Sources live for the process."""
    key = f"brdf-{next(_counter)}"
    _sources[key] = brdf
    return key


def estimate_alpha(brdf) -> float:
    """A GGX roughness matching the width of the BRDF's specular peak.

    The luminance of ``f`` along ``theta_h`` (``theta_d = 0.05``, ``phi_d = pi/2``, so
    ``wi`` and ``wo`` stay above the horizon) from ``1e-4`` to ``1.2`` rad: ``alpha`` is
    the ``theta_h`` where the peak has fallen to half its height above the value at
    1.2 rad, divided by 0.64 (GGX falls to half at ``theta_h = 0.64 alpha``); 0.5 when
    there is no peak (less than a factor of two).

    Returns
    -------
    float
        In ``[0.002, 0.6]``.
    """
    from brdfkit.geometry import io_from_half_diff

    th = np.geomspace(1e-4, 1.2, 200)
    wi, wo = io_from_half_diff(th, np.full_like(th, 0.05), np.full_like(th, math.pi / 2))
    f = np.asarray(brdf.eval_dirs(wi.astype(np.float32), wo.astype(np.float32)), np.float64)
    lum = f @ np.array([0.2126, 0.7152, 0.0722])
    peak, floor = float(lum[0]), float(lum[-1])
    if not np.isfinite(lum).all() or peak < 2 * max(floor, 1e-12):
        return 0.5
    below = np.flatnonzero(lum - floor < 0.5 * (peak - floor))
    if below.size == 0:
        return 0.6
    return float(np.clip(th[below[0]] / 0.64, 0.002, 0.6))


def open_source(props) -> object:
    """The BRDF a BSDF's properties name: a registered ``source``, or a ``filename``
    (``.binary`` or ``.emb`` with its ``model``) resolved as Mitsuba resolves its files."""
    if "source" in props:
        key = props["source"]
        if key not in _sources:
            raise InputError(f"brdfkit BSDF: unknown source {key!r} (use register_source)")
        return _sources[key]
    if "filename" not in props:
        raise InputError("brdfkit BSDF: give a 'filename' (.binary or .emb) or a registered 'source'")
    if not _opener:
        raise InputError("brdfkit BSDF: a 'filename' needs brdfkit's file loader: import brdfkit.files first "
                         "(the brdfkit command line does)")
    model = props["model"] if "model" in props else None
    filename = str(props["filename"])
    try:  # resolve relative to the scene file, as Mitsuba does for its own files
        import mitsuba as mi

        filename = str(mi.file_resolver().resolve(filename))
        if model:
            model = str(mi.file_resolver().resolve(str(model)))
    except Exception:
        pass
    return _opener[0](filename, model_path=model, device="cpu")


def bsdf_class(mi, dr):
    """The ``brdfkit`` BSDF class of this Mitsuba (made on first call)."""
    if "cls" in _classes:
        return _classes["cls"]

    class BrdfkitBSDF(mi.BSDF):
        """Mitsuba BSDF evaluating a brdfkit BRDF (see the module docstring)."""

        def __init__(self, props):
            mi.BSDF.__init__(self, props)
            self.brdf = open_source(props)
            alpha = float(props["alpha"]) if "alpha" in props else estimate_alpha(self.brdf)
            self.alpha = alpha
            self.ggx = (mi.MicrofacetDistribution(mi.MicrofacetType.GGX, alpha, True),
                        mi.MicrofacetDistribution(mi.MicrofacetType.GGX, min(0.8, 4 * alpha), True))
            flags = mi.BSDFFlags.GlossyReflection | mi.BSDFFlags.DiffuseReflection | mi.BSDFFlags.FrontSide
            self.m_components = [flags]
            self.m_flags = flags

        def _f(self, wi, wo):
            brdf = self.brdf

            @dr.wrap(source="drjit", target="torch")
            def call(a, b):
                import torch

                # Dr.Jit's Array3f arrives as (3, N); a BRDF takes NumPy (N, 3).
                with torch.no_grad():
                    wi_, wo_ = (x.detach().float().cpu().numpy().T for x in (a, b))
                out = np.asarray(brdf.eval_dirs(wi_, wo_), np.float32)
                out = np.clip(np.nan_to_num(out, nan=0.0, posinf=0.0, neginf=0.0), 0.0, None)
                return torch.from_numpy(np.ascontiguousarray(out.T)).to(a.device)

            return mi.Color3f(call(wi, wo))

        def _valid(self, si, wo):
            return (mi.Frame3f.cos_theta(si.wi) > 0) & (mi.Frame3f.cos_theta(wo) > 0)

        def _pdf(self, si, wo):
            cos_o = mi.Frame3f.cos_theta(wo)
            m = dr.normalize(si.wi + wo)
            dwo = dr.maximum(dr.dot(wo, m), 1e-12)
            pdf = LOBE_WEIGHTS[0] * mi.warp.square_to_cosine_hemisphere_pdf(wo)
            for w, distr in zip(LOBE_WEIGHTS[1:], self.ggx):
                pdf += w * distr.pdf(si.wi, m) / (4 * dwo)
            return dr.select(self._valid(si, wo) & (cos_o > 0), pdf, 0.0)

        def eval(self, ctx, si, wo, active=True):
            # Mitsuba's si.wi is the view direction and wo the light direction; the BRDF
            # is reciprocal, and eval includes the light's cosine.
            value = self._f(mi.Vector3f(wo), mi.Vector3f(si.wi)) * mi.Frame3f.cos_theta(wo)
            return dr.select(self._valid(si, wo) & active, value, 0.0)

        def pdf(self, ctx, si, wo, active=True):
            return dr.select(active, self._pdf(si, wo), 0.0)

        def eval_pdf(self, ctx, si, wo, active=True):
            return self.eval(ctx, si, wo, active), self.pdf(ctx, si, wo, active)

        def sample(self, ctx, si, sample1, sample2, active=True):
            wo_cos = mi.warp.square_to_cosine_hemisphere(sample2)
            m1, _ = self.ggx[0].sample(si.wi, sample2)
            m2, _ = self.ggx[1].sample(si.wi, sample2)
            c0, c1 = LOBE_WEIGHTS[0], LOBE_WEIGHTS[0] + LOBE_WEIGHTS[1]
            wo = dr.select(sample1 < c0, wo_cos,
                           dr.select(sample1 < c1, mi.reflect(si.wi, m1), mi.reflect(si.wi, m2)))
            bs = dr.zeros(mi.BSDFSample3f)
            bs.wo = wo
            bs.pdf = self._pdf(si, wo)
            bs.eta = 1.0
            bs.sampled_type = mi.UInt32(+mi.BSDFFlags.GlossyReflection)
            bs.sampled_component = mi.UInt32(0)
            ok = active & (bs.pdf > 0)
            value = self.eval(ctx, si, wo, ok) / dr.maximum(bs.pdf, 1e-20)
            return bs, dr.select(ok, value, 0.0)

        def traverse(self, callback):
            pass

        def to_string(self):
            return f"BrdfkitBSDF[alpha={self.alpha:.4g}]"

    _classes["cls"] = BrdfkitBSDF
    return BrdfkitBSDF
