"""The route matrix's parameters and inputs (``tests/test_routes_*.py``).

Every parameter is generated from the registries, never listed by hand: the built-ins
the package ships and what each one serves (kinds and their sizes, sparse methods), as
the one answer to that question gives it (:func:`brdfkit.methods.service.serves`, which
``brdfkit models`` and the commands ask too), the methods (``METHODS``) and the recipes
of ``brdfkit fit`` (``FITTERS``). A new built-in, kind, size, method or recipe is a new route of the
matrix without an edit here; a recipe without a tiny setting below fails its route with a
message saying so.

The inputs are the materials the package ships (``brdfkit material``), written once per
run for both pytest-xdist workers; a module's encodes, decodes and scores are made once
and shared by its tests (:class:`Routes`).
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from pathlib import Path

import pytest

from conftest import run_cli

MATERIALS = ("teflon", "chrome-steel", "blue-metallic-paint", "violet-rubber")
"""What ``brdfkit material`` can write without ``../shared`` (the package's own NBRDF fits)."""

RESOLUTION = "16"
"""Render size of the matrix's scores (pixels): each route is checked to run and to give a
table that renders like its truth, not measured."""

FLOOR_DB = 30.0
"""PSNR (dB, the reference scene) that every decoded table of a route reaches against its
truth from :data:`FULL_SIZE` numbers up."""

FULL_SIZE = 12
"""Below this many numbers a basis of one to three components a channel is what it is:
unrefined, teflon's projection onto one component renders 19.0 dB, chrome-steel's onto
two 29.2 and onto three 29.6 (16 px, merl80-l40, 2026-12-01)."""

LOW_SIZE_FLOOR_DB = 18.0
"""The floor below :data:`FULL_SIZE` numbers; a black or wrong table renders far under it."""


def shipped():
    """``[(name, kinds {kind: (sizes, default size)}, methods (names served))]`` of the
    built-ins the package ships, as :func:`brdfkit.methods.service.installed_services`
    says they serve (``brdfkit models``; empty without them)."""
    from brdfkit.methods.service import installed_services

    return [(s.bundle, {k: (sizes, s.default_sizes[k]) for k, sizes in s.kinds.items()}, s.methods)
            for s in installed_services()]


def encode_routes(at_default: bool):
    """``(built-in, kind, size, default size)`` of every shipped built-in's kinds: at each
    kind's default size (``at_default``), or at each of its other sizes, largest first (a
    compact basis keeps the most components restored, and a smaller size takes their
    leading rows: restored once per built-in instead of once per size)."""
    return [pytest.param(name, kind, size, default, id=f"{name}-{kind}-{size}")
            for name, kinds, _ in shipped() for kind, (sizes, default) in kinds.items()
            for size in sorted(sizes, reverse=True) if (size == default) == at_default]


def kind_routes():
    """``(built-in, kind, default size)`` of every kind of every shipped built-in."""
    return [pytest.param(name, kind, default, id=f"{name}-{kind}")
            for name, kinds, _ in shipped() for kind, (_, default) in kinds.items()]


def model_routes():
    """The name of every shipped built-in."""
    return [pytest.param(name, id=name) for name, _, _ in shipped()]


def method_routes():
    """``(built-in, method, served)`` of every sparse method that takes a model against
    every built-in, and ``(None, method, True)`` of each that takes none."""
    from brdfkit.methods import METHODS

    free = [pytest.param(None, m, True, id=m) for m in METHODS if not METHODS[m].needs_model]
    return free + [pytest.param(name, method, method in methods, id=f"{name}-{method}")
                   for name, _, methods in shipped() for method in METHODS if METHODS[method].needs_model]


def floor(size: int) -> float:
    """The PSNR floor of a route at ``size`` numbers."""
    return FLOOR_DB if size >= FULL_SIZE else LOW_SIZE_FLOOR_DB


def materials(tmp_path_factory) -> Path:
    """A folder of the shipped materials as MERL tables, ``<name>.binary``, written once
    per run (both workers share it)."""
    from brdfkit.materials.nbrdf_networks import write_material

    base = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        base = base.parent
    folder = base / "route-materials"
    if not all((folder / f"{m}.binary").is_file() for m in MATERIALS):
        part = Path(tempfile.mkdtemp(prefix=".route-materials-", dir=base))
        for m in MATERIALS:
            write_material(m, part / f"{m}.binary")
        try:
            os.rename(part, folder)
        except OSError:  # the other worker wrote them first: the same tables
            shutil.rmtree(part, ignore_errors=True)
    return folder


REFINED = ("--steps", "2")
"""The refinement of the default size's encodes (Levenberg-Marquardt iterations or Adam
steps): the refinement's code runs, at a fraction of the default budget; the route and
the bytes, not the score, are what is checked."""


def route_material(size: int) -> str:
    """The material of a size's route: it changes with the size, so that every shipped
    material is taken."""
    return MATERIALS[(size // 3) % len(MATERIALS)]


def module_routes(folder: str):
    """A module-scoped fixture ``routes``: the module's :class:`Routes` on the shipped
    materials, its files in a temporary folder named ``folder``."""

    @pytest.fixture(scope="module")
    def routes(tmp_path_factory):
        return Routes(materials(tmp_path_factory), tmp_path_factory.mktemp(folder))

    return routes


class Routes:
    """A module's files, each made once through the CLI and kept by what made it: an
    encode alone (``model, kind, size, material``: refined at the default size,
    :data:`REFINED`, else not), a decode of an ``.emb``, a score of a table against its
    truth. The encode of a route is the one the batch, the blend and the other commands
    take: each test redoing it was most of the matrix's time."""

    def __init__(self, tables, folder):
        self.tables, self.folder = tables, folder
        self._embs, self._decoded, self._scores = {}, {}, {}

    def encode(self, capsys, model, kind, size, default, material):
        """``brdfkit encode TABLE -m MODEL --kind KIND --size SIZE OPTIONS``, alone."""
        options = REFINED if size == default else ("--no-refine",)
        key = (model, kind, size, material)
        if key not in self._embs:
            out = self.folder / f"{model}-{kind}-{size}"
            ok(capsys, ["encode", self.tables / f"{material}.binary", "-m", model, "--kind", kind, "--size", size,
                        "-o", out, *options])
            self._embs[key] = out / f"{material}.emb"
        return self._embs[key]

    def decode(self, capsys, emb):
        """``brdfkit decode EMB -o TABLE``: the table."""
        if emb not in self._decoded:
            out = emb.with_name(f"{emb.stem}-decoded.binary")
            ok(capsys, ["decode", emb, "-o", out])
            self._decoded[emb] = out
        return self._decoded[emb]

    def score(self, capsys, material, table):
        """``brdfkit metrics --ref TRUTH TABLE``'s PSNR."""
        if table not in self._scores:
            self._scores[table] = psnr(capsys, self.tables / f"{material}.binary", table)
        return self._scores[table]

    def route(self, capsys, model, kind, size, default):
        """encode -> decode -> metrics of a size's route, on its material, checked: the
        embedding, the material and the score."""
        from brdfkit.io.embedding import read_embedding

        name = route_material(size)
        emb = self.encode(capsys, model, kind, size, default, name)
        got = read_embedding(emb)
        assert (got.kind, got.size) == (kind, size)
        assert bool(got.refinement) == (size == default), f"{model} {kind} {size}: refined {got.refinement}"
        score = self.score(capsys, name, self.decode(capsys, emb))
        assert score >= floor(size), f"{model} {kind} {size} on {name}: {score:.2f} dB"
        return emb


def psnr(capsys, ref, pred, *extra) -> float:
    """``brdfkit metrics --ref REF PRED --json``'s PSNR at :data:`RESOLUTION`."""
    code, out, err = run_cli(capsys, ["metrics", "--ref", ref, pred, "--json", "--resolution", RESOLUTION,
                                      "--quiet", *extra])
    assert code == 0, err
    return json.loads(out)["psnr"]


def ok(capsys, args) -> str:
    """Run ``brdfkit ARGS`` in-process; its stderr, after checking it exited 0."""
    code, _, err = run_cli(capsys, args)
    assert code == 0, f"brdfkit {' '.join(map(str, args))}: exit {code}: {err}"
    return err
