"""Synthetic analytic materials written as MERL tables: built-in data for the demo and tests.

Each material is a Lambertian base plus a GGX microfacet lobe (Walter et al. 2007,
"Microfacet Models for Refraction through Rough Surfaces") with separable Smith
shadowing-masking and exact Fresnel, for a dielectric (real index of refraction) or a
conductor (complex index ``n + ik`` per RGB channel)::

    f(wi, wo) = albedo / pi + ks * D(h) F(wi.h) G1(wi) G1(wo) / (4 cos_i cos_o)

Random libraries draw parameters from these documented ranges (``docs/synthetic.md``):

============ ============================== ==========================================
parameter    dielectric (60%)               conductor (40%)
============ ============================== ==========================================
alpha        log-uniform [0.01, 0.6]        log-uniform [0.01, 0.6]
albedo (RGB) uniform [0.005, 0.85] each     0
ior / n, k   ior uniform [1.3, 1.8]         a metal from :data:`METALS`, k scaled [0.8, 1.2]
ks           1                              1
============ ============================== ==========================================

and always include the stiff cases of :data:`STIFF` (near-mirror, black, white, strong
grazing Fresnel), which a model and a renderer must survive.
"""

from __future__ import annotations

import dataclasses
import os

import numpy as np

from brdfkit.geometry import TABLE_SHAPE, grid_directions

__all__ = ["Material", "METALS", "STIFF", "evaluate", "table", "library", "write_library"]

# Complex index of refraction (n, k) at roughly 650, 550, 450 nm.
METALS = {
    "gold": ((0.18, 0.42, 1.37), (3.42, 2.35, 1.77)),
    "copper": ((0.27, 0.68, 1.22), (3.61, 2.62, 2.29)),
    "aluminium": ((1.50, 0.98, 0.62), (7.65, 6.55, 5.31)),
    "silver": ((0.15, 0.14, 0.13), (3.98, 3.35, 2.47)),
    "chromium": ((3.20, 3.18, 2.33), (3.30, 3.33, 3.14)),
}


@dataclasses.dataclass(frozen=True)
class Material:
    """Parameters of one analytic material.

    Attributes
    ----------
    name
        File stem when written.
    kind
        ``"dielectric"`` or ``"conductor"``.
    alpha
        GGX roughness (``alpha = roughness^2`` in Disney terms), > 0.
    albedo
        Lambertian albedo per RGB channel, in ``[0, 1]``.
    ior
        Dielectric: real index per channel. Conductor: real part ``n`` per channel.
    k
        Conductor: imaginary part of the index per channel (ignored for dielectrics).
    ks
        Scale of the specular lobe.
    """

    name: str
    kind: str
    alpha: float
    albedo: tuple = (0.0, 0.0, 0.0)
    ior: tuple = (1.5, 1.5, 1.5)
    k: tuple = (0.0, 0.0, 0.0)
    ks: float = 1.0


STIFF = (
    # GGX peak D(0) = 1 / (pi alpha^2) = 1.3e4 at alpha = 0.005: values above 1e3.
    Material("stiff-mirror", "conductor", 0.005, ior=METALS["silver"][0], k=METALS["silver"][1]),
    Material("stiff-black", "dielectric", 0.3, albedo=(1e-3, 1e-3, 1e-3), ks=0.01),
    Material("stiff-white", "dielectric", 0.4, albedo=(0.95, 0.95, 0.95)),
    # Smooth dark dielectric: the reflectance climbs from 4% to 100% towards grazing.
    Material("stiff-grazing", "dielectric", 0.05, albedo=(0.01, 0.01, 0.02), ior=(1.5, 1.5, 1.5)),
)


def _fresnel_dielectric(cos, eta):
    """Unpolarised Fresnel reflectance from outside a dielectric of index ``eta``."""
    cos = np.clip(cos, 0.0, 1.0)
    sin2_t = (1.0 - cos ** 2) / eta ** 2
    cos_t = np.sqrt(np.clip(1.0 - sin2_t, 0.0, None))
    rs = (cos - eta * cos_t) / (cos + eta * cos_t)
    rp = (eta * cos - cos_t) / (eta * cos + cos_t)
    return 0.5 * (rs ** 2 + rp ** 2)


def _fresnel_conductor(cos, n, k):
    """Unpolarised Fresnel reflectance of a conductor of complex index ``n + ik``."""
    cos = np.clip(cos, 0.0, 1.0).astype(np.complex128)
    eta = n + 1j * k
    sin2 = 1.0 - cos ** 2
    cos_t = np.sqrt(1.0 - sin2 / eta ** 2)
    rs = (cos - eta * cos_t) / (cos + eta * cos_t)
    rp = (eta * cos - cos_t) / (eta * cos + cos_t)
    return 0.5 * (np.abs(rs) ** 2 + np.abs(rp) ** 2)


def _smith_g1(cos, a2):
    cos = np.clip(cos, 1e-12, 1.0)
    return 2.0 * cos / (cos + np.sqrt(a2 + (1.0 - a2) * cos ** 2))


def evaluate(material: Material, wi, wo) -> np.ndarray:
    """BRDF values (1/sr) of ``material`` for direction pairs.

    Parameters
    ----------
    wi, wo
        Unit vectors ``(..., 3)`` in the local frame.

    Returns
    -------
    numpy.ndarray
        ``(..., 3)`` float64, 0 where either direction is below the horizon.
    """
    wi, wo = np.asarray(wi, np.float64), np.asarray(wo, np.float64)
    ci, co = wi[..., 2], wo[..., 2]
    above = (ci > 0) & (co > 0)
    h = wi + wo
    h = h / np.clip(np.linalg.norm(h, axis=-1, keepdims=True), 1e-30, None)
    ch = np.clip(h[..., 2], 0.0, 1.0)
    cd = np.clip((wi * h).sum(-1), 0.0, 1.0)
    a2 = material.alpha ** 2
    d = a2 / (np.pi * ((a2 - 1.0) * ch ** 2 + 1.0) ** 2)
    g = _smith_g1(ci, a2) * _smith_g1(co, a2)
    cols = []
    for c in range(3):
        if material.kind == "conductor":
            fr = _fresnel_conductor(cd, material.ior[c], material.k[c])
        else:
            fr = _fresnel_dielectric(cd, material.ior[c])
        spec = material.ks * d * fr * g / (4.0 * np.clip(ci, 1e-12, None) * np.clip(co, 1e-12, None))
        cols.append(material.albedo[c] / np.pi + spec)
    out = np.stack(cols, -1)
    return np.where(above[..., None], out, 0.0)


def table(material: Material) -> np.ndarray:
    """The material on the MERL grid: ``(90, 90, 180, 3)`` float64, physical units, NaN
    below the horizon (as in measured files)."""
    wi, wo = grid_directions()
    out = evaluate(material, wi, wo)
    out[~((wi[..., 2] > 0) & (wo[..., 2] > 0))] = np.nan
    assert out.shape == TABLE_SHAPE
    return out


def _random_material(rng: np.random.Generator, name: str) -> Material:
    alpha = float(np.exp(rng.uniform(np.log(0.01), np.log(0.6))))
    if rng.random() < 0.6:
        return Material(name, "dielectric", alpha,
                        albedo=tuple(float(x) for x in rng.uniform(0.005, 0.85, 3)),
                        ior=(float(rng.uniform(1.3, 1.8)),) * 3)
    metal = list(METALS)[rng.integers(len(METALS))]
    n, k = METALS[metal]
    scale = rng.uniform(0.8, 1.2, 3)
    return Material(name, "conductor", alpha, ior=tuple(float(x) for x in n),
                    k=tuple(float(a * s) for a, s in zip(k, scale)))


def library(n: int, seed: int = 0, stiff: bool = True) -> list[Material]:
    """A deterministic library of ``n`` materials (same ``n`` and ``seed``, same library).

    With ``stiff`` the first materials are :data:`STIFF` (as many as fit in ``n``); the
    rest are drawn at random, named ``synth-000``, ``synth-001``, ...
    """
    if n < 1:
        raise ValueError("a library needs at least one material")
    rng = np.random.default_rng(seed)
    fixed = list(STIFF[:n]) if stiff else []
    return fixed + [_random_material(rng, f"synth-{i:03d}") for i in range(n - len(fixed))]


def write_library(folder: str | os.PathLike, n: int, seed: int = 0, stiff: bool = True) -> list[str]:
    """Write :func:`library` as MERL files ``folder/<name>.binary``; returns the paths."""
    from brdfkit.io.merl import write_merl

    os.makedirs(folder, exist_ok=True)
    paths = []
    for m in library(n, seed, stiff):
        p = os.path.join(os.fspath(folder), m.name + ".binary")
        write_merl(p, table(m))
        paths.append(p)
    return paths
