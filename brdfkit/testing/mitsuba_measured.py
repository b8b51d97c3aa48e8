"""Mitsuba 3's own ``measured`` BSDF on a ``.bsdf`` file: the judge of the files brdfkit
writes (``tests/test_rgl_bsdf.py``, ``benchmarks/studies/rgl_roundtrip.py``).

Mitsuba runs in a child process with a scalar variant (``scalar_rgb``, or
``scalar_spectral`` for spectral files), which needs no libLLVM, so that it neither
needs nor disturbs the ``llvm_ad_rgb`` variant the rest of brdfkit (and of a test run)
imports in-process. Arrays go to and from the child as ``.npy`` files in a temporary
folder; nothing is unpickled.

* :func:`measured_eval`: ``bsdf.eval`` (``f cos(theta_o)``) at direction pairs;
* :func:`measured_sampling`: ``bsdf.sample`` (the directions it draws) and ``bsdf.pdf``
  (the density it says they follow);
* :func:`measured_render`: the reference scene (:mod:`brdfkit.render.scene`, the same
  dict as :func:`brdfkit.render.mitsuba3.scenes.reference_scene_dict`) path-traced with
  the file on the sphere, or lit by light sampling alone (:data:`INTEGRATORS`).

Run as ``python -m brdfkit.testing.mitsuba_measured JOB FOLDER`` by these functions.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile

import numpy as np

__all__ = ["measured_eval", "measured_render", "measured_sampling", "mitsuba_available", "INTEGRATORS"]


def mitsuba_available() -> bool:
    """Whether the ``mitsuba`` package is importable (without importing it)."""
    import importlib.util

    return importlib.util.find_spec("mitsuba") is not None


def _run(job: str, args: dict, arrays: dict, timeout: float) -> dict:
    with tempfile.TemporaryDirectory(prefix="brdfkit-mitsuba-") as folder:
        for name, a in arrays.items():
            np.save(os.path.join(folder, name + ".npy"), np.asarray(a), allow_pickle=False)
        with open(os.path.join(folder, "args.json"), "w") as f:
            json.dump(args, f)
        env = dict(os.environ, OMP_NUM_THREADS=os.environ.get("OMP_NUM_THREADS", "1"))
        done = subprocess.run([sys.executable, "-m", "brdfkit.testing.mitsuba_measured", job, folder],
                              capture_output=True, text=True, timeout=timeout, env=env)
        if done.returncode != 0:
            raise RuntimeError(f"Mitsuba {job} failed (exit {done.returncode}): {done.stderr.strip()[-2000:]}")
        return {n[:-4]: np.load(os.path.join(folder, n), allow_pickle=False)
                for n in os.listdir(folder) if n.startswith("out_") and n.endswith(".npy")}


def measured_eval(path, wi, wo, *, wavelengths=None, timeout: float = 600.0) -> np.ndarray:
    """Mitsuba's ``measured`` BSDF of ``path`` at direction pairs.

    Parameters
    ----------
    path
        A ``.bsdf`` file, or a list of them (evaluated at the same pairs, in one child).
    wi, wo
        Unit directions ``(M, 3)``, local frame; ``wi`` is Mitsuba's ``si.wi``.
    wavelengths
        For a spectral file: the four wavelengths (nm) each pair is evaluated at, ``(M, 4)``
        (variant ``scalar_spectral``); ``None``: an RGB file (``scalar_rgb``).
    timeout
        Seconds before the child is stopped.

    Returns
    -------
    numpy.ndarray
        float64 ``(M, 3)`` (RGB) or ``(M, 4)`` (spectral): ``f cos(theta_o)``; with a list
        of files, ``(F, M, C)``.
    """
    arrays = {"wi": np.asarray(wi, np.float64), "wo": np.asarray(wo, np.float64)}
    if wavelengths is not None:
        arrays["wavelengths"] = np.asarray(wavelengths, np.float64)
    many = isinstance(path, (list, tuple))
    paths = [os.path.abspath(os.fspath(p)) for p in (path if many else [path])]
    out = _run("eval", {"paths": paths}, arrays, timeout)
    values = np.stack([out[f"out_values_{i}"] for i in range(len(paths))])
    return values if many else values[0]


INTEGRATORS = {"path": None, "emitter": {"type": "direct", "emitter_samples": 1, "bsdf_samples": 0,
                                         "hide_emitters": True}}
"""The integrators of :func:`measured_render`: ``path``, the reference scene's own (a path
tracer of depth 2: light and BSDF sampling, combined by multiple importance sampling), and
``emitter``, Mitsuba's ``direct`` integrator with light sampling alone (one environment
sample a pixel sample, no BSDF sampling: the BSDF is only evaluated, never sampled)."""


def measured_render(path, resolution: int = 64, spp: int = 256, seed: int = 0, timeout: float = 600.0,
                    integrator: str = "path") -> np.ndarray:
    """The reference scene path-traced by Mitsuba (``scalar_rgb``) with the ``measured``
    BSDF of ``path`` on the sphere: float32 ``(R, R, 3)`` linear RGB; ``integrator`` one
    of :data:`INTEGRATORS`."""
    if integrator not in INTEGRATORS:
        raise ValueError(f"integrator {integrator!r}: expected one of {', '.join(INTEGRATORS)}")
    args = {"path": os.path.abspath(os.fspath(path)), "resolution": int(resolution), "spp": int(spp),
            "seed": int(seed), "integrator": INTEGRATORS[integrator]}
    return _run("render", args, {}, timeout)["out_image"]


def _child_eval(mi, folder, args):
    wi = np.load(os.path.join(folder, "wi.npy"))
    wo = np.load(os.path.join(folder, "wo.npy"))
    lam_path = os.path.join(folder, "wavelengths.npy")
    lam = np.load(lam_path) if os.path.exists(lam_path) else None
    mi.set_variant("scalar_spectral" if lam is not None else "scalar_rgb")
    ctx = mi.BSDFContext()
    si = mi.SurfaceInteraction3f()
    si.sh_frame = mi.Frame3f(mi.Vector3f(0.0, 0.0, 1.0))
    for i, path in enumerate(args["paths"]):
        bsdf = mi.load_dict({"type": "measured", "filename": path})
        out = np.zeros((wi.shape[0], 4 if lam is not None else 3))
        for k in range(wi.shape[0]):
            si.wi = mi.Vector3f(*wi[k])
            if lam is not None:
                si.wavelengths = mi.Spectrum(*lam[k])
            v = bsdf.eval(ctx, si, mi.Vector3f(*wo[k]))
            out[k] = [v[c] for c in range(out.shape[1])]
        np.save(os.path.join(folder, f"out_values_{i}.npy"), out, allow_pickle=False)


def measured_sampling(path, wi, u, wo, timeout: float = 600.0) -> dict:
    """Mitsuba's ``measured`` BSDF of ``path`` (``scalar_rgb``) sampling and its density:
    ``bsdf.sample`` at views ``wi`` ``(M, 3)`` with random numbers ``u`` ``(M, 3)``, and
    ``bsdf.pdf`` at the pairs ``(wi, wo)`` of the caller's ``wo`` ``(M, 3)`` (the same ``wi``).

    Returns
    -------
    dict
        ``{"sampled" (M, 3): the sampled directions (zeros where the sample failed),
        "weight" (M, 3), "sampled_pdf" (M,), "pdf" (M,): the density at the given wo}``.
    """
    arrays = {"wi": np.asarray(wi, np.float64), "u": np.asarray(u, np.float64), "wo": np.asarray(wo, np.float64)}
    out = _run("sample", {"path": os.path.abspath(os.fspath(path))}, arrays, timeout)
    return {k[4:]: v for k, v in out.items()}


def _child_sample(mi, folder, args):
    wi, u, wo = (np.load(os.path.join(folder, f"{n}.npy")) for n in ("wi", "u", "wo"))
    mi.set_variant("scalar_rgb")
    ctx = mi.BSDFContext()
    si = mi.SurfaceInteraction3f()
    si.sh_frame = mi.Frame3f(mi.Vector3f(0.0, 0.0, 1.0))
    bsdf = mi.load_dict({"type": "measured", "filename": args["path"]})
    m = wi.shape[0]
    sampled, weight, spdf, pdf = np.zeros((m, 3)), np.zeros((m, 3)), np.zeros(m), np.zeros(m)
    for k in range(m):
        si.wi = mi.Vector3f(*wi[k])
        bs, w = bsdf.sample(ctx, si, float(u[k, 0]), mi.Point2f(float(u[k, 1]), float(u[k, 2])))
        if bs.pdf > 0:
            sampled[k] = [bs.wo[0], bs.wo[1], bs.wo[2]]
            weight[k] = [w[0], w[1], w[2]]
            spdf[k] = bs.pdf
        pdf[k] = bsdf.pdf(ctx, si, mi.Vector3f(*wo[k]))
    for name, a in (("sampled", sampled), ("weight", weight), ("sampled_pdf", spdf), ("pdf", pdf)):
        np.save(os.path.join(folder, f"out_{name}.npy"), a, allow_pickle=False)


def _child_render(mi, folder, args):
    import dataclasses

    from brdfkit.render.mitsuba3.scenes import reference_scene_dict
    from brdfkit.render.scene import REFERENCE

    mi.set_variant("scalar_rgb")
    scene = dataclasses.replace(REFERENCE, resolution=args["resolution"])
    d = reference_scene_dict({"type": "measured", "filename": args["path"]}, scene, args["spp"], mi=mi)
    if args.get("integrator"):
        d["integrator"] = dict(args["integrator"])
    img = np.array(mi.render(mi.load_dict(d), spp=args["spp"], seed=args["seed"]), dtype=np.float32)[..., :3]
    np.save(os.path.join(folder, "out_image.npy"), img, allow_pickle=False)


def _main(argv):
    job, folder = argv
    with open(os.path.join(folder, "args.json")) as f:
        args = json.load(f)
    import mitsuba as mi

    {"eval": _child_eval, "render": _child_render, "sample": _child_sample}[job](mi, folder, args)


if __name__ == "__main__":
    _main(sys.argv[1:])
