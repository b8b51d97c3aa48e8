"""The sha256 of a file's bytes: the digest a basis file is known by (in embeddings, in
the built-ins' manifest, beside a learnt prior), and the cache keys of reference renders
(``brdfkit bench``, ``brdfkit compare``)."""

from __future__ import annotations

import functools
import hashlib
import os

__all__ = ["file_digest", "cached_file_digest"]


def file_digest(path: str | os.PathLike) -> str:
    """sha256 hex of the bytes of the file ``path``, read in 1 MiB blocks."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


@functools.lru_cache(maxsize=16)
def _digest(path: str, size: int, mtime_ns: int) -> str:
    return file_digest(path)


def cached_file_digest(path: str | os.PathLike) -> str:
    """:func:`file_digest`, computed once per process while the file keeps its size and
    modification time (a 20 MB basis file takes about 50 ms to hash)."""
    st = os.stat(path)
    return _digest(os.path.abspath(os.fspath(path)), st.st_size, st.st_mtime_ns)
