"""The ``__init__.pyi`` stubs beside the packages that load their names lazily: each
stubbed name imports and is the object its stub says, and every name a package serves
lazily is in its stub (issue 27 item 5)."""

from __future__ import annotations

import ast
import importlib
import pathlib

import pytest

import brdfkit

ROOT = pathlib.Path(brdfkit.__file__).parent


def _lazy_packages():
    """Packages whose ``__init__.py`` serves names through ``lazy_attributes``."""
    out = []
    for init in sorted(ROOT.rglob("__init__.py")):
        if "lazy_attributes(__name__" in init.read_text():
            rel = init.parent.relative_to(ROOT.parent)
            out.append(".".join(rel.parts))
    return out


def _stub_names(package: str) -> dict:
    """``{name: (module, attribute)}`` of the package's stub (``from M import a as a``)."""
    path = ROOT.parent.joinpath(*package.split("."), "__init__.pyi")
    names = {}
    for node in ast.parse(path.read_text()).body:
        if isinstance(node, ast.ImportFrom):
            for a in node.names:
                names[a.asname or a.name] = (node.module, a.name)
        elif isinstance(node, ast.FunctionDef):
            names[node.name] = (package, node.name)
        elif isinstance(node, ast.AnnAssign) and node.target.id != "__all__":
            names[node.target.id] = (package, node.target.id)
    return names


def test_every_lazy_package_has_a_stub():
    packages = _lazy_packages()
    assert {"brdfkit", "brdfkit.hypernet", "brdfkit.render"} <= set(packages)
    for package in packages:
        assert ROOT.parent.joinpath(*package.split("."), "__init__.pyi").is_file(), package


@pytest.mark.parametrize("package", _lazy_packages())
def test_each_stubbed_name_imports_as_the_stub_says(package):
    mod = importlib.import_module(package)
    for name, (where, attr) in _stub_names(package).items():
        got = getattr(mod, name)
        source = importlib.import_module(where)
        expected = getattr(source, attr) if hasattr(source, attr) else importlib.import_module(f"{where}.{attr}")
        assert got is expected, f"{package}.{name}"


@pytest.mark.parametrize("package", _lazy_packages())
def test_the_stub_names_every_public_name(package):
    mod = importlib.import_module(package)
    stubbed = set(_stub_names(package))
    assert set(mod.__all__) <= stubbed, sorted(set(mod.__all__) - stubbed)
    assert set(dir(mod)) <= stubbed, sorted(set(dir(mod)) - stubbed)
