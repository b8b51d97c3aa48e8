"""Fuzzing of brdfkit's file parsers: only brdfkit's own one-line errors may escape.

Used by ``tests/test_fuzz.py`` (a short run in the suite) and
``benchmarks/fuzz_parsers.py`` (minutes per parser); needs hypothesis (the ``test``
extra), so ``import brdfkit`` never imports it. Each parser gets random bytes and
mutations of a valid file of its format: truncation, byte changes (half of them in the
first kilobytes, where the headers are), and for safetensors files a rewritten JSON
header (dtypes, shapes, offsets, metadata and the model config replaced by random JSON),
re-framed with a correct length so that the parser gets past the framing.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import json
import os
import shutil
import sys
import tempfile
import time
import warnings
from typing import Callable

import numpy as np
from hypothesis import strategies as st

from brdfkit.errors import BrdfkitError

JSON_SCALARS = (st.none() | st.booleans() | st.integers(-2**64, 2**64) | st.floats()
                | st.text(max_size=12) | st.sampled_from([0, 1, -1, 2**31, 7, 90, "F32", "F16", "I64", "BOOL",
                                                          "U8", "1", "brdfkit-model", ""]))
JSON_VALUES = st.recursive(JSON_SCALARS, lambda c: st.lists(c, max_size=4) | st.dictionaries(
    st.text(max_size=8), c, max_size=4), max_leaves=8)


@dataclasses.dataclass(frozen=True)
class Parser:
    """A parser under test: ``read(path)``, the file suffix it expects, and a function
    returning the bytes of a valid file (built once per process)."""

    name: str
    read: Callable
    suffix: str
    seed: Callable[[], bytes]
    safetensors: bool = False


# --- valid seeds ---------------------------------------------------------------------------

def _seed_folder() -> str:
    """A new temporary folder for one seed file; :func:`_take` removes it."""
    return tempfile.mkdtemp(prefix="brdfkit-fuzz-seeds-")


def _take(path) -> bytes:
    """The bytes of a seed file, removing the file and its folder: a test run used to leave
    34 MB of seeds in the temporary folder."""
    try:
        with open(path, "rb") as f:
            return f.read()
    finally:
        shutil.rmtree(os.path.dirname(path), ignore_errors=True)


# The seed model: a hypernetwork small enough that a network file is a few kilobytes (the
# tiny configuration of the test suite), untrained.
SEED_MODEL_CONFIG = dict(latent_dim=7, encoder_hidden=(16, 16), hypo_hidden=8, hypo_layers=2,
                         decoder_hidden=16, decoder_layers=1)


@functools.lru_cache(maxsize=None)
def model_seed() -> bytes:
    import torch

    from brdfkit.materials import synthetic
    from brdfkit.hypernet.network import HyperBRDF, HyperConfig
    from brdfkit.hypernet.network_file import save_network

    path = os.path.join(_seed_folder(), "model.safetensors")
    torch.manual_seed(0)
    save_network(path, HyperBRDF(HyperConfig(**SEED_MODEL_CONFIG)), synthetic.table(synthetic.STIFF[2]),
               {"materials": ["stiff-white"], "steps": 0})
    return _take(path)


@functools.lru_cache(maxsize=None)
def embedding_seed() -> bytes:
    from brdfkit.io.embedding import Embedding, write_embedding

    path = os.path.join(_seed_folder(), "a.emb")
    write_embedding(path, Embedding(np.linspace(-1, 1, 7), "hypernet", "ab" * 32, "mat.binary", 40))
    return _take(path)


@functools.lru_cache(maxsize=None)
def reference_seed() -> bytes:
    from brdfkit.geometry import TABLE_SHAPE
    from brdfkit.hypernet.mapping import save_reference

    path = os.path.join(_seed_folder(), "ref.safetensors")
    table = np.full(TABLE_SHAPE, 0.5, dtype=np.float32)
    save_reference(path, table, ["a", "b"])
    return _take(path)


@functools.lru_cache(maxsize=None)
def ipca_seed() -> bytes:
    from brdfkit.basis import PcaBasis, save_basis

    path = os.path.join(_seed_folder(), "basis.safetensors")
    p = 64
    rng = np.random.default_rng(0)
    save_basis(path, PcaBasis(np.arange(1000, 1000 + 3 * p, 3, dtype=np.int64), rng.random(p, dtype=np.float32),
                              rng.random(p, dtype=np.float32), rng.random((2, p), dtype=np.float32),
                              np.array([1.0, 0.5], np.float32), ["a", "b"]))
    return _take(path)


@functools.lru_cache(maxsize=None)
def csv_seed() -> bytes:
    return (b"# a comment\ntheta_h,theta_d,phi_d,r,g,b\n0.1,0.2,0.3,0.5,0.25,0.125\n"
            b"0.3,0.4,1.0,1e3,2e-4,0\n\n0.5,1.2,2.5,0.01,0.02,0.03\n")


@functools.lru_cache(maxsize=None)
def merl_seed() -> bytes:
    # the header and the first cells of a table: read_merl checks the size first, so a
    # full-size payload only matters for the NaN/Inf scan (test_samples.py fuzzes that)
    stored = np.linspace(-1.0, 3.0, 300)
    return np.array([90, 90, 180], "<i4").tobytes() + stored.astype("<f8").tobytes()


@functools.lru_cache(maxsize=None)
def bsdf_seed() -> bytes:
    # a small RGL .bsdf (3 incident elevations, an 8 x 8 sample grid): 4 kB
    from brdfkit.geometry import TABLE_SHAPE
    from brdfkit.io.rgl_bsdf import FitSettings, write_bsdf

    path = os.path.join(_seed_folder(), "a.bsdf")
    write_bsdf(path, np.full(TABLE_SHAPE, 0.1), FitSettings(resolution=8, theta_i=3, ndf=16, vndf=(4, 8)))
    return _take(path)


@functools.lru_cache(maxsize=None)
def brdf_seed() -> bytes:
    # a pbrt-v2 / Cornell .brdf file: 31 wavelengths, three samples
    values = " ".join(f"{0.01 * (k % 7) + 0.001:.6f}" for k in range(31))
    rows = "".join(f"{ti} 0 {to} {po} {values}\n" for ti, to, po in ((0.5, 0.3, 3.1), (1.2, 1.0, -0.5), (0.1, 0, 0)))
    return ("# num wls\n31\n\n# wls\n" + " ".join(str(w) for w in range(400, 701, 10)) + "\n\n" + rows).encode()


@functools.lru_cache(maxsize=None)
def measurement_csv_seed() -> bytes:
    # a measurement CSV: angles in degrees, one column per wavelength
    head = "theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg," + ",".join(f"{w}nm" for w in range(400, 701, 20))
    rows = ["30,0,30,180," + ",".join(["0.2"] * 16), "60,0,10,45," + ",".join(["1e-3"] * 16)]
    return ("# a comment\n" + head + "\n" + "\n".join(rows) + "\n").encode()


# The parsers, each imported on its first call (importing this module imports no parser).

def read_merl(path):
    from brdfkit.io.merl import read_merl

    return read_merl(path)


def read_bsdf(path):
    from brdfkit.io.rgl_bsdf import read_bsdf

    return read_bsdf(path)


def read_samples(path):
    from brdfkit.io.samples import read_samples

    return read_samples(path)


def read_pbrt_brdf(path):
    from brdfkit.io.pbrt_brdf import read_pbrt_brdf

    return read_pbrt_brdf(path)


def read_measurement_csv(path):
    from brdfkit.io.sample_files import read_measurement_csv

    return read_measurement_csv(path)


def read_embedding(path):
    from brdfkit.io.embedding import read_embedding

    return read_embedding(path)


def load_network(path):
    from brdfkit.hypernet.network_file import load_network

    return load_network(path, "cpu")


def load_reference(path):
    from brdfkit.hypernet.mapping import load_reference

    return load_reference(path)


def load_basis(path):
    from brdfkit.basis import load_basis

    return load_basis(path)


PARSERS = {p.name: p for p in (
    Parser("read_merl", read_merl, ".binary", merl_seed),
    Parser("read_bsdf", read_bsdf, ".bsdf", bsdf_seed),
    Parser("read_samples", read_samples, ".csv", csv_seed),
    Parser("read_pbrt_brdf", read_pbrt_brdf, ".brdf", brdf_seed),
    Parser("read_measurement_csv", read_measurement_csv, ".csv", measurement_csv_seed),
    Parser("read_embedding", read_embedding, ".emb", embedding_seed),
    Parser("load_network", load_network, ".safetensors", model_seed, safetensors=True),
    Parser("load_reference", load_reference, ".safetensors", reference_seed, safetensors=True),
    Parser("load_basis", load_basis, ".safetensors", ipca_seed, safetensors=True),
)}


def add_parser(parser: Parser) -> None:
    """Register another parser."""
    PARSERS[parser.name] = parser


@functools.lru_cache(maxsize=None)
def exr_seed() -> bytes:
    from brdfkit.render.image import write_exr

    path = os.path.join(_seed_folder(), "img.exr")
    write_exr(path, np.linspace(0, 2, 4 * 5 * 3, dtype=np.float32).reshape(4, 5, 3))
    return _take(path)


def read_exr(path):
    from brdfkit.render.image import read_exr

    return read_exr(path)


add_parser(Parser("read_exr", read_exr, ".exr", exr_seed))


# --- mutations -----------------------------------------------------------------------------

def _edit_bytes(data, seed: bytes) -> bytes:
    b = bytearray(seed)
    for _ in range(data.draw(st.integers(1, 8), label="edits")):
        if not b:
            break
        limit = len(b) - 1 if data.draw(st.booleans(), label="anywhere") else min(len(b) - 1, 4096)
        i = data.draw(st.integers(0, limit), label="at")
        kind = data.draw(st.sampled_from(["set", "insert", "delete"]), label="kind")
        if kind == "set":
            b[i] = data.draw(st.integers(0, 255), label="byte")
        elif kind == "insert":
            b[i:i] = data.draw(st.binary(min_size=1, max_size=16), label="bytes")
        else:
            del b[i:i + data.draw(st.integers(1, 16), label="n")]
    return bytes(b)


def _edit_safetensors_header(data, seed: bytes) -> bytes:
    n = int.from_bytes(seed[:8], "little")
    header = json.loads(seed[8:8 + n])
    body = seed[8 + n:]
    for _ in range(data.draw(st.integers(1, 4), label="header edits")):
        # half the edits go to the metadata (format, version, config, names), where the
        # parsers' own checks are; the rest to a tensor entry or a new key
        key = "__metadata__" if "__metadata__" in header and data.draw(st.booleans(), label="meta") else \
            data.draw(st.sampled_from(sorted(header) + ["<new>"]), label="key")
        if key == "<new>":
            header[data.draw(st.text(max_size=10), label="new key")] = data.draw(JSON_VALUES, label="new value")
            continue
        entry = header[key]
        if key == "__metadata__":
            field = data.draw(st.sampled_from(sorted(entry) + ["<drop>"]), label="meta field")
            if field == "<drop>":
                entry.pop(data.draw(st.sampled_from(sorted(entry) or ["x"]), label="drop"), None)
            elif field in ("config", "meta", "materials") and data.draw(st.booleans(), label="inner"):
                try:
                    inner = json.loads(entry[field])
                except ValueError:
                    inner = {}
                if isinstance(inner, dict) and inner and data.draw(st.booleans(), label="one value"):
                    inner[data.draw(st.sampled_from(sorted(inner)), label="inner key")] = \
                        data.draw(JSON_VALUES, label="inner value")
                else:
                    inner = data.draw(JSON_VALUES, label="inner doc")
                entry[field] = json.dumps(inner)
            else:
                entry[field] = data.draw(st.text(max_size=20) | JSON_VALUES.map(json.dumps), label="meta value")
        elif isinstance(entry, dict):
            field = data.draw(st.sampled_from(["dtype", "shape", "data_offsets", "<drop>", "<whole>"]),
                              label="tensor field")
            if field == "<drop>":
                header.pop(key)
            elif field == "<whole>":
                header[key] = data.draw(JSON_VALUES, label="tensor entry")
            elif field == "shape":
                entry[field] = data.draw(st.lists(st.integers(-2, 2**40) | st.sampled_from([0, 1, 3, 90, 180]),
                                                  max_size=5) | JSON_VALUES, label="shape")
            elif field == "data_offsets":
                lim = len(body) + 16
                entry[field] = data.draw(st.lists(st.integers(-1, lim), min_size=2, max_size=2) | JSON_VALUES,
                                         label="offsets")
            else:
                entry[field] = data.draw(st.sampled_from(["F32", "F16", "BF16", "F64", "I64", "I32", "I16", "I8",
                                                          "U8", "U16", "U32", "U64", "BOOL", "F8_E4M3", "F8_E5M2"])
                                         | JSON_VALUES, label="dtype")
        else:
            header[key] = data.draw(JSON_VALUES, label="value")
    raw = json.dumps(header).encode()
    raw += b" " * (-len(raw) % 8)
    return len(raw).to_bytes(8, "little") + raw + body


def draw_input(data, parser: Parser) -> bytes:
    """One fuzz input for ``parser`` (hypothesis ``data`` object)."""
    kinds = ["random", "truncate", "edit"] + (["header"] * 3 if parser.safetensors else [])
    kind = data.draw(st.sampled_from(kinds), label="kind")
    if kind == "random":
        return data.draw(st.binary(max_size=600), label="random bytes")
    seed = parser.seed()
    if kind == "truncate":
        return seed[:data.draw(st.integers(0, len(seed) - 1), label="cut")]
    if kind == "edit":
        return _edit_bytes(data, seed)
    return _edit_safetensors_header(data, seed)


@contextlib.contextmanager
def _captured_output():
    """What is written to file descriptors 1 and 2 (C libraries included) and the
    warnings Python would show, while the block runs: ``(lines, warnings)``."""
    lines: list[str] = []
    caught: list = []
    sys.stdout.flush()
    sys.stderr.flush()
    saved = (os.dup(1), os.dup(2))
    with tempfile.TemporaryFile() as tmp, warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        os.dup2(tmp.fileno(), 1)
        os.dup2(tmp.fileno(), 2)
        try:
            yield lines, caught
        finally:
            for fd, old in zip((1, 2), saved):
                os.dup2(old, fd)
                os.close(old)
            tmp.seek(0)
            lines.extend(ln for ln in tmp.read().decode("utf-8", "replace").splitlines() if ln.strip())
            # the categories a user would see (DeprecationWarning and kin are hidden)
            caught.extend(x for x in w if not issubclass(x.category, (DeprecationWarning, PendingDeprecationWarning,
                                                                      ImportWarning)))


def check_parser(parser: Parser, raw: bytes, folder: str, slow_s: float = 30.0) -> tuple[bool, float]:
    """Write ``raw`` and parse it: a result or a one-line :class:`BrdfkitError` naming
    the file, and nothing else printed; anything else (another exception, a multi-line
    message, output from a C library or a warning, a parse slower than ``slow_s``)
    fails. Returns ``(accepted, seconds)``."""
    path = os.path.join(folder, "fuzz" + parser.suffix)
    with open(path, "wb") as f:
        f.write(raw)
    accepted = True
    t0 = time.perf_counter()
    with _captured_output() as (printed, caught):
        try:
            parser.read(path)
        except BrdfkitError as e:
            accepted = False
            msg = str(e)
            assert msg.isprintable(), repr(msg)  # one line, no terminal escapes
            assert path in msg, msg
    elapsed = time.perf_counter() - t0
    assert not printed, f"{parser.name} printed {printed[:3]}"
    assert not caught, f"{parser.name} warned {[str(x.message) for x in caught[:3]]}"
    assert elapsed < slow_s, f"{parser.name} took {elapsed:.1f} s on a {len(raw)}-byte input"
    return accepted, elapsed
