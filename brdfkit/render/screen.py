"""The render-aligned error: a small, differentiable render of the reference scene.

Renders are what brdfkit is judged by (reference-scene PSNR and Delta E 2000,
:mod:`brdfkit.evaluation.metrics`), and a BRDF-space error ranks reconstructions differently: a latent refinement that cut
:func:`~brdfkit.evaluation.metrics.brdf_log_rmse` threefold lost 3 dB on screen. This module makes the render itself the error.

A render of the reference scene (:mod:`brdfkit.render.quadrature`) is *linear* in the
BRDF: pixel ``p`` is ``sum_k rw_pk f(wi_pk, wo_pk)`` over its quadrature pairs ``k``. A
:class:`Screen` keeps those pairs for a low-resolution image (32 px by default: 812
pixels on the sphere) once, as Rusinkiewicz angles, network inputs and weights, so that

* a table is rendered by a trilinear lookup at the pairs (:meth:`Screen.render_table`),
* a hyponet is rendered by evaluating it at the pairs only, with gradients
  (:meth:`Screen.render_hyponet`): no dense table is made, and the render is what the
  refinement of :mod:`brdfkit.hypernet.refine_on_screen` descends on,

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
    """The quadrature pairs of one low-resolution scene, ready for repeated renders.

    Attributes
    ----------
    pix
        int64 ``(M,)`` the pair's pixel in ``[0, P)``.
    theta_h, theta_d, phi_d
        float64 ``(M,)`` radians, ``phi_d`` folded into ``[0, pi)``.
    hd
        float32 ``(M, 6)`` network inputs (:func:`brdfkit.geometry.hd_vectors`).
    rw
        float32 ``(M, 3)`` radiance times quadrature weight.
    pixels
        ``P``, the pixels on the object.
    """

    pix: object
    theta_h: object
    theta_d: object
    phi_d: object
    hd: object
    rw: object
    pixels: int

    def _sum(self, f):
        import torch

        out = torch.zeros(self.pixels, 3, dtype=f.dtype, device=f.device)
        return out.index_add(0, self.pix, f * self.rw.to(f.dtype))

    def lookup(self, table):
        """A ``(90, 90, 180, 3)`` table at the pairs, float64 torch ``(M, 3)`` (trilinear,
        as :class:`~brdfkit.render.renderable.TableBRDF` renders it; unmeasured corners left out)."""
        import torch

        from brdfkit.geometry.trilinear import lookup_trilinear

        t = torch.as_tensor(np.ascontiguousarray(table, np.float32), device=self.hd.device)
        return lookup_trilinear(t, self.theta_h.float(), self.theta_d.float(), self.phi_d.float(), fill=0.0).double()

    def render_table(self, table, at_pairs=None):
        """Image ``(P, 3)`` float64 torch of a table (``at_pairs``: its :meth:`lookup`,
        when already made)."""
        return self._sum(self.lookup(table) if at_pairs is None else at_pairs)

    def reference(self, model):
        """The model's ``rho_ref`` at the pairs, float32 ``(M, 3)`` (cached per model;
        ``model`` a :class:`~brdfkit.hypernet.loaded.LoadedNetwork`, or anything with its
        ``cache``, ``reference_at_pairs`` and ``hyponet_values``)."""
        key = id(self)
        cache = model.cache.screen
        # The id of a screen that was freed is reused by the next one made: a cached
        # reference counts only if its screen is this one (else another scene's pairs are
        # indexed out of bounds, a device-side assert on CUDA).
        hit = cache.get(key)
        if hit is None or hit[0]() is not self:
            ref = model.reference_at_pairs(self.theta_h, self.theta_d, self.phi_d)
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
            Evaluate only these pairs (int64 ``(K,)``, repeats allowed): a subset of the
            pixels' pairs, or a draw of them.
        scale
            float32 ``(K,)`` factor of each evaluated pair (a draw's ``1 / (K p)``).
        """
        import torch

        hd, ref, pix, rw = self.hd, self.reference(model), self.pix, self.rw
        if idx is not None:
            hd, ref, pix, rw = hd[idx], ref[idx], pix[idx], rw[idx]
        if scale is not None:
            rw = rw * scale[:, None]
        rho = model.hyponet_values(weights, hd, ref)
        out = torch.zeros(self.pixels, 3, dtype=rho.dtype, device=rho.device)
        return out.index_add(0, pix, rho * rw)


def screen_error(pred, ref, pixels=None):
    """Mean squared difference of two :class:`Screen` images after the metrics' display
    encoding (torch, differentiable in ``pred``); over the pixel indices ``pixels`` only
    when given. The whole image of ``RESOLUTION^2`` pixels is not divided by: this is the
    mean over the object's pixels."""
    from brdfkit.render.display import display_encode_torch

    a, b = display_encode_torch(pred), display_encode_torch(ref)
    if pixels is not None:
        a, b = a[pixels], b[pixels]
    return ((a - b) ** 2).mean()


def screen_psnr(pred, ref, pixels=None) -> float:
    """:func:`screen_error` as a PSNR in dB (peak 1; 100 for identical images)."""
    mse = float(screen_error(pred, ref, pixels))
    return 100.0 if mse <= 0.0 else min(100.0, -10.0 * math.log10(mse))


_SCREENS: dict = {}


def screen(device=None, resolution: int = SCREEN_RESOLUTION, env=None, q: Quadrature = QUADRATURE) -> Screen:
    """The :class:`Screen` of the reference scene at ``resolution`` pixels (kept per
    process: built in about 0.1 s, 40 MB at 32 px).

    Parameters
    ----------
    device
        Torch device (``None``: CPU).
    resolution
        Image side in pixels.
    env
        :class:`~brdfkit.render.envmap.EnvMap` (default: the reference environment).
    q
        Quadrature node counts (default: the reference scene's).
    """
    import torch

    from brdfkit.geometry import half_diff_from_io, hd_vectors
    from brdfkit.render.envmap import reference_envmap
    from brdfkit.render.pairs import block_pairs
    from brdfkit.render.quadrature import _techniques

    env = env if env is not None else reference_envmap()
    dev = torch.device(device) if device is not None else torch.device("cpu")
    key = (resolution, env.digest(), env.bright, q, str(dev))
    if key in _SCREENS:
        return _SCREENS[key]
    normals, inside = Scene(resolution=resolution, quadrature=q).pixel_normals()
    normals = torch.as_tensor(np.ascontiguousarray(normals[inside]), device=dev)
    tq = _techniques(q, env, dev)
    wo_world = torch.tensor([0.0, 0.0, 1.0], dtype=torch.float64, device=dev)
    parts = []
    block = max(1, (1 << 17) // (tq.n_c + tq.n_b + tq.n_a))
    with torch.no_grad():
        for s in range(0, normals.shape[0], block):
            pix, wi, wo, rw, _ = block_pairs(tq, normals[s:s + block], wo_world)
            above = (wi[:, 2] > 0) & (wo[:, 2] > 0)
            th, _, td, pd = half_diff_from_io(wi.double(), wo.double())
            pd = torch.remainder(pd, math.pi)
            pd = torch.where(pd > math.pi - 1e-9, pd - math.pi, pd)
            parts.append((pix.long()[above] + s, th[above], td[above], pd[above], rw.T[above]))
    pix, th, td, pd, rw = (torch.cat(p) for p in zip(*parts))
    out = Screen(pix=pix, theta_h=th, theta_d=td, phi_d=pd, hd=hd_vectors(th, td, pd).float(),
                 rw=rw.contiguous(), pixels=int(normals.shape[0]))
    if len(_SCREENS) >= 4:
        _SCREENS.clear()
    _SCREENS[key] = out
    return out
