# Stub of brdfkit.render (brdfkit/render/__init__.py), whose TableBRDF loads lazily;
# tests/test_stubs.py checks that it names what the package serves.
import numpy

from brdfkit.render.renderable import TableBRDF as TableBRDF

__all__: list[str]

def render(brdf, scene=None, env=None, progress=None) -> numpy.ndarray: ...
