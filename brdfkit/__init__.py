"""brdfkit: measured BRDFs and hypernetwork neural BRDFs.

Follows Gokbudak, Sztrajman, Zhou, Chung and Oztireli, "Hypernetworks for Generalizable
BRDF Representation", ECCV 2024. The public API is imported lazily: ``import brdfkit``
loads neither torch nor mitsuba; each name pulls in only the module that defines it.

Data flows one way: ``errors`` / ``atomic`` / ``geometry`` / ``device`` (the ground floor)
-> I/O (``merl``, ``samples``, ``embedding``, ``materials``, ``tensorfile``) -> ``mapping``
-> ``model`` -> methods and jobs (``methods``, ``training``, ``render``, ``bench``) -> ``cli``.
"""

from __future__ import annotations

import importlib

__version__ = "0.1.0"

# public name -> defining module
_API = {
    "read_merl": "brdfkit.merl",
    "write_merl": "brdfkit.merl",
    "BrdfkitError": "brdfkit.errors",
    "InputError": "brdfkit.errors",
    "FormatError": "brdfkit.errors",
    "SampleSet": "brdfkit.samples",
    "read_samples": "brdfkit.samples",
    "write_samples": "brdfkit.samples",
    "draw_samples": "brdfkit.samples",
    "measure_samples": "brdfkit.samples",
    "DirectionSet": "brdfkit.directions",
    "read_directions": "brdfkit.directions",
    "write_directions": "brdfkit.directions",
    "plan_directions": "brdfkit.planning",
    "to_mapped": "brdfkit.mapping",
    "from_mapped": "brdfkit.mapping",
    "median_reference": "brdfkit.mapping",
    "load_model": "brdfkit.api",
    "encode": "brdfkit.api",
    "decode": "brdfkit.api",
    "interpolate": "brdfkit.api",
    "fit": "brdfkit.api",
    "sparse": "brdfkit.api",
    "Embedding": "brdfkit.embedding",
    "read_embedding": "brdfkit.embedding",
    "write_embedding": "brdfkit.embedding",
    "set_torch_threads": "brdfkit.threads",
}

__all__ = sorted(_API) + ["geometry", "synthetic", "__version__"]


def __getattr__(name):
    if name in _API:
        value = getattr(importlib.import_module(_API[name]), name)
        globals()[name] = value
        return value
    if name in ("geometry", "synthetic", "mapping", "merl", "samples"):
        return importlib.import_module(f"brdfkit.{name}")
    raise AttributeError(f"module 'brdfkit' has no attribute {name!r}")


def __dir__():
    return __all__
