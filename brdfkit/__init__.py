"""brdfkit: measured BRDFs and hypernetwork neural BRDFs.

Follows Gokbudak, Sztrajman, Zhou, Chung and Oztireli, "Hypernetworks for Generalizable
BRDF Representation", ECCV 2024. The public API is imported lazily: ``import brdfkit``
loads neither torch nor mitsuba; each name pulls in only the module that defines it
(``__init__.pyi`` lists them for IDEs and type checkers).

The package, one folder per domain, in layers (:data:`LAYERS`): a module imports only from
its own layer and the layers above it in this table, inside functions too
(``tests/test_layout.py``):

==== ======================================= ============================================
     where                                   what
==== ======================================= ============================================
1    ``errors``, ``atomic``, ``console``,    the foundation: one-line errors, atomic
     ``runtime``, ``distributed``            outputs, messages and progress, the torch
                                             device and thread count, ``torchrun``'s
                                             process group
2    ``geometry/``                           Rusinkiewicz coordinates, the MERL grid, its
                                             lookups
3    ``io/``                                 file formats: MERL ``.binary``, RGL
                                             ``.bsdf``, sample and direction CSVs,
                                             ``.emb``, the checked safetensors reader
4    ``materials/``, ``models/``             materials brdfkit makes (GGX, stiff cases,
                                             NBRDF networks); the part registry
                                             (``PARTS``), the built-in models: bundles of
                                             parts, the manifest, names to files
5    ``render/``                             the reference scene, quadrature, the scene
                                             suite, the render-aligned error, the display
                                             encoding, Mitsuba 3's ``brdfkit`` BSDF
6    ``basis/``, ``hypernet/``               the PCA basis; the hypernetwork (network,
                                             files, encode, decode, refinement, training);
                                             neither imports the other
7    ``prior/``, ``residual/``               the learnt prior of a basis; the hypernetwork
                                             residual of a basis
8    ``embeddings/``, ``methods/``           embedding kinds by name (``KINDS``), decoders,
                                             blends; sparse-reconstruction methods by name
                                             (``METHODS``); what a model serves (kinds,
                                             sizes, methods: ``methods.service``, which
                                             reads both registries) and the choice a
                                             ``-m`` value makes
9    ``files/``                              a BRDF file of any type, opened, converted,
                                             rendered
10   ``acquisition/``                        where to measure: sampling, planning,
                                             designs, the benchmark protocol
11   ``evaluation/``                         metrics, comparisons, held-out error
12   ``figures/``, ``view/``                 plots, comparison sheets, interpolation
                                             strips; the page that renders BRDFs live
                                             in WebGL2, GLSL for an engine
13   ``training/``, ``bench/``, ``testing/`` what ``brdfkit fit`` trains (``FITTERS``);
                                             the benchmark; the tests' examples and fuzzer
14   ``api``                                 the front: the library's verbs (encode,
                                             decode, sparse, interpolate, fit, ...)
15   ``demos/``                              ``brdfkit demo``, run through the front as a
                                             user would
16   ``cli/``                                the ``brdfkit`` command line, thin over the
                                             library
==== ======================================= ============================================

Examples
--------
>>> import brdfkit
>>> sorted(brdfkit.__all__)[:4]
['BrdfkitError', 'DirectionSet', 'Embedding', 'FormatError']
"""

from __future__ import annotations

import importlib

__version__ = "0.1.0"

LAYERS = (("errors", "atomic", "console", "runtime", "distributed"), ("geometry",), ("io",), ("materials", "models"), ("render",),
          ("basis", "hypernet"), ("prior", "residual"), ("embeddings", "methods"), ("files",), ("acquisition",),
          ("evaluation",), ("figures", "view"), ("training", "bench", "testing"), ("api",), ("demos",), ("cli",))
"""The packages and top-level modules in their layers, lowest first (the table above):
data flows down this list, never up."""


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
