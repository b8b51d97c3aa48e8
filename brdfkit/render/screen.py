"""The render-aligned error: a small, differentiable render of the reference scene.

Renders are what brdfkit is judged by (reference-scene PSNR and Delta E 2000,
:mod:`brdfkit.evaluation.metrics`), and a BRDF-space error ranks reconstructions differently: a latent refinement that cut
:func:`~brdfkit.evaluation.metrics.brdf_log_rmse` threefold lost 3 dB on screen. This module makes the render itself the error.

A render of the reference scene (:mod:`brdfkit.render.quadrature`) is *linear* in the
BRDF: pixel ``p`` is ``sum_k rw_pk f(wi_pk, wo_pk)`` over its quadrature pairs ``k``. A
:class:`Screen` keeps those pairs for a low-resolution image (32 px by default: 812
pixels on the sphere) once, in NumPy, as grid coordinates and weights, so that

* a table is rendered by a trilinear lookup at the pairs (:meth:`Screen.render_table`),
  and a basis's coefficients through a sparse map of the cells the pairs reach
  (:mod:`brdfkit.basis.refine_on_screen`);
* a hyponet is rendered in torch by evaluating it at the pairs only, with gradients
  (:meth:`Screen.render_hyponet`, the pairs as tensors by :meth:`Screen.tensors`): no dense
  table is made, and the render is what the refinement of
  :mod:`brdfkit.hypernet.refine_on_screen` descends on,

and :func:`screen_error` compares two such images as the metrics do: exposure, clip to
``[0, 1]``, sRGB OETF, mean squared difference (:func:`brdfkit.render.display.display_encode`),
reported as a PSNR (:func:`screen_psnr`). ``benchmarks/studies/study_error.py`` measured
how well it ranks reconstructions as the 128 px renders do, on the reference scene and on a
second scene nothing was tuned on (the environment turned half a turn about the vertical,
:func:`rotated_envmap`), beside ``brdf_log_rmse`` and the training loss
(``docs/notes/render-error.md``).
"""

from __future__ import annotations

import dataclasses
import functools
import math
import weakref

import numpy as np

from brdfkit.render.scene import QUADRATURE, Quadrature, Scene

__all__ = ["SCREEN_RESOLUTION", "Screen", "rotated_envmap", "screen", "screen_error", "screen_psnr"]

SCREEN_RESOLUTION = 32
"""Side of the error's image in pixels: 812 pixels on the sphere, about 0.5 M pairs."""


@functools.lru_cache(maxsize=4)
def rotated_envmap(turn: float = 0.5):
    """The reference environment turned by ``turn`` of a full turn about the vertical
    (``u`` shifted): the sun and the window light the sphere from behind the camera's
    other side. The second scene of ``docs/notes/render-error.md``, on which nothing was tuned."""
    from brdfkit.render.envmap import EnvMap, reference_envmap

    env = reference_envmap()
    w = env.image.shape[1]
    shift = int(round(turn * w))
    img = np.roll(env.image, shift, axis=1)
    du = shift / w
    rects = []
    for r in env.bright:
        u0, u1 = r[0] + du, r[1] + du
        if u0 >= 1.0:
            u0, u1 = u0 - 1.0, u1 - 1.0
        rects.append((u0, u1) + tuple(r[2:]))
    return EnvMap(image=np.ascontiguousarray(img), bright=tuple(rects))


@dataclasses.dataclass
class Screen:
    """The quadrature pairs of one low-resolution scene, ready for repeated renders (NumPy).

    Attributes
    ----------
    pix
        int64 ``(M,)`` the pair's pixel in ``[0, P)``.
    coords
        float32 ``(3, M)`` the pairs' MERL grid coordinates (what a table's lookup needs,
        :mod:`brdfkit.render.lookup`).
    rw
        float32 ``(M, 3)`` radiance times quadrature weight.
    pixels
        ``P``, the pixels on the object.
    """

    pix: np.ndarray
    coords: np.ndarray
    rw: np.ndarray
    pixels: int

    @functools.cached_property
    def angles(self):
        """float64 ``(theta_h, theta_d, phi_d)`` of the pairs (radians, ``phi_d`` in
        ``[0, pi)``), from their grid coordinates."""
        u = self.coords.astype(np.float64)
        return (u[0] / 90) ** 2 * (math.pi / 2), u[1] / 90 * (math.pi / 2), u[2] / 180 * math.pi

    theta_h = property(lambda self: self.angles[0])
    theta_d = property(lambda self: self.angles[1])
    phi_d = property(lambda self: self.angles[2])

    @functools.cached_property
    def hd(self):
        """float32 ``(M, 6)`` network inputs (:func:`brdfkit.geometry.hd_vectors`)."""
        from brdfkit.geometry import hd_vectors

        return hd_vectors(*self.angles).astype(np.float32)

    def sum_pixels(self, f, channels: int = 3):
        """Image ``(P, C)`` float64 of per-pair values ``f`` ``(M, C)`` (BRDF times
        ``rw``, summed per pixel)."""
        f = np.asarray(f, np.float64).reshape(self.pix.size, channels)
        return np.stack([np.bincount(self.pix, f[:, c], minlength=self.pixels) for c in range(channels)], 1)

    def lookup(self, table):
        """A ``(90, 90, 180, 3)`` table at the pairs, float64 ``(M, 3)`` (trilinear, as
        :class:`~brdfkit.render.renderable.TableBRDF` renders it; unmeasured corners left out)."""
        from brdfkit.render.lookup import TableRows

        rows = table if isinstance(table, TableRows) else TableRows(table)
        return rows.lookup(self.coords).T.astype(np.float64)

    def render_table(self, table, at_pairs=None):
        """Image ``(P, 3)`` float64 of a table (``at_pairs``: its :meth:`lookup`, when
        already made)."""
        return self.sum_pixels((self.lookup(table) if at_pairs is None else at_pairs) * self.rw)

    def tensors(self, device=None) -> dict:
        """The pairs as torch tensors on ``device`` (made once per device): ``pix``
        (int64), ``hd`` (float32 ``(M, 6)``), ``rw`` (float32 ``(M, 3)``) and the angles
        (float64): what a hyponet's render (:meth:`render_hyponet`) needs."""
        import torch

        key = str(torch.device(device) if device is not None else torch.device("cpu"))
        cache = self.__dict__.setdefault("_tensors", {})
        if key not in cache:
            to = lambda a: torch.from_numpy(np.ascontiguousarray(a)).to(key)  # noqa: E731
            cache[key] = {"pix": to(self.pix), "hd": to(self.hd), "rw": to(self.rw), "theta_h": to(self.theta_h),
                          "theta_d": to(self.theta_d), "phi_d": to(self.phi_d)}
        return cache[key]

    def reference(self, model):
        """The model's ``rho_ref`` at the pairs, float32 torch ``(M, 3)`` (cached per model;
        ``model`` a :class:`~brdfkit.hypernet.loaded.LoadedNetwork`, or anything with its
        ``cache``, ``device``, ``reference_at_pairs`` and ``hyponet_values``)."""
        key = id(self)
        cache = model.cache.screen
        # The id of a screen that was freed is reused by the next one made: a cached
        # reference counts only if its screen is this one.
        hit = cache.get(key)
        if hit is None or hit[0]() is not self:
            t = self.tensors(model.device)
            ref = model.reference_at_pairs(t["theta_h"], t["theta_d"], t["phi_d"])
            if len(cache) >= 8:  # a few scenes per model (screen tuning turns three)
                cache.clear()
            cache[key] = hit = (weakref.ref(self), ref)
        return hit[1]

    def render_hyponet(self, model, weights, idx=None, scale=None):
        """Image ``(P, 3)`` float32 torch of hyponet ``weights`` (batch of one, as
        :meth:`brdfkit.hypernet.network.HyperBRDF.hyponet_weights` gives them), with
        gradients, evaluated at the pairs only.

        Parameters
        ----------
        idx
            Evaluate only these pairs (int64 torch ``(K,)``, repeats allowed): a subset
            of the pixels' pairs, or a draw of them.
        scale
            float32 torch ``(K,)`` factor of each evaluated pair (a draw's ``1 / (K p)``).
        """
        import torch

        t = self.tensors(model.device)
        hd, ref, pix, rw = t["hd"], self.reference(model), t["pix"], t["rw"]
        if idx is not None:
            idx = torch.as_tensor(idx, device=hd.device).long()
            hd, ref, pix, rw = hd[idx], ref[idx], pix[idx], rw[idx]
        if scale is not None:
            rw = rw * torch.as_tensor(scale, device=rw.device)[:, None]
        rho = model.hyponet_values(weights, hd, ref)
        out = torch.zeros(self.pixels, 3, dtype=rho.dtype, device=rho.device)
        return out.index_add(0, pix, rho * rw)


def screen_error(pred, ref, pixels=None):
    """Mean squared difference of two :class:`Screen` images after the metrics' display
    encoding; over the pixel indices ``pixels`` only when given. NumPy images give a
    float; torch ones a torch scalar, differentiable in ``pred``. The whole image of
    ``RESOLUTION^2`` pixels is not divided by: this is the mean over the object's pixels."""
    if type(pred).__module__.startswith("torch"):
        from brdfkit.render.display import display_encode_torch

        a, b = display_encode_torch(pred), display_encode_torch(ref)
        if pixels is not None:
            a, b = a[pixels], b[pixels]
        return ((a - b) ** 2).mean()
    from brdfkit.render.display import display_encode

    a, b = display_encode(pred), display_encode(ref)
    if pixels is not None:
        a, b = a[pixels], b[pixels]
    return float(np.mean((a - b) ** 2))


def screen_psnr(pred, ref, pixels=None) -> float:
    """:func:`screen_error` as a PSNR in dB (peak 1; 100 for identical images)."""
    mse = float(screen_error(pred, ref, pixels))
    return 100.0 if mse <= 0.0 else min(100.0, -10.0 * math.log10(mse))


_SCREENS: dict = {}


def screen(device=None, resolution: int = SCREEN_RESOLUTION, env=None, q: Quadrature = QUADRATURE) -> Screen:
    """The :class:`Screen` of the reference scene at ``resolution`` pixels (kept per
    process: 32 px built in about 0.05 s, 10 MB).

    Parameters
    ----------
    device
        Ignored (the pairs are NumPy arrays; :meth:`Screen.tensors` puts them on a torch
        device); kept for callers that pass one.
    resolution
        Image side in pixels.
    env
        :class:`~brdfkit.render.envmap.EnvMap` (default: the reference environment).
    q
        Quadrature node counts (default: the reference scene's).
    """
    from brdfkit.render.envmap import reference_envmap
    from brdfkit.render.pairs import block_pairs
    from brdfkit.render.quadrature import BLOCK_PIXELS, _techniques
    from brdfkit.runtime import thread_map

    env = env if env is not None else reference_envmap()
    key = (resolution, env.digest(), env.bright, q)
    if key in _SCREENS:
        return _SCREENS[key]
    normals, inside = Scene(resolution=resolution, quadrature=q).pixel_normals()
    normals = np.ascontiguousarray(normals[inside])
    tq = _techniques(q, env)
    wo_world = np.array([0.0, 0.0, 1.0])
    starts = range(0, normals.shape[0], BLOCK_PIXELS)
    parts = list(thread_map(lambda s: block_pairs(tq, normals[s:s + BLOCK_PIXELS], wo_world), starts))
    pix = np.concatenate([pb.pix.astype(np.int64) + s for s, pb in zip(starts, parts)])
    coords = np.concatenate([pb.coords for pb in parts], 1)
    rw = np.ascontiguousarray(np.concatenate([pb.rw for pb in parts], 1).T)
    out = Screen(pix=pix, coords=coords, rw=rw, pixels=int(normals.shape[0]))
    if len(_SCREENS) >= 8:
        _SCREENS.clear()
    _SCREENS[key] = out
    return out
