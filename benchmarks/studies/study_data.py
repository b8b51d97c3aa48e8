"""Research data for the generalisation study (issue 12): proxy tables held in memory.

Every MERL / RGL proxy table (``../shared/tools/nbrdf_to_merl.py``) is read once and kept
as float32 values at the cells measured by all of them, cached in one ``.npy`` beside the
proxies so a study run starts in seconds. The 20 test materials are never loaded here.
"""

from __future__ import annotations

import json
import os
import pathlib
import time

import numpy as np

from brdfkit.geometry import GRID_SHAPE, N_CELLS, cos_theta_i, grid_angles
from brdfkit.io.merl import read_merl

BENCHMARKS = pathlib.Path(__file__).resolve().parent.parent
SHARED = BENCHMARKS.parent.parent / "shared"
TEST_LIST = SHARED / "data" / "merl-test.txt"
VALIDATION_LIST = BENCHMARKS / "validation.txt"


def test_materials() -> list[str]:
    return TEST_LIST.read_text().split()


def validation_materials() -> list[str]:
    """The fixed 16 validation materials: every fifth of the 80 MERL training materials in
    name order (``benchmarks/validation.txt``)."""
    return VALIDATION_LIST.read_text().split()


class Library:
    """Proxy tables at the cells every table measures.

    Attributes
    ----------
    names : list of str
    cells : int64 ``(P,)`` flat MERL indices
    values : float32 ``(M, P, 3)``, 1/sr
    """

    def __init__(self, names, cells, values):
        self.names = list(names)
        self.cells = cells
        self.values = values
        th, td, pd = np.meshgrid(*grid_angles(), indexing="ij")
        self.cos_i = np.clip(cos_theta_i(th, td, pd).reshape(N_CELLS)[cells], 0, None).astype(np.float32)

    def index(self, name: str) -> int:
        return self.names.index(name)

    def table(self, name: str) -> np.ndarray:
        """Dense float64 ``(90, 90, 180, 3)`` with NaN off ``cells``."""
        out = np.full((N_CELLS, 3), np.nan)
        out[self.cells] = self.values[self.index(name)]
        return out.reshape(GRID_SHAPE + (3,))

    def log_rmse(self, name: str, pred_flat: np.ndarray) -> float:
        """:func:`brdfkit.evaluation.metrics.brdf_log_rmse` on ``cells`` (pred ``(P, 3)``)."""
        c = self.cos_i[:, None].astype(np.float64)
        ref = self.values[self.index(name)].astype(np.float64)
        return float(np.sqrt(np.mean((np.log1p(np.asarray(pred_flat, np.float64) * c)
                                      - np.log1p(ref * c)) ** 2)))


def load_library(proxies: str | os.PathLike, exclude=()) -> Library:
    """Read ``proxies/merl/*.binary`` and ``proxies/rgl/*.binary`` (names prefixed
    ``rgl:``), skipping ``exclude``; cached in ``proxies/study-cache.npz``."""
    proxies = pathlib.Path(proxies)
    cache = proxies / "study-cache.npz"
    exclude = set(exclude)
    if cache.exists():
        z = np.load(cache, allow_pickle=False)
        names = [str(n) for n in z["names"]]
        keep = [i for i, n in enumerate(names) if n not in exclude]
        return Library([names[i] for i in keep], z["cells"], z["values"][keep])
    files = sorted((proxies / "merl").glob("*.binary")) + sorted((proxies / "rgl").glob("*.binary"))
    names, tables = [], []
    for f in files:
        name = ("rgl:" if f.parent.name == "rgl" else "") + f.stem
        if name in exclude or f.stem in set(test_materials()):
            continue
        names.append(name)
        tables.append(read_merl(f).reshape(N_CELLS, 3).astype(np.float32))
    measured = np.all([np.isfinite(t).all(axis=1) for t in tables], axis=0)
    cells = np.flatnonzero(measured)
    values = np.stack([t[cells] for t in tables])
    np.savez(cache, names=np.array(names), cells=cells, values=values)
    return Library(names, cells, values)


def record_progress(recs: list, done: int, total: int, name: str, t0: float, json_path=None) -> None:
    """After a material: its progress line (``t0`` the run's ``time.time()`` at its
    start), and the records so far written to ``json_path`` when given, so that a run
    stopped early keeps what it measured."""
    print(f"[{done}/{total}] {name} {time.time() - t0:.0f} s", flush=True)
    if json_path:
        pathlib.Path(json_path).write_text(json.dumps(recs))
