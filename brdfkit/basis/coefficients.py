"""A material as the coefficients of a PCA basis (a *basis embedding*), and back.

A basis embedding holds ``K`` coefficients per channel of a PCA basis (its ``K`` leading
components; ``3 K`` numbers, the embedding's size): the least-squares projection of the
table, which is the PCA of that size whatever the material, then refined on renders of
the objective scenes (:mod:`brdfkit.basis.refine_on_screen`; never a judged scene),
keeping the projection wherever the held-out pixels do not agree. Decoding is the
basis's closed form (:meth:`~brdfkit.basis.model.PcaBasis.decode`); blending two
embeddings blends the log-mapped tables. A hypernetwork's latent holds for the
materials it was trained on and fails outside them; the basis holds for any
(``docs/compression.md``).

The embedding names its basis by the SHA-256 of the basis file
(:attr:`brdfkit.io.embedding.Embedding.decoder`).
"""

from __future__ import annotations

import numpy as np

from brdfkit.errors import InputError, ModelMismatchError
from brdfkit.render.renderable import DecodedBRDF

__all__ = ["DEFAULT_SIZE", "DEFAULT_STEPS", "BasisBRDF", "basis_sizes", "check_coefficients", "encode_coefficients",
           "refinement_record"]

DEFAULT_SIZE = 39
"""Numbers per material of a basis embedding by default: 13 components a channel, beside
the hypernetwork's 40-D latent."""

DEFAULT_STEPS = 8
"""Most refinement iterations of a basis embedding (``brdfkit encode --steps``):
Levenberg-Marquardt iterations of :mod:`brdfkit.basis.refine_on_screen`, with
:data:`~brdfkit.basis.refine_on_screen.DEFAULT_TRUST` (``docs/compression.md``)."""


def basis_sizes(basis) -> range:
    """The sizes a basis embedding of ``basis`` (a basis, or its number of components) may
    have: ``3 K`` numbers for ``K`` from 1 to the basis's components.

    Examples
    --------
    >>> from brdfkit.testing.examples import tiny_basis
    >>> list(basis_sizes(tiny_basis(4))), list(basis_sizes(2))
    ([3, 6, 9, 12], [3, 6])
    """
    k = basis if isinstance(basis, int) else basis.n_components
    return range(3, 3 * k + 1, 3)


def _components(basis, size: int, what: str = "a basis embedding") -> int:
    """``K`` of an embedding of ``size`` numbers; :class:`InputError` for a size the basis
    does not offer."""
    if size not in basis_sizes(basis):
        raise InputError(f"{what} of {size} numbers: a basis embedding holds 3 numbers a component, and this basis "
                         f"has {basis.n_components} components (sizes 3, 6, ... {3 * basis.n_components})")
    return size // 3


def encode_coefficients(basis, table, *, digest: str, size: int | None = None, source: str = "",
                        steps: int | None = None):
    """A dense table as a basis embedding.

    Parameters
    ----------
    basis
        :class:`~brdfkit.basis.model.PcaBasis`; its leading ``K`` components encode.
    table
        ``(90, 90, 180, 3)`` BRDF in 1/sr, NaN where unmeasured.
    digest
        SHA-256 of the basis file (:func:`brdfkit.io.digest.cached_file_digest`), recorded
        as the embedding's decoder.
    size
        Numbers per material, ``3 K`` (:func:`basis_sizes`; default :data:`DEFAULT_SIZE`,
        or all the basis's components when it has fewer).
    source
        Provenance recorded in the embedding.
    steps
        Most refinement steps (default :data:`DEFAULT_STEPS`; 0: the projection alone).

    Returns
    -------
    brdfkit.io.embedding.Embedding
        Kind ``"basis"``, ``values`` float32 ``(3 K,)``, the ``(K, 3)`` coefficients
        component-major; ``refinement`` records the steps.

    Examples
    --------
    >>> from brdfkit.testing.examples import lambertian_table, tiny_basis
    >>> emb = encode_coefficients(tiny_basis(4), lambertian_table(), digest="ab" * 32, size=6, steps=0)
    >>> emb.kind, emb.size, emb.refinement is None
    ('basis', 6, True)
    """
    from brdfkit.basis.refine_on_screen import DEFAULT_TRUST, prepare_screens, refine_coefficients
    from brdfkit.io.embedding import Embedding
    from brdfkit.render.objective import THREADS, ObjectiveConfig
    from brdfkit.runtime import beside, blas_threads, stage

    if size is None:
        size = min(DEFAULT_SIZE, 3 * basis.n_components)
    part = basis.leading(_components(basis, int(size)))
    steps = DEFAULT_STEPS if steps is None else int(steps)
    cfg = ObjectiveConfig(steps=steps)
    with blas_threads(THREADS):  # the same sums whatever the machine's cores
        with stage("objective views and cell maps"):  # while the table is projected, where it can
            made = beside(prepare_screens, part, table, cfg) if steps else None
        with stage("project"):
            c0 = part.project(table)
        with stage("waiting for the objective views and cell maps"):
            screens = made.result() if made is not None else None
        with stage("refine"):
            c, rec = refine_coefficients(part, table, c0, cfg, trust=DEFAULT_TRUST, screens=screens)
    measured = int(np.isfinite(np.asarray(table).reshape(-1, 3)).all(axis=1).sum())
    record = refinement_record(rec) if steps else None
    return Embedding(np.asarray(c, np.float32).reshape(-1), "basis", digest, source, measured, refinement=record)


def refinement_record(rec: dict) -> dict:
    """What an embedding records of a refinement (:func:`brdfkit.render.objective.refine_loop`'s
    record): the iterations, the one kept, why it stopped, the solver and the held-out
    errors (display MSE) of the start and of each iteration."""
    return {"steps": rec["steps"], "best_step": rec["best_step"], "stopped": rec["stopped"], "solver": rec["solver"],
            "heldout": [float(f"{e:.6g}") for e in rec["heldout"]]}


def check_coefficients(emb, basis, digest: str, name: str = "") -> np.ndarray:
    """The ``(K, 3)`` float32 coefficients of a basis embedding, checked against the
    basis (its file's SHA-256 ``digest``, enough components).

    Raises
    ------
    ModelMismatchError
        Another basis, or more components than the basis has (one line).
    """
    what = f"embedding {name}" if name else "embedding"
    if emb.decoder != digest:
        raise ModelMismatchError(f"{what} holds coefficients of basis {emb.decoder[:12]}, not of the given basis "
                                 f"{digest[:12]}; encode the material again with this basis")
    if emb.size % 3 or emb.size // 3 > basis.n_components:
        raise ModelMismatchError(f"{what} holds {emb.size} numbers; a basis of {basis.n_components} components "
                                 f"decodes 3, 6, ... {3 * basis.n_components}")
    return emb.values.reshape(emb.size // 3, 3)


class BasisBRDF(DecodedBRDF):
    """A basis embedding as a renderable BRDF (``eval_pairs``, ``eval_dirs``, ``to_table``):
    a render decodes it only at the cells its pairs reach
    (:class:`~brdfkit.render.renderable.DecodedBRDF`)."""

    def __init__(self, basis, coefficients, name: str = "embedding", device=None):
        self.basis = basis
        self.coefficients = np.asarray(coefficients, np.float32)
        self.name = name

    def to_table(self) -> np.ndarray:
        """float64 ``(90, 90, 180, 3)``, 1/sr, NaN off the basis's cells."""
        return self.basis.leading(self.coefficients.shape[0]).decode(self.coefficients)

    def at_cells(self, cells) -> tuple:
        """``(cells, values)``: the decode at those of the flat MERL ``cells`` the basis
        covers, float64 ``(n, 3)``."""
        return self.basis.leading(self.coefficients.shape[0]).decode_at(self.coefficients, cells)
