"""A model's parts: which part a file is, and a part loaded by the ``-m`` value that names it.

A model (what ``-m`` takes) is a file or a built-in bundle of parts
(:data:`brdfkit.models.builtin.PARTS`): a hypernetwork (``network``), a PCA basis
(``basis``), a learnt prior (``prior``) and a basis residual (``residual``). Each file
says which part it is by the format its header records.
"""

from __future__ import annotations

import os

__all__ = ["file_part", "load_part"]


def file_part(path: str | os.PathLike) -> str:
    """The part a model file is, by the format its header records: ``prior``
    (``brdfkit-prior``), ``basis`` (``brdfkit-basis``), ``residual``
    (``brdfkit-residual``), else ``network`` (whose loader then names what is wrong with
    a file that is none of them)."""
    from brdfkit.errors import FormatError, InputError
    from brdfkit.io.tensorfile import open_safetensors

    try:
        with open_safetensors(os.fspath(path)) as f:
            fmt = (f.metadata() or {}).get("format")
    except (FormatError, InputError, OSError):
        fmt = None
    from brdfkit.basis.basis_file import is_basis_format
    from brdfkit.prior.prior_file import PRIOR_FORMAT
    from brdfkit.residual.residual_file import RESIDUAL_FORMAT

    if is_basis_format(fmt):
        return "basis"
    return {PRIOR_FORMAT: "prior", RESIDUAL_FORMAT: "residual"}.get(fmt, "network")


def load_part(spec: str | os.PathLike, part: str, device="cpu"):
    """Part ``part`` of the model ``spec`` (a built-in's name or a file), loaded and
    checked: a built-in's file against the manifest's digest, weights against the digest
    the file records."""
    from brdfkit.models.builtin import resolve_part

    path = resolve_part(spec, part)
    if part == "network":
        from brdfkit.hypernet.network_file import load_network

        return load_network(path, device=device)
    if part == "prior":
        from brdfkit.prior.prior_file import load_prior

        return load_prior(path, device=device)
    if part == "residual":
        from brdfkit.residual.residual_file import load_residual

        return load_residual(path)
    from brdfkit.basis.basis_file import load_basis

    return load_basis(path)
