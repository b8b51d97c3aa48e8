"""A Mitsuba 3 BSDF plugin ``brdfkit`` backed by a measured or neural BRDF.

Registered by name (``mi.register_bsdf("brdfkit", ...)``) by :func:`load_mitsuba`, so it
works from XML::

    <bsdf type="brdfkit" id="material">
        <string name="filename" value="teflon.binary"/>      <!-- or an .emb ... -->
        <string name="model" value="model.safetensors"/>     <!-- ... with its model -->
    </bsdf>

and from dict scenes (``{"type": "brdfkit", "filename": ...}``, or
``{"type": "brdfkit", "source": register_source(brdf)}`` for a BRDF object already in
memory: a :class:`~brdfkit.render.brdf.TableBRDF` or a :class:`~brdfkit.model.brdf.NeuralBRDF`).

Evaluation calls the BRDF's ``eval_dirs`` (trilinear table lookup, or the hyponet at the
queried directions) once per wavefront through ``dr.wrap(source="drjit", target="torch")``:
vectorised, no per-lane Python. Because a Python call cannot be traced into a symbolic
kernel, renders run with Dr.Jit's symbolic loops and calls switched off
(:func:`render_scene` does this), i.e. in wavefront mode.

Sampling is a fixed mixture, so that diffuse, glossy and near-mirror materials all
converge:

* with probability 0.25, a cosine-weighted hemisphere direction;
* with probability 0.5, the mirror of ``wi`` about a GGX visible normal of roughness
  ``alpha`` (Heitz 2018), ``alpha`` estimated from the BRDF itself (:func:`estimate_alpha`:
  the half-width of its specular peak at small ``theta_d``, clamped to ``[0.002, 0.6]``);
* with probability 0.25, the same with roughness ``min(0.8, 4 alpha)`` for the lobe's tails.

``pdf`` is the exact density of that mixture, ``sample`` returns ``f cos / pdf``.
The ``llvm_ad_rgb`` variant is used.

Mitsuba's LLVM backend needs a ``libLLVM`` that Dr.Jit accepts: LLVM 19 is seen to work,
Debian 12's 14 is refused and 15 aborts the process (``docs/render.md``).
:func:`ensure_libllvm` looks for LLVM 19 only (``BRDFKIT_LIBLLVM_SEARCH``, glob patterns
separated by ``os.pathsep``, replaces the search), sets ``DRJIT_LIBLLVM_PATH`` when unset,
refuses one naming LLVM 15 or older, and otherwise asks for ``apt-get install -y
libllvm19``. Mitsuba is imported only in this module.
"""

from __future__ import annotations

import glob
import itertools
import math
import os
import threading

import numpy as np

from ..errors import BrdfkitError, InputError

__all__ = ["LIBLLVM_CANDIDATES", "ensure_libllvm", "libllvm_version", "load_mitsuba", "register_source",
           "estimate_alpha", "reference_scene_dict", "render_scene", "render_reference",
           "load_user_scene"]

VARIANT = "llvm_ad_rgb"
LIBLLVM_CANDIDATES = tuple(f"/usr/lib/{d}/{n}" for d in ("x86_64-linux-gnu", "llvm-19/lib", "aarch64-linux-gnu")
                           for n in ("libLLVM.so.19.1", "libLLVM-19.so"))
LIBLLVM_PATTERNS = ("/usr/lib/*/libLLVM.so.19*", "/usr/lib/*/libLLVM-19.so*",
                    "/usr/lib/llvm-19/lib/libLLVM*.so*")
# Seen on Debian 12: 14 is refused by Dr.Jit, 15 aborts the process (exit 134).
BROKEN_LLVM_BELOW = 16
_INSTALL_HINT = ("Mitsuba's LLVM backend needs libLLVM 19 (the version seen to work; "
                 "Debian 12's LLVM 14 and 15 crash): install it with "
                 "`apt-get install -y libllvm19`, or set DRJIT_LIBLLVM_PATH to a libLLVM 19 .so")
# Mixture weights: cosine, GGX(alpha), GGX(4 alpha).
LOBE_WEIGHTS = (0.25, 0.5, 0.25)
# Lanes per Mitsuba pass (pixels x samples): bounds memory in wavefront mode.
PASS_LANES = 1 << 20

_lock = threading.Lock()
_state: dict = {}  # the imported modules and the BSDF class, made once
_sources: dict = {}
# The model of ``.emb`` BSDFs that name none, while :func:`load_user_scene` loads a scene
# (the command line's ``-m``); the plugin reads no environment variable of its own.
_fallback_model: str | None = None
_counter = itertools.count()


def ensure_libllvm() -> str:
    """Make sure Dr.Jit will find a usable ``libLLVM`` before Mitsuba is imported.

    Returns
    -------
    str
        The library path in ``DRJIT_LIBLLVM_PATH`` (set here to the first of
        :data:`LIBLLVM_CANDIDATES` that exists, when unset).

    Raises
    ------
    BrdfkitError
        No usable library: the message says to ``apt-get install -y libllvm19``.
    """
    path = os.environ.get("DRJIT_LIBLLVM_PATH")
    if path:
        if not os.path.isfile(path):
            raise BrdfkitError(f"DRJIT_LIBLLVM_PATH={path}: no such file. {_INSTALL_HINT}")
        version = libllvm_version(path)
        if version is not None and version < BROKEN_LLVM_BELOW:
            raise BrdfkitError(f"DRJIT_LIBLLVM_PATH={path}: LLVM {version} crashes Mitsuba's "
                               f"LLVM backend. {_INSTALL_HINT}")
        return path
    search = os.environ.get("BRDFKIT_LIBLLVM_SEARCH")
    if search is not None:
        candidates, patterns = (), tuple(p for p in search.split(os.pathsep) if p)
    else:
        candidates, patterns = LIBLLVM_CANDIDATES, LIBLLVM_PATTERNS
    found = [c for c in candidates if os.path.isfile(c)]
    found += sorted(f for p in patterns for f in glob.glob(p) if os.path.isfile(f))
    if not found:
        raise BrdfkitError(f"no usable libLLVM found. {_INSTALL_HINT}")
    os.environ["DRJIT_LIBLLVM_PATH"] = found[0]
    return found[0]


def libllvm_version(path: str) -> int | None:
    """The LLVM major version in a library's file name (``libLLVM-15.so.1``,
    ``libLLVM.so.19.1``, ``/usr/lib/llvm-14/lib/libLLVM.so``), or ``None``."""
    import re

    name = os.path.basename(path)
    m = re.match(r"libLLVM-(\d+)", name) or re.match(r"libLLVM\.so\.(\d+)", name)
    if m is None:
        m = re.search(r"llvm-(\d+)", path)
    return int(m.group(1)) if m else None


def load_mitsuba():
    """Import Mitsuba with the ``llvm_ad_rgb`` variant and register the ``brdfkit`` BSDF.

    Returns
    -------
    tuple
        ``(mitsuba, drjit)`` modules.
    """
    with _lock:
        if "mi" in _state:
            return _state["mi"], _state["dr"]
        ensure_libllvm()
        try:
            import drjit as dr
            import mitsuba as mi

            mi.set_variant(VARIANT)
        except ImportError as e:
            if "LLVM" in str(e):  # Dr.Jit refused the library (LLVM 14), Mitsuba is there
                raise BrdfkitError(f"Mitsuba's LLVM backend refused {os.environ.get('DRJIT_LIBLLVM_PATH')}. "
                                   f"{_INSTALL_HINT}") from None
            raise BrdfkitError(f"cannot import Mitsuba 3 ({e}); install it with `pip install mitsuba`") from None
        except Exception as e:  # variant not compiled, LLVM refused
            raise BrdfkitError(f"Mitsuba variant {VARIANT} unavailable ({e}). {_INSTALL_HINT}") from None
        mi.register_bsdf("brdfkit", lambda props: _bsdf_class(mi, dr)(props))
        _state["mi"], _state["dr"] = mi, dr
        return mi, dr


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
    import torch

    from ..geometry import io_from_half_diff

    th = np.geomspace(1e-4, 1.2, 200)
    wi, wo = io_from_half_diff(th, np.full_like(th, 0.05), np.full_like(th, math.pi / 2))
    with torch.no_grad():
        f = brdf.eval_dirs(torch.as_tensor(wi, dtype=torch.float32),
                           torch.as_tensor(wo, dtype=torch.float32)).double().cpu().numpy()
    lum = f @ np.array([0.2126, 0.7152, 0.0722])
    peak, floor = float(lum[0]), float(lum[-1])
    if not np.isfinite(lum).all() or peak < 2 * max(floor, 1e-12):
        return 0.5
    below = np.flatnonzero(lum - floor < 0.5 * (peak - floor))
    if below.size == 0:
        return 0.6
    return float(np.clip(th[below[0]] / 0.64, 0.002, 0.6))


def _open_source(props) -> object:
    if "source" in props:
        key = props["source"]
        if key not in _sources:
            raise InputError(f"brdfkit BSDF: unknown source {key!r} (use register_source)")
        return _sources[key]
    if "filename" not in props:
        raise InputError("brdfkit BSDF: give a 'filename' (.binary or .emb) or a registered 'source'")
    from .brdf import load_brdf

    model = props["model"] if "model" in props else _fallback_model
    filename = str(props["filename"])
    try:  # resolve relative to the scene file, as Mitsuba does for its own files
        import mitsuba as mi

        filename = str(mi.file_resolver().resolve(filename))
        if model:
            model = str(mi.file_resolver().resolve(str(model)))
    except Exception:
        pass
    return load_brdf(filename, model_path=model, device="cpu")


def _bsdf_class(mi, dr):
    if "cls" in _state:
        return _state["cls"]

    class BrdfkitBSDF(mi.BSDF):
        """Mitsuba BSDF evaluating a brdfkit BRDF (see the module docstring)."""

        def __init__(self, props):
            mi.BSDF.__init__(self, props)
            self.brdf = _open_source(props)
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

                with torch.no_grad():
                    # Dr.Jit's Array3f arrives as (3, N); the BRDF wants (N, 3).
                    out = brdf.eval_dirs(a.T.contiguous().float(), b.T.contiguous().float())
                    out = torch.nan_to_num(out.float(), nan=0.0, posinf=0.0, neginf=0.0).clamp_min(0.0)
                return out.T.contiguous()

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

    _state["cls"] = BrdfkitBSDF
    return BrdfkitBSDF


def reference_scene_dict(bsdf: dict, scene=None, spp: int | None = None) -> dict:
    """The reference scene (:mod:`brdfkit.render.scene`) as a Mitsuba scene dict.

    Path tracer with ``max_depth = 2`` (direct lighting; the sphere is convex), emitters
    hidden (black background), orthographic camera on ``+z``, box-filtered pixels,
    independent sampler, and the reference environment map written once to an EXR in
    the cache folder.
    """
    from .envmap import reference_envmap
    from .scene import REFERENCE

    mi, _ = load_mitsuba()
    scene = scene or REFERENCE
    h = scene.view_half_width
    to_world = mi.ScalarTransform4f().look_at(origin=[0, 0, 10], target=[0, 0, 0], up=[0, 1, 0]) \
        @ mi.ScalarTransform4f().scale([h, h, 1.0])
    return {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": 2, "hide_emitters": True},
        "sensor": {
            "type": "orthographic", "to_world": to_world,
            "film": {"type": "hdrfilm", "width": scene.resolution, "height": scene.resolution,
                     "rfilter": {"type": "box"}, "pixel_format": "rgb"},
            "sampler": {"type": "independent", "sample_count": int(spp or scene.spp)},
        },
        "emitter": {"type": "envmap", "filename": reference_envmap().exr_path()},
        "sphere": {"type": "sphere", "center": [0, 0, 0], "radius": 1.0, "bsdf": bsdf},
    }


def render_scene(scene, spp: int, seed: int = 0, progress=None) -> np.ndarray:
    """Render a loaded Mitsuba scene in passes (wavefront mode), averaging them.

    Parameters
    ----------
    scene
        A ``mi.Scene``.
    spp
        Samples per pixel in all.
    seed
        Seed of the first pass (pass ``i`` uses ``seed + i``).
    progress
        Optional callable ``progress(done_spp, spp)``.

    Returns
    -------
    numpy.ndarray
        float32 ``(H, W, 3)`` linear RGB.
    """
    mi, dr = load_mitsuba()
    if spp < 1:
        raise InputError(f"--spp {spp}: need at least 1 sample per pixel")
    w, h = scene.sensors()[0].film().crop_size()
    per_pass = int(max(1, min(spp, PASS_LANES // max(1, w * h))))
    acc, done, i = None, 0, 0
    old = (dr.flag(dr.JitFlag.SymbolicLoops), dr.flag(dr.JitFlag.SymbolicCalls))
    dr.set_flag(dr.JitFlag.SymbolicLoops, False)
    dr.set_flag(dr.JitFlag.SymbolicCalls, False)
    try:
        while done < spp:
            n = min(per_pass, spp - done)
            img = np.array(mi.render(scene, spp=n, seed=seed + i), dtype=np.float64)[..., :3]
            acc = img * n if acc is None else acc + img * n
            done += n
            i += 1
            if progress is not None:
                progress(done, spp)
    finally:
        dr.set_flag(dr.JitFlag.SymbolicLoops, old[0])
        dr.set_flag(dr.JitFlag.SymbolicCalls, old[1])
    return (acc / spp).astype(np.float32)


def render_reference(brdf, scene=None, spp: int | None = None, seed: int = 0, progress=None):
    """Path-trace the reference scene with ``brdf`` on the sphere.

    Returns
    -------
    numpy.ndarray
        float32 ``(R, R, 3)`` linear RGB, ``spp`` (default ``scene.spp``) samples per pixel.
    """
    from .scene import REFERENCE

    mi, _ = load_mitsuba()
    scene = scene or REFERENCE
    spp = int(spp or scene.spp)
    sc = mi.load_dict(reference_scene_dict({"type": "brdfkit", "source": register_source(brdf)},
                                           scene, spp))
    return render_scene(sc, spp, seed, progress)


def load_user_scene(path, bsdf_id: str, brdf, resolution: int | None = None, spp: int | None = None,
                    model_path: str | None = None):
    """Load a Mitsuba XML scene with the BSDF of id ``bsdf_id`` replaced by ``brdf``.

    The ``<bsdf ... id="bsdf_id">`` element is rewritten to
    ``<bsdf type="brdfkit" id="bsdf_id">`` with the BRDF as its source (its children
    dropped); relative paths in the file resolve against its folder. Other ``brdfkit``
    BSDFs of the file that load an ``.emb`` without a ``model`` use ``model_path``.

    Raises
    ------
    InputError
        Not XML, no BSDF with that id, or Mitsuba cannot load the result.
    """
    import xml.etree.ElementTree as ET

    from ..atomic import check_input_file

    mi, _ = load_mitsuba()
    path = check_input_file(path)
    try:
        tree = ET.parse(path)
    except ET.ParseError as e:
        raise InputError(f"{path}: not a Mitsuba XML scene ({e})") from None
    hits = [el for el in tree.getroot().iter("bsdf") if el.get("id") == bsdf_id]
    if not hits:
        ids = sorted({el.get("id") for el in tree.getroot().iter("bsdf") if el.get("id")})
        raise InputError(f"{path}: no <bsdf id=\"{bsdf_id}\"> (BSDF ids in the file: {', '.join(ids) or 'none'})")
    key = register_source(brdf)
    for el in hits:
        for child in list(el):
            el.remove(child)
        el.attrib = {"type": "brdfkit", "id": bsdf_id}
        ET.SubElement(el, "string", {"name": "source", "value": key})
    if resolution is not None:
        for film in tree.getroot().iter("film"):
            for child in film:
                if child.get("name") in ("width", "height"):
                    child.set("value", str(int(resolution)))
    text = ET.tostring(tree.getroot(), encoding="unicode")
    resolver = mi.file_resolver()
    resolver.prepend(os.path.dirname(os.path.abspath(path)))
    global _fallback_model
    _fallback_model = os.fspath(model_path) if model_path else None
    try:
        scene = mi.load_string(text)
    except Exception as e:
        raise InputError(f"{path}: Mitsuba cannot load this scene ({str(e).splitlines()[0] if str(e) else e})") from None
    finally:
        _fallback_model = None
    if spp is None:
        spp = int(scene.sensors()[0].sampler().sample_count())
    return scene, spp
