"""The built-in models: the pretrained files shipped in this folder, their
``manifest.json``, and their lookup by name (:mod:`~brdfkit.models.builtin`).

This folder holds data (``*.safetensors``, ``manifest.json``; ``docs/models.md``) beside
the one module that reads the manifest. Loading or packing a hypernetwork file is the
hypernetwork's own (:mod:`brdfkit.hypernet.packing`); a learnt prior's or a PCA basis's,
its method's (:mod:`brdfkit.methods`).

May import: the ground floor and :mod:`brdfkit.io`. No torch.
"""
