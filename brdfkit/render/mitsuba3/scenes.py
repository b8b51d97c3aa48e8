"""Mitsuba 3 scenes with a brdfkit BRDF: the reference scene path-traced, a user's XML
scene with one BSDF replaced, and renders in passes (wavefront mode).
"""

from __future__ import annotations

import os

import numpy as np

from brdfkit.errors import InputError
from brdfkit.render.mitsuba3.bsdf import register_source
from brdfkit.render.mitsuba3.loader import load_mitsuba

__all__ = ["PASS_LANES", "reference_scene_dict", "render_scene", "render_reference", "load_user_scene"]

# Lanes per Mitsuba pass (pixels x samples): bounds memory in wavefront mode.
PASS_LANES = 1 << 20


def reference_scene_dict(bsdf: dict, scene=None, spp: int | None = None, env=None, mi=None) -> dict:
    """The reference scene (:mod:`brdfkit.render.scene`) as a Mitsuba scene dict.

    Path tracer with ``max_depth = 2`` (direct lighting; the sphere is convex), emitters
    hidden (black background), orthographic camera on ``+z``, box-filtered pixels,
    independent sampler, and the environment map (``env``, default the reference one; a
    suite scene's, :func:`brdfkit.render.scene_suite.scene_env`) written once to an EXR in
    the cache folder. ``mi``: the Mitsuba module with a variant already set (default:
    :func:`load_mitsuba`'s; ``brdfkit.testing.mitsuba_measured`` passes a scalar one).
    """
    from brdfkit.render.envmap import reference_envmap
    from brdfkit.render.scene import REFERENCE

    if mi is None:
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
        "emitter": {"type": "envmap", "filename": (env if env is not None else reference_envmap()).exr_path()},
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


def render_reference(brdf, scene=None, spp: int | None = None, seed: int = 0, progress=None, env=None):
    """Path-trace the reference scene (under ``env``, default the reference environment)
    with ``brdf`` on the sphere.

    Returns
    -------
    numpy.ndarray
        float32 ``(R, R, 3)`` linear RGB, ``spp`` (default ``scene.spp``) samples per pixel.
    """
    from brdfkit.render.scene import REFERENCE

    mi, _ = load_mitsuba()
    scene = scene or REFERENCE
    spp = int(spp or scene.spp)
    sc = mi.load_dict(reference_scene_dict({"type": "brdfkit", "source": register_source(brdf)},
                                           scene, spp, env))
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

    from brdfkit.atomic import check_input_file

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
    if model_path:  # the scene's other brdfkit BSDFs that name no model take this one
        for el in tree.getroot().iter("bsdf"):
            props = {child.get("name"): child.get("value", "") for child in el}
            if el.get("type") == "brdfkit" and "model" not in props and props.get("filename", "").endswith(".emb"):
                ET.SubElement(el, "string", {"name": "model", "value": os.path.abspath(os.fspath(model_path))})
    if resolution is not None:
        for film in tree.getroot().iter("film"):
            for child in film:
                if child.get("name") in ("width", "height"):
                    child.set("value", str(int(resolution)))
    text = ET.tostring(tree.getroot(), encoding="unicode")
    resolver = mi.file_resolver()
    resolver.prepend(os.path.dirname(os.path.abspath(path)))
    try:
        scene = mi.load_string(text)
    except Exception as e:
        raise InputError(f"{path}: Mitsuba cannot load this scene ({str(e).splitlines()[0] if str(e) else e})") from None
    if spp is None:
        spp = int(scene.sensors()[0].sampler().sample_count())
    return scene, spp
