"""The examples in the library's docstrings run, on synthetic tables (issue 27 item 6;
colour-science's habit): every module of ``brdfkit`` whose docstrings hold ``>>>``
examples is run with :mod:`doctest`, in a temporary folder, and the public API's
functions must have examples."""

from __future__ import annotations

import doctest
import importlib
import pathlib
import pkgutil

import pytest

import brdfkit

# The public functions whose docstrings must show an example (issue 27 item 6).
MUST_SHOW = {
    "brdfkit.io.merl": ("read_merl", "write_merl"),
    "brdfkit.api": ("load_model", "encode", "decode", "sparse", "interpolate"),
    "brdfkit.render": ("render",),
    "brdfkit.evaluation.metrics": ("brdf_log_rmse", "psnr", "delta_e_2000", "ssim", "score"),
    "brdfkit.acquisition.planning": ("plan_directions",),
}


def _modules_with_examples():
    root = pathlib.Path(brdfkit.__file__).parent
    names = ["brdfkit"]
    names += [m.name for m in pkgutil.walk_packages([str(root)], "brdfkit.")]
    out = []
    for name in names:
        spec = importlib.util.find_spec(name)
        if spec is not None and spec.origin and ">>>" in pathlib.Path(spec.origin).read_text():
            out.append(name)
    return sorted(out)


def test_the_public_api_shows_examples():
    for module, names in MUST_SHOW.items():
        mod = importlib.import_module(module)
        for name in names:
            assert ">>>" in (getattr(mod, name).__doc__ or ""), f"{module}.{name} has no example"


# The modules whose examples take seconds (``api``: encodes refined on renders; ``metrics``:
# colour-science's import and Delta E): run with the slow tests.
SLOW_EXAMPLES = {"brdfkit.api", "brdfkit.evaluation.metrics"}


@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow) if n in SLOW_EXAMPLES else n
                                  for n in _modules_with_examples()])
def test_docstring_examples_run(name, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # examples write their files here
    mod = importlib.import_module(name)
    result = doctest.testmod(mod, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE, verbose=False)
    assert result.attempted > 0, name
    assert result.failed == 0, f"{result.failed} of {result.attempted} examples of {name} failed (output above)"
