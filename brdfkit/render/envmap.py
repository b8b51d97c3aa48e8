"""The reference environment: a procedural, deterministic HDR lat-long map.

The map is built from a few analytic parts so that both the diffuse colour and the
highlights of a material matter in a render:

* a sky (upper hemisphere) graded from a pale horizon ``(0.60, 0.64, 0.68)`` to a blue
  zenith ``(0.16, 0.28, 0.60)``,
* a coloured ground ``(0.24, 0.18, 0.10)`` darkening towards the nadir, blended into the
  sky over about 2 degrees at the horizon,
* a small, very bright warm sun: a disc of 1.5 degrees radius, radiance ``800`` (about
  half the irradiance of a surface facing it), 40 degrees above the horizon,
* a bright rectangular window (radiance about 2.4) split into four panes by dark
  mullions, 20 to 45 degrees above the horizon,

all in linear sRGB radiance. Sun and window sit on the camera's side (``+z``), so a
sphere seen by the reference camera is lit by them and a mirror sphere reflects them.

Direction convention (Mitsuba 3's ``envmap`` emitter with an identity transform, so the
same map lights both renderers): world ``y`` is up; a direction ``d`` has texture
coordinates ``u = atan2(d_x, -d_z) / (2 pi)`` (wrapped into ``[0, 1)``) and
``v = arccos(d_y) / pi``. Column ``j`` of a ``W``-wide map sits at ``u = (j + 0.5) / W``,
row ``i`` of an ``H``-high map at ``v = i / (H - 1)`` (rows 0 and ``H - 1`` are the
poles, which Mitsuba averages; the map is constant there), and radiance between them is
bilinear, wrapping in ``u``: :meth:`EnvMap.radiance` reproduces Mitsuba's lookup.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import math
import os

import numpy as np

__all__ = ["EnvMap", "reference_envmap", "uniform_envmap", "uv_to_direction", "direction_to_uv"]

SUN_RADIUS_DEG = 1.5
SUN_RADIANCE = 800.0
SUN_COLOUR = (1.0, 0.92, 0.80)
SUN_UV = (0.43, 0.5 - 40.0 / 180.0)  # 40 degrees above the horizon
WINDOW_UV = (0.56, 0.66, 0.5 - 45.0 / 180.0, 0.5 - 20.0 / 180.0)  # u0, u1, v0, v1
WINDOW_RADIANCE = (2.3, 2.4, 2.6)
MULLION_WIDTH_UV = 0.004
ZENITH = (0.16, 0.28, 0.60)
HORIZON = (0.60, 0.64, 0.68)
GROUND = (0.24, 0.18, 0.10)


def uv_to_direction(u, v):
    """Unit directions ``(..., 3)`` of lat-long texture coordinates (module convention)."""
    phi, theta = np.broadcast_arrays(2.0 * np.pi * np.asarray(u, np.float64),
                                     np.pi * np.asarray(v, np.float64))
    st = np.sin(theta)
    return np.stack([st * np.sin(phi), np.cos(theta), -st * np.cos(phi)], -1)


def direction_to_uv(d):
    """Texture coordinates ``(u, v)`` in ``[0, 1)`` x ``[0, 1]`` of unit directions (shape
    ``(..., 3)``; float64).

    Examples
    --------
    >>> u, v = direction_to_uv(np.array([0.0, 1.0, 0.0]))
    >>> float(v)
    0.0
    """
    d = np.asarray(d, np.float64)
    u = np.arctan2(d[..., 0], -d[..., 2]) / (2 * np.pi)
    return u - np.floor(u), np.arccos(np.clip(d[..., 1], -1.0, 1.0)) / np.pi


@dataclasses.dataclass(frozen=True)
class EnvMap:
    """A lat-long environment map and the regions a renderer should sample densely.

    Attributes
    ----------
    image
        float32 ``(H, W, 3)`` linear-sRGB radiance (W/(m^2 sr) up to a common scale).
    bright
        Tuple of ``(u0, u1, v0, v1, nu, nv, ramp_u, ramp_v)``: rectangles in texture
        coordinates holding the small bright features (sun, window), the number of
        quadrature nodes per axis :mod:`brdfkit.render.quadrature` places in each, and the
        width of the margin over which the rectangle's light nodes hand over to the other
        nodes. Empty for a smooth map.
    """

    image: np.ndarray
    bright: tuple = ()

    @property
    def shape(self):
        return self.image.shape[:2]

    def digest(self) -> str:
        """Short hash of the pixels (names the cached EXR)."""
        return hashlib.sha256(np.ascontiguousarray(self.image).tobytes()).hexdigest()[:16]

    def radiance(self, d):
        """Radiance arriving from world directions ``d`` (``(N, 3)`` unit vectors),
        bilinear exactly as Mitsuba 3's ``envmap`` looks it up; float64 ``(N, 3)``."""
        h, w = self.shape
        u, v = direction_to_uv(d)
        x = (u - 0.5 / w) * w  # column j at u = (j + 0.5) / W
        x = x - np.floor(x / w) * w
        y = v * (h - 1)
        x0 = np.clip(np.floor(x), 0, w - 1)
        y0 = np.clip(np.floor(y), 0, h - 2)
        fx, fy = (x - x0)[:, None], (y - y0)[:, None]
        x0, y0 = x0.astype(np.intp), y0.astype(np.intp)
        x1 = (x0 + 1) % w
        flat = np.asarray(self.image, np.float64).reshape(-1, 3)
        v00, v01 = flat[y0 * w + x0], flat[y0 * w + x1]
        v10, v11 = flat[(y0 + 1) * w + x0], flat[(y0 + 1) * w + x1]
        return (1 - fy) * ((1 - fx) * v00 + fx * v01) + fy * ((1 - fx) * v10 + fx * v11)

    def exr_path(self, folder: str | os.PathLike | None = None) -> str:
        """This map as an OpenEXR file for Mitsuba, written once (atomically) into a cache
        folder (``$BRDFKIT_CACHE`` or ``~/.cache/brdfkit``) and named by its hash."""
        from brdfkit.render.image import write_exr

        folder = os.fspath(folder or os.environ.get("BRDFKIT_CACHE")
                           or os.path.join(os.path.expanduser("~"), ".cache", "brdfkit"))
        os.makedirs(folder, exist_ok=True)
        path = os.path.join(folder, f"envmap-{self.digest()}.exr")
        if not os.path.exists(path):
            write_exr(path, self.image)
        return path


def _smoothstep(e0, e1, x):
    t = np.clip((x - e0) / (e1 - e0), 0.0, 1.0)
    return t * t * (3 - 2 * t)


def _texel_coverage(width, height, inside, n=8, v_range=None):
    """Fraction of each texel's area (in ``u, v``) where ``inside(u, v)`` holds, from an
    ``n x n`` supersampling of the texel around its sample point.

    ``v_range = (v_lo, v_hi)``: ``inside`` is false outside it, so only the rows whose
    samples reach it are evaluated (the sun's disc covers a few of the 128 rows; testing
    all of them was 0.85 s of every render's start). The other rows are 0."""
    j = np.arange(width)
    i = np.arange(height)
    if v_range is not None:
        lo = max(0, int(np.floor(v_range[0] * (height - 1))) - 2)
        hi = min(height, int(np.ceil(v_range[1] * (height - 1))) + 3)
        i = i[lo:hi]
    off = (np.arange(n) + 0.5) / n - 0.5
    cov = np.zeros((i.size, width))
    for a in off:
        for b in off:
            u = ((j + 0.5 + a) / width) % 1.0
            v = np.clip((i + b) / (height - 1), 0.0, 1.0)
            cov += inside(u[None, :], v[:, None])
    if v_range is None:
        return cov / (n * n)
    out = np.zeros((height, width))
    out[i] = cov / (n * n)
    return out


@functools.lru_cache(maxsize=4)
def reference_envmap(width: int = 256, height: int = 128) -> EnvMap:
    """The procedural reference environment (see the module docstring).

    Parameters
    ----------
    width, height
        Texture size; the default ``256 x 128`` is the reference scene's.

    Returns
    -------
    EnvMap
        Deterministic: the same size gives the same pixels on every machine.
    """
    v = np.arange(height) / (height - 1)
    u = (np.arange(width) + 0.5) / width
    dirs = uv_to_direction(u[None, :], v[:, None])  # (H, W, 3)
    elev = np.arcsin(np.clip(dirs[..., 1], -1, 1))  # radians, + above the horizon
    zenith = np.array(ZENITH)
    horizon = np.array(HORIZON)
    ground = np.array(GROUND)
    t = np.sqrt(np.clip(elev / (np.pi / 2), 0, 1))[..., None]
    sky = horizon * (1 - t) + zenith * t
    gnd = ground * (0.55 + 0.45 * (1 - np.clip(-elev / (np.pi / 2), 0, 1)))[..., None]
    blend = _smoothstep(-0.02, 0.02, elev)[..., None]
    img = gnd * (1 - blend) + sky * blend

    # Window: four panes; mullions are dark frame bars across the middle.
    u0, u1, v0, v1 = WINDOW_UV
    um, vm, mw = (u0 + u1) / 2, (v0 + v1) / 2, MULLION_WIDTH_UV

    def pane(uu, vv):
        inside = (uu >= u0) & (uu <= u1) & (vv >= v0) & (vv <= v1)
        bar = (np.abs(uu - um) < mw) | (np.abs(vv - vm) < mw * 2)
        return (inside & ~bar).astype(np.float64)

    def frame(uu, vv):
        inside = (uu >= u0) & (uu <= u1) & (vv >= v0) & (vv <= v1)
        bar = (np.abs(uu - um) < mw) | (np.abs(vv - vm) < mw * 2)
        return (inside & bar).astype(np.float64)

    cp, cf = _texel_coverage(width, height, pane)[..., None], _texel_coverage(width, height, frame)[..., None]
    img = img * (1 - cp - cf) + cp * np.array(WINDOW_RADIANCE) + cf * np.array([0.05, 0.04, 0.03])

    # Sun: a disc of SUN_RADIUS_DEG around its direction, anti-aliased by coverage.
    s = uv_to_direction(*SUN_UV)
    cos_r = math.cos(math.radians(SUN_RADIUS_DEG))

    def disc(uu, vv):
        return (uv_to_direction(uu, vv) @ s >= cos_r).astype(np.float64)

    r_v = math.radians(SUN_RADIUS_DEG) / math.pi  # the disc's extent in v (theta = pi v)
    cs = _texel_coverage(width, height, disc, v_range=(SUN_UV[1] - r_v, SUN_UV[1] + r_v))[..., None]
    img = img * (1 - cs) + cs * SUN_RADIANCE * np.array(SUN_COLOUR)

    # Poles: Mitsuba replaces the first and last rows by their mean; make them constant.
    img[0] = img[0].mean(0)
    img[-1] = img[-1].mean(0)

    du, dv = 1.0 / width, 1.0 / (height - 1)
    r = math.radians(SUN_RADIUS_DEG)
    su, sv = SUN_UV
    half_u = r / (2 * math.pi * math.sin(math.pi * sv))
    # Rectangles around the features with a margin of 3 texels (the bilinear support
    # plus a 2-texel ramp over which the light nodes hand over to the others).
    m_u, m_v = 3 * du, 3 * dv
    sun_rect = (su - half_u - m_u, su + half_u + m_u, sv - r / math.pi - m_v, sv + r / math.pi + m_v,
                8, 8, 2 * du, 2 * dv)
    win_rect = (u0 - m_u, u1 + m_u, v0 - m_v, v1 + m_v, 12, 10, 2 * du, 2 * dv)
    return EnvMap(image=img.astype(np.float32), bright=(sun_rect, win_rect))


def uniform_envmap(radiance=(1.0, 1.0, 1.0), width: int = 64, height: int = 32) -> EnvMap:
    """A constant environment (for closed-form checks: a Lambertian surface of albedo
    ``a`` under it has radiance ``a * L`` everywhere)."""
    img = np.empty((height, width, 3), np.float32)
    img[:] = np.asarray(radiance, np.float32)
    return EnvMap(image=img)
