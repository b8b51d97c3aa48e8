"""The package's layout: the bars DEVELOPERS.md sets (at most 6 top-level modules, functions
of at most 100 lines, files of at most 450), no private name imported across packages,
and the basis and the hypernetwork independent of each other: importing, encoding and
decoding with one loads nothing of the other."""

from __future__ import annotations

import ast
import os
import subprocess
import sys

import pytest

ROOT = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "brdfkit")


def _modules():
    for folder, _, files in os.walk(ROOT):
        for f in sorted(files):
            if f.endswith(".py"):
                path = os.path.join(folder, f)
                with open(path, encoding="utf-8") as fh:
                    yield os.path.relpath(path, os.path.dirname(ROOT)), fh.read()


def _package(rel: str) -> str:
    """``brdfkit/basis/model.py`` -> ``basis``; a top-level module is its own."""
    parts = rel.split(os.sep)
    return parts[1] if len(parts) > 2 else parts[1][:-3]


def _imports(tree):
    """``(module, names)`` of every ``from brdfkit... import`` and ``import brdfkit...``."""
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("brdfkit"):
            yield node.module, [a.name for a in node.names]
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name.startswith("brdfkit"):
                    yield a.name, []


def _target(node):
    """The brdfkit packages or top-level modules an import statement names."""
    from brdfkit import LAYERS

    known = {p for layer in LAYERS for p in layer}
    if isinstance(node, ast.ImportFrom) and node.module == "brdfkit":
        return [a.name if a.name in known else "" for a in node.names]
    if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("brdfkit."):
        return [node.module.split(".")[1]]
    if isinstance(node, ast.Import):
        return [a.name.split(".")[1] for a in node.names if a.name.startswith("brdfkit.")]
    return []


def test_the_layer_table_names_every_package_and_top_level_module():
    """``brdfkit.LAYERS`` holds every package and top-level module once, and the table of
    ``brdfkit/__init__.py``'s docstring shows the same layers in the same order."""
    import re

    import brdfkit

    names = [p for layer in brdfkit.LAYERS for p in layer]
    present = {f[:-3] if f.endswith(".py") else f for f in os.listdir(ROOT)
               if (f.endswith(".py") and f != "__init__.py")
               or os.path.isfile(os.path.join(ROOT, f, "__init__.py"))}
    assert sorted(names) == sorted(present) and len(names) == len(set(names))
    rows, number = [], None
    for line in brdfkit.__doc__.splitlines():
        m = re.match(r"(\d+)\s{2,}(.*)", line)
        if m:
            number = int(m.group(1))
            rows.append((number, []))
        if number is not None and re.match(r"(\d+)?\s+``", line):
            rows[-1][1].extend(re.findall(r"``(\w+)/?``", line.split("  ")[0] + line[5:45]))
    assert [tuple(names) for _, names in rows] == [tuple(layer) for layer in brdfkit.LAYERS], rows


def test_data_flows_one_way():
    """No module imports from a layer below its own (``brdfkit.LAYERS``), inside functions
    included: no library module imports ``api``, ``files`` or ``cli`` from below them."""
    from brdfkit import LAYERS

    layer = {p: i for i, ps in enumerate(LAYERS) for p in ps}
    upward = []
    for rel, src in _modules():
        here = _package(rel)
        if here == "__init__":
            continue
        for node in ast.walk(ast.parse(src)):
            for there in _target(node):
                if there and layer[there] > layer[here]:
                    upward.append((rel, here, there))
    assert not upward, upward


def _module_name(rel: str) -> str:
    """``brdfkit/models/parts.py`` -> ``brdfkit.models.parts``; a package's
    ``__init__.py`` is the package."""
    name = rel[:-3].replace(os.sep, ".")
    return name[:-len(".__init__")] if name.endswith(".__init__") else name


def test_no_two_modules_import_each_other():
    """No module imports a module that imports it, inside functions included: what a model
    serves is answered in one place (``brdfkit.methods.service``), and ``models/builtin.py``
    and ``models/parts.py`` no longer send a question back and forth."""
    trees = {_module_name(rel): ast.parse(src) for rel, src in _modules()}
    imports = {}
    for name, tree in trees.items():
        found = set()
        for module, names in _imports(tree):
            found |= {f"{module}.{n}" if f"{module}.{n}" in trees else module for n in names or [""]}
        imports[name] = {m for m in found if m in trees and m != name}
    pairs = sorted({tuple(sorted((a, b))) for a in imports for b in imports[a] if a in imports[b]})
    assert not pairs, pairs


def test_the_residual_imports_the_basis_and_not_the_hypernetwork():
    found = [(rel, module) for rel, src in _modules() if _package(rel) == "residual"
             for module, _ in _imports(ast.parse(src)) if module.startswith("brdfkit.hypernet")]
    assert not found, found


def test_at_most_six_top_level_modules():
    top = [f for f in os.listdir(ROOT) if f.endswith(".py") and f != "__init__.py"]
    assert len(top) <= 6, sorted(top)


def test_functions_and_files_are_short():
    long_files, long_functions = [], []
    for rel, src in _modules():
        if src.count("\n") > 450:
            long_files.append((rel, src.count("\n")))
        for node in ast.walk(ast.parse(src)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and node.end_lineno - node.lineno >= 100:
                long_functions.append((rel, node.name, node.end_lineno - node.lineno + 1))
    assert not long_files and not long_functions, (long_files, long_functions)


def test_no_private_name_crosses_a_package():
    crossing = []
    for rel, src in _modules():
        here = _package(rel)
        for module, names in _imports(ast.parse(src)):
            there = module.split(".")[1] if "." in module else ""
            crossing += [(rel, module, n) for n in names if n.startswith("_") and there != here]
            crossing += [(rel, module, "") for part in module.split(".")[1:] if part.startswith("_") and there != here]
    assert not crossing, crossing


@pytest.mark.parametrize("package, other", [("basis", "hypernet"), ("hypernet", "basis")])
def test_basis_and_hypernet_never_import_each_other(package, other):
    """Statically: no module of one names the other, inside functions included."""
    found = [(rel, module) for rel, src in _modules() if _package(rel) == package
             for module, _ in _imports(ast.parse(src)) if module.startswith(f"brdfkit.{other}")]
    assert not found, found


def _run(code: str, tmp_path) -> list:
    env = {**os.environ, "OMP_NUM_THREADS": "1", "BRDFKIT_BUILTIN_MODELS": str(tmp_path / "none")}
    out = subprocess.run([sys.executable, "-c", code + "\nimport sys\nprint(sorted(m for m in sys.modules "
                          "if m.startswith(('brdfkit.hypernet', 'brdfkit.basis'))))"],
                         capture_output=True, text=True, env=env, cwd=tmp_path, timeout=300)
    assert out.returncode == 0, out.stderr
    return eval(out.stdout.strip().splitlines()[-1])


@pytest.mark.slow
def test_importing_either_loads_nothing_of_the_other(tmp_path):
    loaded = _run("import brdfkit.basis, brdfkit.basis.coefficients, brdfkit.basis.refine_on_screen", tmp_path)
    assert loaded and not [m for m in loaded if m.startswith("brdfkit.hypernet")]
    loaded = _run("import brdfkit.hypernet, brdfkit.hypernet.refine_on_screen, brdfkit.hypernet.encoding", tmp_path)
    assert loaded and not [m for m in loaded if m.startswith("brdfkit.basis")]


@pytest.mark.slow
def test_a_basis_embedding_is_encoded_and_decoded_without_the_hypernetwork(tmp_path):
    """``encode`` and ``decode`` of a basis embedding, through the library as the command
    line calls it, load no module of the hypernetwork (and so none of its weights)."""
    loaded = _run("from brdfkit.testing.examples import lambertian_table, tiny_basis_file\n"
                  "import brdfkit\n"
                  "path = tiny_basis_file('b.safetensors')\n"
                  "emb = brdfkit.encode(lambertian_table(), path, size=6, steps=2)\n"
                  "table = brdfkit.decode(emb, path)\n"
                  "assert emb.kind == 'basis' and table.shape == (90, 90, 180, 3)", tmp_path)
    assert "brdfkit.basis.coefficients" in loaded
    assert not [m for m in loaded if m.startswith("brdfkit.hypernet")], loaded
