"""The sha256 of a file's bytes: the fingerprint of a basis file beside a learnt prior,
and the cache keys of reference renders (``brdfkit bench``, ``brdfkit compare``)."""

from __future__ import annotations

import hashlib
import os

__all__ = ["file_digest"]


def file_digest(path: str | os.PathLike) -> str:
    """sha256 hex of the bytes of the file ``path``, read in 1 MiB blocks."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()
