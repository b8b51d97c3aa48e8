"""The route matrix, compression at every size: every shipped built-in x every kind it
offers x every size other than the kind's default, through the CLI and real files:
``encode --no-refine`` -> ``.emb`` -> ``decode`` -> ``.binary`` -> ``metrics`` against the
material's own table, with a floor on the PSNR (``helpers_routes.floor``).

Unrefined: the projection, or the encoder's pass; the refinement is the same code at
every size, and is taken at the default size (``tests/test_routes_encode.py``, which also
takes the batch and the other commands). The parameters come from the registries
(``helpers_routes``): a new built-in, kind, size or residual member is covered without
an edit here. Apart from the default size's file, so that the suite's two workers each
take one of these two long files."""

from __future__ import annotations

import pytest

from helpers_routes import encode_routes, module_routes
from helpers_view import shipped_models  # noqa: F401  (a fixture)

# The matrix takes minutes in all: CI runs it (the suite), `-m "not slow"` leaves it out.
pytestmark = [pytest.mark.usefixtures("shipped_models"), pytest.mark.slow]


routes = module_routes("sizes")


@pytest.mark.parametrize("model, kind, size, default", encode_routes(at_default=False))
def test_encode_decode_metrics(routes, capsys, model, kind, size, default):
    """encode -> decode -> metrics at one size, on a material that changes with the size."""
    routes.route(capsys, model, kind, size, default)
