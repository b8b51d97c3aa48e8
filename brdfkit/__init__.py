"""brdfkit: measured BRDFs and hypernetwork neural BRDFs.

Follows Gokbudak, Sztrajman, Zhou, Chung and Oztireli, "Hypernetworks for Generalizable
BRDF Representation", ECCV 2024. The public API is imported lazily: ``import brdfkit``
loads neither torch nor mitsuba; each name pulls in only the module that defines it
(``__init__.pyi`` lists them for IDEs and type checkers).

The package, one folder per domain; data flows down this list, never up (each package's
docstring says what it may import):

============================ ===========================================================
``errors``, ``atomic``,      what every layer shares: one-line errors, atomic outputs,
``console``, ``runtime``     messages and progress, the torch device and thread count
``geometry/``                Rusinkiewicz coordinates, the MERL grid, its lookups
``io/``                      files: MERL ``.binary``, sample and direction CSVs, ``.emb``,
                             the checked safetensors reader, folders of tables
``materials/``               materials brdfkit makes: GGX and stiff cases, the shipped
                             NBRDF networks
``models/``                  the built-in models: files, manifest, names to files
``hypernet/``                the hypernetwork: network, model files, mapping, encode,
                             decode, refinement on samples and on screen, tuning,
                             ``training/`` (loop, data, checkpoints, DDP)
``methods/``                 sparse-reconstruction methods by name (``hypernet``,
                             ``ipca``, ``nbrdf``, ``prior``)
``acquisition/``             where to measure: sampling, planning, designs, the protocol
``brdf_file``                a BRDF file of any kind, opened by one loader
``render/``                  the reference scene, quadrature, the display encoding,
                             the render-aligned error, Mitsuba 3
``evaluation/``              metrics and comparisons of files
``figures/``                 plots, comparison sheets, interpolation strips
``bench/``, ``demos/``       the benchmark; the demos
``api``                      the public functions (load_model, encode, decode, sparse, ...)
``cli/``                     the ``brdfkit`` command line, thin over the library
============================ ===========================================================

Examples
--------
>>> import brdfkit
>>> sorted(brdfkit.__all__)[:4]
['BrdfkitError', 'DirectionSet', 'Embedding', 'FormatError']
"""

from __future__ import annotations

import importlib

__version__ = "0.1.0"


def lazy_attributes(package: str, names: dict):
    """``(__getattr__, __dir__)`` for a package whose public names load on first use.

    Parameters
    ----------
    package
        The package's ``__name__``.
    names
        Public name -> the module that defines it (``"brdfkit.io.merl"``); a name that is
        itself a module maps to that module's full name with ``"module:"`` before it.

    The package keeps an ``__init__.pyi`` naming the same things for static tools
    (scikit-image's habit); ``tests/test_stubs.py`` checks that the two agree.
    """

    def __getattr__(name):
        where = names.get(name)
        if where is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        if where.startswith("module:"):
            return importlib.import_module(where[len("module:"):])
        value = getattr(importlib.import_module(where), name)
        setattr(importlib.import_module(package), name, value)
        return value

    def __dir__():
        return sorted(names)

    return __getattr__, __dir__


# public name -> defining module
_API = {
    "read_merl": "brdfkit.io.merl",
    "write_merl": "brdfkit.io.merl",
    "BrdfkitError": "brdfkit.errors",
    "InputError": "brdfkit.errors",
    "FormatError": "brdfkit.errors",
    "SampleSet": "brdfkit.io.samples",
    "read_samples": "brdfkit.io.samples",
    "write_samples": "brdfkit.io.samples",
    "draw_samples": "brdfkit.acquisition.sampling",
    "measure_samples": "brdfkit.acquisition.sampling",
    "DirectionSet": "brdfkit.io.directions",
    "read_directions": "brdfkit.io.directions",
    "write_directions": "brdfkit.io.directions",
    "plan_directions": "brdfkit.acquisition.planning",
    "to_mapped": "brdfkit.hypernet.mapping",
    "from_mapped": "brdfkit.hypernet.mapping",
    "median_reference": "brdfkit.hypernet.mapping",
    "load_model": "brdfkit.api",
    "encode": "brdfkit.api",
    "decode": "brdfkit.api",
    "interpolate": "brdfkit.api",
    "fit": "brdfkit.api",
    "sparse": "brdfkit.api",
    "Embedding": "brdfkit.io.embedding",
    "read_embedding": "brdfkit.io.embedding",
    "write_embedding": "brdfkit.io.embedding",
    "set_torch_threads": "brdfkit.runtime",
}
_PUBLIC_MODULES = {
    "geometry": "module:brdfkit.geometry",
    "synthetic": "module:brdfkit.materials.synthetic",
}
# Modules reachable by their short names since before the package had folders; not in
# ``__all__``.
_MODULES = {
    "mapping": "module:brdfkit.hypernet.mapping",
    "merl": "module:brdfkit.io.merl",
    "samples": "module:brdfkit.io.samples",
}

__all__ = sorted(_API) + ["geometry", "synthetic", "__version__"]

__getattr__, _dir = lazy_attributes(__name__, {**_API, **_PUBLIC_MODULES, **_MODULES})


def __dir__():
    return __all__
