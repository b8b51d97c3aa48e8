"""The scene suite: the named scenes brdfkit judges renders in, and the scenes an
objective may fit.

A reconstruction is judged by renders (PSNR, Delta E 2000), and a render judges only the
part of the BRDF its lighting shows. The reference scene lights the sphere from the
camera's side, so grazing angles, backlight and colour under other light go unseen, and
anything fitted on its renders can be fitted to it. The suite is the same sphere and
orthographic camera (:mod:`brdfkit.render.scene`) under other procedural, deterministic
environments, each lighting the BRDF where the others do not:

================ ===========================================================================
name             lighting
================ ===========================================================================
``reference``    the reference environment (:func:`~brdfkit.render.envmap.reference_envmap`):
                 sky, ground, a window and a small sun, all on the camera's side
``backlight``    a warm area light behind the sphere, a cool one behind and above, a dark
                 sky: only the rim lights up, at grazing ``theta_i`` and large ``theta_d``
``rim``          two narrow strip lights at the horizon, at the sphere's sides slightly
                 behind it, and a dim front fill: grazing light from the sides
``small-lights`` five small bright discs at 5, 20, 40, 60 and 80 degrees of elevation over
                 a dark grey room: sharp highlights at several half-vector angles
``overcast``     a CIE standard overcast sky (Moon and Spencer 1942) over a grey ground: no
                 feature, only the diffuse and broad parts of the BRDF
``sunset``       other content and colour: an orange-to-violet sky, a low orange sun, a
                 magenta and a cyan neon panel, a green striped ground
================ ===========================================================================

Every scene is a role: ``judge`` scenes are what the results report (:data:`SUITE`,
``brdfkit metrics --scenes all``); ``objective`` scenes (:data:`OBJECTIVE_SCENES`, a
seeded family of studio set-ups, never reported) are the only scenes an objective may
descend (``docs/notes/render-error.md``). The reference scene is judged too, for continuity
with earlier figures, but today's built-in models were tuned on its renders: its
figures are labelled as such in the results.

Each environment is scaled so that the display (which clips at 1,
:mod:`brdfkit.render.display`) shows its lights without washing out a white Lambertian
sphere: its brightest pixel is 1.09 in ``reference``, 0.46 in ``backlight`` and 0.44 in
``rim`` (only the rim is lit), 0.77 in ``small-lights``, 0.67 in ``overcast`` and 0.94 in
``sunset`` (96 px quadrature renders, ``benchmarks/scene_suite.py``).

Examples
--------
>>> list(SUITE)
['reference', 'backlight', 'rim', 'small-lights', 'overcast', 'sunset']
>>> scene_names("all") == list(SUITE), scene_names("rim,overcast")
(True, ['rim', 'overcast'])
"""

from __future__ import annotations

import dataclasses
import functools
import math
from typing import Callable

import numpy as np

from brdfkit.errors import InputError
from brdfkit.render.envmap import EnvMap, _smoothstep, _texel_coverage, reference_envmap, uv_to_direction

__all__ = ["SuiteScene", "SUITE", "OBJECTIVE_SCENES", "scene_names", "scene_env", "objective_envmap",
           "require_objective"]

_W, _H = 256, 128  # the reference map's size


@dataclasses.dataclass(frozen=True)
class SuiteScene:
    """One named scene: ``name``, a one-line ``summary``, its ``role`` (``"judge"`` or
    ``"objective"``) and ``build()``, which makes its :class:`~brdfkit.render.envmap.EnvMap`."""

    name: str
    summary: str
    role: str
    build: Callable = dataclasses.field(repr=False)


def _uv_of(azimuth_deg: float, elevation_deg: float) -> tuple[float, float]:
    """Texture coordinates of a direction given by its azimuth (0: the camera's side,
    ``+z``; 90: the camera's right, ``+x``; 180: behind) and elevation, in degrees."""
    u = (0.5 + azimuth_deg / 360.0) % 1.0
    return u, 0.5 - elevation_deg / 180.0


def _sky(zenith, horizon, ground, ground_dark: float = 0.45):
    """Sky graded from ``horizon`` to ``zenith`` over the upper hemisphere, ``ground``
    darkening towards the nadir, blended at the horizon; float64 ``(H, W, 3)`` and the
    elevation (radians) of each texel."""
    v = np.arange(_H) / (_H - 1)
    u = (np.arange(_W) + 0.5) / _W
    d = uv_to_direction(u[None, :], v[:, None])
    elev = np.arcsin(np.clip(d[..., 1], -1, 1))
    t = np.sqrt(np.clip(elev / (np.pi / 2), 0, 1))[..., None]
    sky = np.asarray(horizon) * (1 - t) + np.asarray(zenith) * t
    gnd = np.asarray(ground) * (1 - ground_dark * np.clip(-elev / (np.pi / 2), 0, 1))[..., None]
    blend = _smoothstep(-0.02, 0.02, elev)[..., None]
    return gnd * (1 - blend) + sky * blend, elev


def _panel(img, u0, u1, v0, v1, radiance, nodes=(10, 8)):
    """Paint a rectangular light (texture coordinates; ``u`` may cross 0) of constant
    ``radiance`` over ``img``, anti-aliased; returns its bright rectangle (module
    :class:`~brdfkit.render.envmap.EnvMap`: 3 texels of margin, a 2-texel ramp)."""

    def inside(uu, vv):
        uu = np.where(uu < u0, uu + 1.0, uu) if u0 < 0 else uu
        return ((uu >= u0) & (uu <= u1) & (vv >= v0) & (vv <= v1)).astype(np.float64)

    c = _texel_coverage(_W, _H, inside, v_range=(v0, v1))[..., None]
    img[:] = img * (1 - c) + c * np.asarray(radiance, np.float64)
    du, dv = 1.0 / _W, 1.0 / (_H - 1)
    return (u0 - 3 * du, u1 + 3 * du, v0 - 3 * dv, v1 + 3 * dv, nodes[0], nodes[1], 2 * du, 2 * dv)


def _disc(img, u, v, radius_deg, radiance):
    """Paint a disc light of ``radius_deg`` around texture point ``(u, v)``, as the
    reference sun is painted; returns its bright rectangle (8 x 8 light nodes)."""
    s = uv_to_direction(u, v)
    cos_r = math.cos(math.radians(radius_deg))

    def inside(uu, vv):
        return (uv_to_direction(uu, vv) @ s >= cos_r).astype(np.float64)

    r = math.radians(radius_deg)
    c = _texel_coverage(_W, _H, inside, v_range=(v - r / math.pi, v + r / math.pi))[..., None]
    img[:] = img * (1 - c) + c * np.asarray(radiance, np.float64)
    du, dv = 1.0 / _W, 1.0 / (_H - 1)
    half_u = r / (2 * math.pi * math.sin(math.pi * v))
    return (u - half_u - 3 * du, u + half_u + 3 * du, v - r / math.pi - 3 * dv, v + r / math.pi + 3 * dv,
            8, 8, 2 * du, 2 * dv)


def _finish(img, rects) -> EnvMap:
    img[0] = img[0].mean(0)  # Mitsuba averages the pole rows: make them constant
    img[-1] = img[-1].mean(0)
    return EnvMap(image=np.ascontiguousarray(img, np.float32), bright=tuple(rects))


def _backlight() -> EnvMap:
    img, _ = _sky((0.02, 0.025, 0.05), (0.05, 0.05, 0.07), (0.02, 0.02, 0.02))
    rects = []
    u, v = _uv_of(180, 12)  # warm, behind the sphere, just above the horizon
    rects.append(_panel(img, u - 0.05, u + 0.05, v - 10 / 180, v + 8 / 180, (27.0, 21.0, 15.0), (12, 8)))
    u, v = _uv_of(160, 50)  # cool, behind and above
    rects.append(_panel(img, u - 0.03, u + 0.03, v - 8 / 180, v + 8 / 180, (7.5, 12.0, 21.0), (8, 8)))
    return _finish(img, rects)


def _rim() -> EnvMap:
    img, _ = _sky((0.06, 0.06, 0.07), (0.09, 0.09, 0.10), (0.04, 0.04, 0.04))
    rects = []
    for az, rad in ((105, (15.0, 15.0, 16.0)), (255, (12.5, 14.0, 17.5))):  # the sides, slightly behind
        u, v = _uv_of(az, 4)
        rects.append(_panel(img, u - 0.012, u + 0.012, v - 14 / 180, v + 14 / 180, rad, (4, 12)))
    return _finish(img, rects)


def _small_lights() -> EnvMap:
    img, _ = _sky((0.03, 0.03, 0.03), (0.03, 0.03, 0.03), (0.02, 0.02, 0.02))
    lights = ((0, 5, (140, 140, 140)), (-40, 20, (180, 120, 80)), (35, 40, (100, 140, 220)), (-15, 60, (160, 160, 160)),
              (70, 80, (120, 120, 120)))
    rects = [_disc(img, *_uv_of(az, el), 2.0, rad) for az, el, rad in lights]
    return _finish(img, rects)


def _overcast() -> EnvMap:
    img, elev = _sky((1.0, 1.0, 1.0), (1.0, 1.0, 1.0), (0.18, 0.18, 0.17), ground_dark=0.2)
    # CIE standard overcast sky: L(elevation) = L_z (1 + 2 sin(elevation)) / 3.
    up = elev > 0
    lum = 0.85 * (1 + 2 * np.sin(np.clip(elev, 0, None))) / 3
    img[up] = np.array([0.93, 0.96, 1.0]) * lum[up][:, None]
    return _finish(img, [])


def _sunset() -> EnvMap:
    img, elev = _sky((0.10, 0.06, 0.22), (0.95, 0.42, 0.16), (0.03, 0.09, 0.03))
    # Fields: the ground in stripes of two greens.
    u = (np.arange(_W) + 0.5) / _W
    stripes = 0.6 + 0.4 * (np.sin(2 * np.pi * 24 * u) > 0)
    img[elev < 0] *= np.broadcast_to(stripes[None, :, None], img.shape)[elev < 0]
    rects = [_disc(img, *_uv_of(25, 4), 3.0, (220.0, 95.0, 30.0))]
    u0, v0 = _uv_of(-55, 25)
    rects.append(_panel(img, u0 - 0.02, u0 + 0.02, v0 - 12 / 180, v0 + 12 / 180, (3.2, 0.4, 2.6), (6, 8)))
    u0, v0 = _uv_of(-85, 12)
    rects.append(_panel(img, u0 - 0.02, u0 + 0.02, v0 - 8 / 180, v0 + 8 / 180, (0.4, 2.8, 3.2), (6, 8)))
    return _finish(img, rects)


@functools.lru_cache(maxsize=8)
def objective_envmap(seed: int) -> EnvMap:
    """A studio set-up drawn from ``seed``: a dim graded sky and three rectangular lights
    at random azimuths (front, sides and behind alike), elevations, sizes and colour
    temperatures. The family objectives fit on (:data:`OBJECTIVE_SCENES`); no scene of
    :data:`SUITE` is one of them."""
    rng = np.random.default_rng(10_000 + int(seed))
    base = rng.uniform(0.02, 0.15)
    img, _ = _sky(base * np.array([0.7, 0.8, 1.0]), base * np.array([1.0, 0.95, 0.9]), (0.3 * base,) * 3)
    rects = []
    for _ in range(3):
        az, el = rng.uniform(0, 360), rng.uniform(-5, 75)
        half_u, half_v = rng.uniform(0.01, 0.06), rng.uniform(3, 15) / 180
        warm = rng.uniform(0, 1)
        colour = np.array([1.0, 0.9, 0.75]) * warm + np.array([0.75, 0.85, 1.0]) * (1 - warm)
        u, v = _uv_of(az, el)
        v = float(np.clip(v, half_v + 0.02, 1 - half_v - 0.02))
        rects.append(_panel(img, u - half_u, u + half_u, v - half_v, v + half_v,
                            colour * rng.uniform(1.5, 6.0) * 0.03 / (half_u * half_v * 4), (8, 8)))
    return _finish(img, rects)


SUITE: dict[str, SuiteScene] = {s.name: s for s in (
    SuiteScene("reference", "sky, ground, window and a small sun on the camera's side", "judge",
               lambda: reference_envmap()),
    SuiteScene("backlight", "area lights behind the sphere: the rim at grazing angles", "judge", _backlight),
    SuiteScene("rim", "strip lights at the sides, at the horizon: grazing light", "judge", _rim),
    SuiteScene("small-lights", "five small discs at 5 to 80 degrees of elevation", "judge", _small_lights),
    SuiteScene("overcast", "a CIE overcast sky over a grey ground", "judge", _overcast),
    SuiteScene("sunset", "an orange-to-violet sky, a low sun, neon panels, green fields", "judge", _sunset),
)}
"""The judged scenes, in their report order."""

OBJECTIVE_SCENES: dict[str, SuiteScene] = {
    f"studio-{i}": SuiteScene(f"studio-{i}", "three random rectangular lights (seeded)", "objective",
                              functools.partial(objective_envmap, i)) for i in range(8)}
"""Scenes an objective may descend (never reported)."""


def scene_names(spec: str) -> list[str]:
    """The suite scenes a ``--scenes`` value names: ``all``, or names joined by commas
    (``reference,rim``); in the order given, without repeats.

    Raises
    ------
    InputError
        An empty value or an unknown name (listing the known ones).
    """
    if spec is None or not str(spec).strip():
        raise InputError("--scenes: give 'all' or scene names separated by commas")
    if str(spec).strip() == "all":
        return list(SUITE)
    names = []
    for name in (p.strip() for p in str(spec).split(",")):
        if name not in SUITE and name not in OBJECTIVE_SCENES:
            raise InputError(f"unknown scene {name!r}; the suite: {', '.join(SUITE)} (or all)")
        if name and name not in names:
            names.append(name)
    return names


@functools.lru_cache(maxsize=16)
def require_objective(scenes, what: str) -> None:
    """Refuse (:class:`InputError`, one line naming ``what``) scenes an objective may not
    descend: none given, or any that is not one of :data:`OBJECTIVE_SCENES` (a judged
    scene of :data:`SUITE` included)."""
    from brdfkit.errors import InputError

    if not scenes or any(s not in OBJECTIVE_SCENES for s in scenes):
        raise InputError(f"{what} must be objective scenes ({', '.join(OBJECTIVE_SCENES)}), never a judged one; "
                         f"got {', '.join(map(str, scenes)) or 'none'}")


def scene_env(name: str) -> EnvMap:
    """The environment of the scene called ``name`` (built once per process)."""
    spec = SUITE.get(name) or OBJECTIVE_SCENES.get(name)
    if spec is None:
        raise InputError(f"unknown scene {name!r}; the suite: {', '.join(SUITE)}")
    return spec.build()
