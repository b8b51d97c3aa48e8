"""Shared helpers of the foundation tests (MERL I/O, geometry, mapping, samples, CLI).

Not a conftest: plain functions imported by the test modules that need them.
"""

from __future__ import annotations

import subprocess
import sys
from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest

from brdfkit.geometry import GRID_SHAPE, N_CELLS, valid_mask

# ../shared beside the checkout; the tests that need it are marked `proxy` and skip.
SHARED = Path(__file__).resolve().parents[2] / "shared"
NBRDF_TO_MERL = SHARED / "tools" / "nbrdf_to_merl.py"
MERL_SIZE = 34_992_012


@lru_cache(maxsize=1)
def measured_mask() -> np.ndarray:
    """``valid_mask()`` (bool ``(90, 90, 180)``), computed once per test process."""
    mask = valid_mask()
    mask.setflags(write=False)
    return mask


def lambert_table(albedo) -> np.ndarray:
    """A Lambertian table: ``albedo / pi`` (1/sr, RGB ``albedo``) on the measured cells,
    NaN elsewhere; float64 ``(90, 90, 180, 3)``."""
    t = np.empty(GRID_SHAPE + (3,))
    t[:] = np.asarray(albedo, np.float64) / np.pi
    t[~measured_mask()] = np.nan
    return t


def random_table(seed: int = 0) -> np.ndarray:
    """A cheap physically plausible table: log-uniform values in [1e-4, 1e3] 1/sr on the
    measured cells, NaN elsewhere; float64 ``(90, 90, 180, 3)``."""
    rng = np.random.default_rng(seed)
    table = 10.0 ** rng.uniform(-4, 3, GRID_SHAPE + (3,))
    table[~measured_mask()] = np.nan
    return table


def merl_bytes(stored_channel_major: np.ndarray, dims=(90, 90, 180)) -> bytes:
    """The bytes of a MERL file: int32 dims, then the stored values (3, N) as float64."""
    return np.asarray(dims, dtype="<i4").tobytes() + \
        np.ascontiguousarray(stored_channel_major, dtype="<f8").tobytes()


def random_stored(seed: int = 0) -> np.ndarray:
    """Stored MERL values ``(3, N_CELLS)``: random doubles over 14 decades (so that many
    of them are not recovered by ``value * scale / scale``), -1 where not measured."""
    rng = np.random.default_rng(seed)
    stored = rng.random((3, N_CELLS)) * 10.0 ** rng.uniform(-8, 6, (3, N_CELLS))
    stored[:, ~measured_mask().reshape(-1)] = -1.0
    return stored


def proxy_material(tmp_path_factory, name: str = "teflon") -> Path:
    """A genuine MERL table decoded from the shared NBRDF fits, written once per test
    session into pytest's temporary folder (never into the repository or a proxies folder).
    Skips the test when ``../shared`` is absent."""
    if not NBRDF_TO_MERL.exists():
        pytest.skip(f"reference data absent ({SHARED})")
    folder = tmp_path_factory.getbasetemp() / "proxy-merl"
    path = folder / f"{name}.binary"
    if not (path.exists() and path.stat().st_size == MERL_SIZE):
        folder.mkdir(exist_ok=True)
        subprocess.run([sys.executable, str(NBRDF_TO_MERL), "merl", str(folder), name],
                       check=True, capture_output=True, timeout=300)
    assert path.stat().st_size == MERL_SIZE
    return path

