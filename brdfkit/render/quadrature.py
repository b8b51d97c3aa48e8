"""The reference-scene renderer: deterministic quadrature, no path tracing.

A convex object under a distant environment sees nothing but the environment, so each
pixel of the reference scene (:mod:`brdfkit.render.scene`) is the direct-lighting integral

    L_o(wo) = integral over the upper hemisphere of L_env(wi) f(wi, wo) cos(theta_i) dwi

at the pixel centre's sphere normal (known in closed form). It is computed with a fixed
set of directions per pixel, the same for every render, so images are noise-free and
reproducible. Three node sets ("techniques") each cover what makes the integrand sharp
somewhere, and a partition of unity ``s_C + s_B + s_A = 1`` over directions says which
technique integrates which part (deterministic multiple importance sampling; Veach and
Guibas 1995). Each node adds ``w s_X L_env f cos``, ``w`` its solid-angle weight.

* **Cosine nodes** (C): an ``n x n`` grid of cell midpoints, concentric disk map
  (Shirley and Chiu 1997) projected to the hemisphere; ``w = pi / (N_C cos(theta_i))``.
  Smooth lighting on diffuse and rough materials.
* **Half-vector nodes** (B): rings ``k = 0 .. K-1`` at ``theta_h = pi/2 (u / K)^p``,
  ``u = k + 1/2``, ``M_k = max(M_min, round(M sqrt(sin theta_h)))`` azimuths each, ``wi``
  the mirror of ``wo`` about each ``h``; ``w = 4 (wo.h) sin(theta_h) dtheta_h/du 2 pi / M_k``.
  With ``p = 3`` the first ring is ``pi/2 (1 / 2K)^3`` (2.5e-5 rad for ``K = 20``) from
  the specular direction, so near-mirror lobes (and MERL's own square-root ``theta_h``
  spacing) are resolved.
* **Light nodes** (A): a fixed grid of world directions in each rectangle of
  ``EnvMap.bright`` (the sun and the window of the reference map), uniform in texture
  coordinates; each node carries the environment radiance *averaged over its patch*
  (integrated once on a fine sub-grid), so the sun's power is exact however few nodes
  cover it.

Shares: ``s_B = s_B0 (1 - rho + rho beta)``, ``s_A = rho (1 - s_B0 beta)``,
``s_C = (1 - s_B0)(1 - rho)``. ``s_B0`` (:func:`half_share`) is the balance heuristic
between the half-vector and cosine nodes' densities (``d_B / (d_B + d_C)``, the ring count
taken as continuous in ``theta_h`` and ``d_C`` floored at a quarter of its value at the
normal, so that coarse outer rings never own the horizon), times a smooth cut to 0 at
``theta_h = half_extent``. ``rho`` is a ramp that is 1 inside a light rectangle and falls
to 0 over its margin, and ``beta`` = 1 for ``theta_h < light_handover[0]`` falling
(smoothly in ``log theta_h``) to 0 at ``light_handover[1]``: near the specular direction
the dense half-vector rings see a bright source better than the light grid does,
elsewhere the light grid does. Cosine nodes never take a share inside a light rectangle,
so no coarse node ever lands on the sun.

Finally each technique is normalised so that, for every pixel, its weights integrate its
share of the cosine-weighted hemisphere exactly: ``sum w s_B cos / pi`` to the tabulated
``integral s_B0 cos / pi`` (a function of ``theta_o`` only, minus the part the light
nodes hold), the cosine nodes to the rest. This makes the quadrature exact for a
constant BRDF under any environment that is constant outside the light rectangles, and
changes the weights by well under 1% otherwise (:attr:`RenderStats.scale_range`).

The BRDF is evaluated only at the queried direction pairs above the horizon with a
non-zero share, in blocks of pixels x nodes, and each pixel sums its pairs in float64.
The pairs, their grid coordinates and their ``L_env w s cos`` are computed technique by
technique, mostly in float32, by :mod:`brdfkit.render.pairs`; they depend on the scene,
not on the BRDF, so those of the last scene rendered (up to :data:`PAIR_CACHE_BYTES`,
0.33 GB at 256 x 256) are kept for the next render of the same scene in the process
(:func:`clear_cache` frees them). Background pixels are black.

A BRDF is evaluated by ``brdf.eval_pairs(block) -> (3, M)`` at a
:class:`~brdfkit.render.pairs.PairBlock` (a table: a trilinear lookup at the pairs' grid
coordinates, :mod:`brdfkit.render.lookup`), or, for one that has only
``eval_dirs(wi, wo) -> (M, 3)``, at the pairs' local directions (NumPy float32
``(M, 3)``; an RGL file, a hyponet). Everything runs in NumPy, on
:func:`brdfkit.runtime.cpu_threads` threads, one block of pixels each: a block's pixels
are summed by one thread in a fixed order, so the image does not depend on the thread
count.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from brdfkit.render.nodes import NodeSet, half_share  # noqa: F401 (re-exported)
from brdfkit.render.pairs import Techniques, block_pairs
from brdfkit.render.scene import REFERENCE, Quadrature, Scene

__all__ = ["NodeSet", "RenderStats", "ScenePairs", "clear_cache", "evaluate", "render", "render_many", "render_pixels"]

# Pixels per block: (pixels x nodes) float32 temporaries of about 0.1 MB, the block's working set
# and the environment's texture in a core's cache (64 measured 30% faster than 160 at 128 px).
BLOCK_PIXELS = 64
# Most bytes of BRDF-independent pairs kept for the next render of the same scene.
PAIR_CACHE_BYTES = 1 << 30

_TECHNIQUES: dict = {}
_PAIRS: dict = {}


def _techniques(q, env):
    """The :class:`~brdfkit.render.pairs.Techniques` of ``(q, env)``, the last few kept
    per process (a render of several BRDFs in turn builds it once)."""
    key = (q, env.digest(), env.bright)
    if key not in _TECHNIQUES:
        if len(_TECHNIQUES) >= 8:
            _TECHNIQUES.clear()
        _TECHNIQUES[key] = Techniques(NodeSet(q, env), env)
    return _TECHNIQUES[key]


def clear_cache():
    """Free the pairs and node constants kept from the last render (:func:`render_pixels`)."""
    _PAIRS.clear()
    _TECHNIQUES.clear()


@dataclasses.dataclass
class RenderStats:
    """What a render did, filled in by :func:`render_pixels` when passed one.

    Attributes
    ----------
    evaluations
        BRDF evaluations made (per BRDF, when several are rendered in one pass).
    scale_range
        ``(min, max)`` of the per-pixel normalisation factors of the half-vector and
        cosine nodes (``(1, 1)`` when none applied).
    """

    evaluations: int = 0
    scale_range: tuple = (1.0, 1.0)


def _needs_directions(brdf) -> bool:
    return not hasattr(brdf, "eval_pairs")


def evaluate(brdf, block):
    """float32 ``(C, M)`` of ``brdf`` at a block's pairs (``eval_pairs``, or
    ``eval_dirs`` at their directions; 0 where a value is not finite, as a renderer
    must not spread a NaN over a pixel)."""
    if not _needs_directions(brdf):
        return brdf.eval_pairs(block)
    vals = np.asarray(brdf.eval_dirs(block.wi.T, block.wo.T), np.float32).T
    return np.where(np.isfinite(vals), vals, np.float32(0))


class ScenePairs:
    """The :class:`~brdfkit.render.pairs.PairBlock` of each block of pixels of one scene:
    made on demand, or taken from the last scene's (kept up to :data:`PAIR_CACHE_BYTES`
    once every block was made: :meth:`keep`).

    Parameters
    ----------
    normals
        float64 ``(P, 3)`` unit world normals.
    env, wo_world, q
        As for :func:`render_pixels`.
    directions
        The blocks must hold the pairs' local directions (a BRDF with only ``eval_dirs``).
    """

    def __init__(self, normals, env, wo_world=(0.0, 0.0, 1.0), q: Quadrature | None = None,
                 directions: bool = False):
        import hashlib

        q = q or REFERENCE.quadrature
        self.normals = np.ascontiguousarray(normals, np.float64).reshape(-1, 3)
        self.starts = list(range(0, self.normals.shape[0], BLOCK_PIXELS))
        self.key = (q, env.digest(), env.bright, tuple(map(float, wo_world)), BLOCK_PIXELS,
                    hashlib.sha256(self.normals.tobytes()).hexdigest())
        self.directions = directions
        self.cached = _PAIRS.get((self.key, True)) or _PAIRS.get((self.key, directions))
        if self.cached is None:
            _PAIRS.clear()  # one scene kept: free the last before building the next
            self._tq = _techniques(q, env)
        self._wo = np.asarray(wo_world, np.float64)
        self._made: dict = {}

    def block(self, i: int):
        """The :class:`~brdfkit.render.pairs.PairBlock` of block ``i`` (pixels
        ``starts[i]`` on)."""
        if self.cached is not None:
            return self.cached[i]
        if i in self._made:
            return self._made[i]
        s = self.starts[i]
        pb = block_pairs(self._tq, self.normals[s:s + BLOCK_PIXELS], self._wo, self.directions)
        self._made[i] = pb
        return pb

    def all_blocks(self) -> list | None:
        """Every block, made now where not yet (on the threads); ``None`` when they would
        not fit in :data:`PAIR_CACHE_BYTES` (then only those made are kept)."""
        from brdfkit.runtime import thread_map

        if self.cached is not None:
            return self.cached
        todo = [i for i in range(len(self.starts)) if i not in self._made]
        size = sum(b.nbytes for b in self._made.values())
        for i, pb in zip(todo, thread_map(self.block, todo)):
            size += pb.nbytes
            if size > PAIR_CACHE_BYTES:
                self._made = {}
                return None
        return [self._made[i] for i in range(len(self.starts))]

    def reached_cells(self):
        """The flat MERL cells the pairs' trilinear corners reach (int64, ascending;
        a table-independent property of the scene, kept with its pairs), or ``None`` when
        the pairs do not fit in memory."""
        if "_reached" not in self.__dict__:
            blocks = self.all_blocks()
            self._reached = None if blocks is None else reached_cells(blocks)
        return self._reached

    def keep(self) -> None:
        """Keep the blocks made for the next render of this scene (all of them, within
        :data:`PAIR_CACHE_BYTES`)."""
        if self.cached is None and len(self._made) == len(self.starts):
            blocks = [self._made[i] for i in range(len(self.starts))]
            if sum(b.nbytes for b in blocks) <= PAIR_CACHE_BYTES:
                _PAIRS[(self.key, self.directions)] = blocks
        self._made = {}


def reached_cells(blocks):
    """The flat MERL cells the trilinear corners of some blocks' pairs reach (int64,
    ascending): each pair's lowest corner marked on the grid (its ``phi_d`` runs of 181,
    :mod:`brdfkit.render.lookup`), then the mark spread to the next cell along each axis
    (clamped at the last ``theta_h`` and ``theta_d``)."""
    from brdfkit.geometry import N_CELLS, N_PHI_D, N_THETA_D, N_THETA_H
    from brdfkit.render.lookup import cell_of

    mark = np.zeros((N_THETA_H, N_THETA_D, N_PHI_D + 1), bool)
    for pb in blocks:
        i = np.floor(pb.coords).astype(np.int64)
        np.minimum(i[0], N_THETA_H - 1, out=i[0])
        np.minimum(i[1], N_THETA_D - 1, out=i[1])
        np.minimum(i[2], N_PHI_D - 1, out=i[2])
        mark[i[0], i[1], i[2]] = True
    mark[:, :, 1:] |= mark[:, :, :-1].copy()
    mark[:, 1:] |= mark[:, :-1].copy()
    mark[1:] |= mark[:-1].copy()
    cells = np.zeros(N_CELLS, bool)
    cells[cell_of(np.flatnonzero(mark))] = True
    return np.flatnonzero(cells)


def render_pixels(brdf, normals, env, wo_world=(0.0, 0.0, 1.0), q: Quadrature | None = None,
                  progress=None, stats: RenderStats | None = None):
    """Direct lighting of surface points with world normals ``normals``.

    Parameters
    ----------
    brdf
        A renderable BRDF (``eval_pairs`` or ``eval_dirs``, :mod:`brdfkit.render.renderable`).
    normals
        Array-like ``(P, 3)`` unit world normals.
    env
        :class:`~brdfkit.render.envmap.EnvMap`.
    wo_world
        World view direction (towards the camera), the same for all points.
    q
        Quadrature settings (default: the reference scene's).
    progress
        Optional callable ``progress(done_points, total_points)``.
    stats
        Optional :class:`RenderStats`, filled in with the BRDF evaluations made and the
        range of the normalisation factors.

    Returns
    -------
    numpy.ndarray
        float32 ``(P, 3)`` outgoing radiance.
    """
    return _render_pixels([brdf], normals, env, wo_world, q, progress, stats)[0]


def _render_pixels(brdfs, normals, env, wo_world=(0.0, 0.0, 1.0), q: Quadrature | None = None,
                   progress=None, stats: RenderStats | None = None):
    """:func:`render_pixels` of several BRDFs in one pass: the nodes, shares and weights
    are computed once (or taken from the last render of the same scene) and each BRDF is
    evaluated at the same pairs; each image is the one a render of that BRDF alone
    gives, to the bit (same pairs, same operations, same order)."""
    from brdfkit.render.renderable import stack_tables
    from brdfkit.runtime import thread_map

    normals = np.asarray(normals, np.float64).reshape(-1, 3)
    total = normals.shape[0]
    pairs = ScenePairs(normals, env, wo_world, q, any(_needs_directions(b) for b in brdfs))
    decoded = [b for b in brdfs if hasattr(b, "prepare_cells")]
    if decoded:  # a decoder evaluated only at the cells the pairs reach (else at every cell)
        cells = pairs.reached_cells()
        if cells is not None:
            for b in decoded:
                b.prepare_cells(cells)
    passes = stack_tables(brdfs)
    outs = [np.zeros((3 * len(idx), total)) for _, idx in passes]
    evaluations, smin, smax = 0, math.inf, -math.inf

    def one(i):
        s, pb = pairs.starts[i], pairs.block(i)
        for (brdf, _), out in zip(passes, outs):
            contrib = evaluate(brdf, pb).reshape(-1, 3, pb.pix.size) * pb.rw
            for ch, row in enumerate(contrib.reshape(-1, pb.pix.size)):
                out[ch, s:s + pb.pixels] = np.bincount(pb.pix, row, minlength=pb.pixels)
        return s, pb

    for s, pb in thread_map(one, range(len(pairs.starts))):
        evaluations += pb.pix.size
        big = pb.big
        if big.any():
            smin, smax = min(smin, float(pb.scale[big].min())), max(smax, float(pb.scale[big].max()))
        if progress is not None:
            progress(s + pb.pixels, total)
    pairs.keep()
    if stats is not None:
        stats.evaluations = evaluations
        stats.scale_range = (smin, smax) if smin <= smax else (1.0, 1.0)
    images = [None] * len(brdfs)
    for (_, idx), out in zip(passes, outs):
        for j, i in enumerate(idx):
            images[i] = out[3 * j:3 * j + 3].T.astype(np.float32)
    return images


def render(brdf, scene: Scene = REFERENCE, env=None, progress=None, stats: RenderStats | None = None):
    """Render the reference scene.

    Parameters
    ----------
    brdf
        A renderable BRDF (:class:`~brdfkit.render.renderable.TableBRDF`,
        :class:`~brdfkit.hypernet.neural_brdf.NeuralBRDF`, ...).
    scene
        :class:`~brdfkit.render.scene.Scene` (resolution, quadrature).
    env
        Environment (default :func:`~brdfkit.render.envmap.reference_envmap`).
    progress
        Optional callable ``progress(done_pixels, total_pixels)``.
    stats
        Optional :class:`RenderStats` to fill in (see :func:`render_pixels`).

    Returns
    -------
    tuple
        ``(image, mask)``: float32 ``(R, R, 3)`` linear-sRGB radiance (background 0, the
        average of the pixel's sample points) and the boolean mask ``(R, R)`` of pixels
        with at least one sample point on the object.
    """
    return render_many([brdf], scene, env, progress, stats)[0]


def render_many(brdfs, scene: Scene = REFERENCE, env=None, progress=None, stats: RenderStats | None = None):
    """Render the reference scene with each of ``brdfs`` in one pass (``brdfkit metrics``
    of two tables): the quadrature's nodes, shares and weights are computed once and every
    BRDF is evaluated at the same direction pairs, the tables among them together
    (:class:`~brdfkit.render.renderable.TableStackBRDF`: the pairs' angles and the lookup's
    corners once for all), so each image equals :func:`render` of that BRDF alone, to
    the bit.

    Parameters
    ----------
    brdfs
        Sequence of renderable BRDFs.
    scene, env, progress, stats
        As for :func:`render` (``stats.evaluations`` counts the evaluations of one BRDF).

    Returns
    -------
    list
        ``(image, mask)`` per BRDF, as :func:`render` returns them.
    """
    from brdfkit.render.envmap import reference_envmap

    env = env if env is not None else reference_envmap()
    normals, inside = scene.pixel_normals()
    images = _render_pixels(list(brdfs), normals[inside], env, q=scene.quadrature, progress=progress,
                            stats=stats)
    out = []
    for pixels in images:
        samples = np.zeros(normals.shape, np.float32)
        samples[inside] = pixels
        out.append((samples.mean(2), inside.any(2)))
    return out
