"""The built-in models: the pretrained files shipped in this folder, their
``manifest.json``, and their lookup by name (:mod:`~brdfkit.models.builtin`); what each
part of a model is as a file (:mod:`~brdfkit.models.parts`).

This folder holds data (``*.safetensors``, ``manifest.json``; ``docs/models.md``) beside
the two modules. Loading a part is its package's own, reached through the part registry
:data:`brdfkit.embeddings.parts.PARTS`; packing a hypernetwork file is
:mod:`brdfkit.hypernet.packing`'s.

May import: the ground floor and :mod:`brdfkit.io`. No torch.
"""
