"""The built-in models: the pretrained files shipped in this folder, their
``manifest.json``, and their lookup by name (:mod:`~brdfkit.models.builtin`); the part
registry (:mod:`~brdfkit.models.parts`): what each part of a model is, as a file and as
what loads it.

This folder holds data (``*.safetensors``, ``manifest.json``; ``docs/models.md``) beside
the two modules. Loading a part is its package's own, named by the part registry
:data:`brdfkit.models.parts.PARTS` and imported when a part loads; packing a hypernetwork
file is :mod:`brdfkit.hypernet.packing`'s.

May import: the ground floor and :mod:`brdfkit.io`. No torch.
"""
