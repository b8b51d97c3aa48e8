"""A dense table as a residual embedding: ``3 K`` coefficients of a basis and the weight of
its residual's correction.

The encoder (:func:`encode_residual`) has the whole table, so it can afford to choose:

1. the projection onto the basis's ``K`` leading components, refined on renders of the
   objective scenes (never a judged one): the basis embedding
   (:mod:`brdfkit.basis.coefficients`);
2. the projection's coefficients with the correction; coefficients fitted again through
   the correction: Levenberg-Marquardt (:mod:`brdfkit.basis.least_squares`, the solver
   of the refinement too) on the mapped error of :data:`FIT_CELLS` cells drawn once (at
   most :data:`FIT_STEPS` iterations; the correction's derivative by forward mode through
   its NumPy network, :func:`brdfkit.residual.network.evaluate_with_jacobian`, in fixed
   pieces of :data:`JACOBIAN_ROWS` cells on as many threads as there are);
   then refined on the same renders with the correction held at its value there (the
   hyponet evaluated once at the cells the renders reach, not at every iteration), and
   kept only where the true decode, correction re-evaluated, renders better;
3. of the basis embedding and the corrected ones, the one with the lower render error on
   the objective scenes' held-out pixels: the basis alone (``correction`` 0) or the basis
   plus the correction (``correction`` 1). Where the correction does not help a
   material, it is not used.

A file with several networks a size (*members*, ``brdfkit fit --method residual -O
members=M``) gives step 2's projection and fitted candidates for each member; the best of
them on the held-out pixels is refined, and the member chosen is recorded in the options
(:func:`brdfkit.residual.model.gain_options`): the networks err on different materials, and
the objective scenes see which one is right for a material (``docs/notes/compression.md``).

Everything is NumPy, seeded and counted in iterations: the same table and files give the
same bytes on any number of cores (the work split into fixed pieces, channels and
scenes, never across BLAS threads, which the encode holds to one), and no torch is
imported.
"""

from __future__ import annotations

import numpy as np

from brdfkit.errors import InputError

__all__ = ["FIT_STEPS", "FIT_CELLS", "JACOBIAN_ROWS", "encode_residual", "fit_through", "correction_fn", "frozen_correction_fn"]

FIT_STEPS = 8
"""Most Levenberg-Marquardt iterations of the fit through the correction (it replaced 60
Adam steps; ``docs/notes/compression.md``)."""
FIT_CELLS = 16384
"""Cells of the fit through the correction, drawn once with a fixed seed (the study drew
65,536; 3 K unknowns a channel need far fewer)."""
JACOBIAN_ROWS = 2048
"""Cells of one piece of the correction's forward-mode derivative (a fixed size: the
pieces' tangents, ``K`` times the hyponet's width a cell, stay in cache; 1.6 times as
fast as all the fit's cells at once)."""


def correction_fn(residual, k: int, member: int = 0):
    """``extra(cells) -> (c -> (U, 3))``: member ``member``'s correction at flat MERL cells
    of coefficients ``c`` ``(k, 3)`` (as :func:`~brdfkit.basis.refine_on_screen.refine_coefficients`
    and :meth:`~brdfkit.basis.refine_on_screen.Screens.with_extra` take it)."""
    from brdfkit.geometry import grid_hd

    residual.net_for(k, member)

    def extra(cells):
        hd = np.ascontiguousarray(grid_hd()[cells])
        return lambda c: residual.correction(c, hd, member).astype(np.float64)

    return extra


def frozen_correction_fn(residual, k: int, c: np.ndarray, member: int = 0):
    """``extra`` as :func:`correction_fn` gives it, the correction held at its value for
    coefficients ``c`` ``(k, 3)``: evaluated once a set of cells, constant in the
    coefficients."""
    live = correction_fn(residual, k, member)

    def extra(cells):
        value = live(cells)(np.asarray(c, np.float64))
        return lambda _c: value

    return extra


def fit_through(residual, mapped: np.ndarray, c0: np.ndarray, steps: int = FIT_STEPS, seed: int = 0,
                member: int = 0) -> np.ndarray:
    """Coefficients ``(K, 3)`` minimising the mapped error of basis plus member ``member``'s
    correction at :data:`FIT_CELLS` cells (``mapped`` ``(P, 3)``: the table's, the mean
    included; NaN unmeasured), from ``c0``: at most ``steps`` Levenberg-Marquardt
    iterations a channel (:func:`brdfkit.basis.least_squares.levenberg_marquardt`; each
    channel's correction depends on its own coefficients alone), the derivative's pieces
    on :func:`brdfkit.runtime.thread_map`'s threads."""
    from brdfkit.residual.network import evaluate_with_jacobian

    from brdfkit.basis.least_squares import levenberg_marquardt
    from brdfkit.runtime import thread_map

    c0 = np.asarray(c0, np.float64)
    k = c0.shape[0]
    part = residual.basis.leading(k)
    ok = np.flatnonzero(np.isfinite(mapped).all(axis=1))
    idx = np.sort(np.random.default_rng(seed).choice(ok, size=min(FIT_CELLS, ok.size), replace=False))
    comp = part.rows_at(idx).T.astype(np.float64)  # (C, K)
    hd = residual.cell_hd()[idx]
    _, cfg, state = residual.net_for(k, member)
    sigma = part.sigma.astype(np.float64)

    def channel(ch):
        target = mapped[idx, ch] - part.mean[idx]

        def evaluate(c):
            return comp @ c + residual.correction_channel(c, hd, member) - target, None

        def jacobian(c, _):
            # Forward mode in fixed pieces of JACOBIAN_ROWS cells (their tangents stay in
            # cache), on as many threads as there are: the same bytes on any number.
            jac = np.concatenate(list(thread_map(
                lambda s: evaluate_with_jacobian(state, cfg, c / sigma, hd[s:s + JACOBIAN_ROWS])[1],
                range(0, hd.shape[0], JACOBIAN_ROWS))))
            return comp + jac / sigma

        return levenberg_marquardt(evaluate, jacobian, c0[:, ch], steps)

    return np.stack([channel(ch) for ch in range(3)], axis=1)


def encode_residual(residual, table, *, digest: str, size: int, source: str = "", steps: int | None = None):
    """A dense table as a residual embedding (module docstring).

    Parameters
    ----------
    residual
        :class:`~brdfkit.residual.model.BasisResidual`.
    table
        ``(90, 90, 180, 3)`` BRDF in 1/sr, NaN where unmeasured.
    digest
        SHA-256 of the residual file, recorded as the embedding's decoder.
    size
        Numbers per material, ``3 K``.
    steps
        Most refinement iterations of each candidate (default
        :data:`brdfkit.basis.coefficients.DEFAULT_STEPS`; 0: the projection and the fit
        through the correction, chosen between on the held-out pixels).

    Returns
    -------
    brdfkit.io.embedding.Embedding
        Kind ``"residual"``, the ``(K, 3)`` coefficients component-major, ``parts`` the
        residual's and its basis's digests, ``options`` the chosen member's gain
        (:func:`brdfkit.residual.model.gain_options`: ``{"correction": 0 or 1}`` for
        member 0).
    """
    from brdfkit.render.objective import THREADS
    from brdfkit.runtime import blas_threads

    if size % 3:
        raise InputError(f"a residual embedding holds 3 numbers a component, not {size}")
    residual.check_k(size // 3)
    with blas_threads(THREADS):  # the same sums whatever the machine's cores
        return _encode(residual, table, digest, size // 3, source, steps)


def _encode(residual, table, digest: str, k: int, source: str, steps):
    """:func:`encode_residual` of ``k`` components a channel (module docstring)."""
    from brdfkit.basis.coefficients import DEFAULT_STEPS, refinement_record
    from brdfkit.basis.refine_on_screen import DEFAULT_TRUST, heldout_error, prepare_screens, refine_coefficients
    from brdfkit.io.embedding import Embedding
    from brdfkit.render.objective import ObjectiveConfig
    from brdfkit.residual.model import gain_options
    from brdfkit.runtime import beside, stage

    part = residual.basis.leading(k)
    steps = DEFAULT_STEPS if steps is None else int(steps)
    cfg = ObjectiveConfig(steps=steps)
    # Independent pieces run beside the caller's (runtime.beside): the renders and maps of
    # the objective scenes (one set for every candidate) while the table is projected; the
    # basis alone refined while the correction's candidates are fitted.
    with stage("objective views and cell maps"):  # (returns at once when it runs beside)
        made = beside(prepare_screens, part, table, cfg)
    with stage("project"):
        c0 = part.project(table)
        mapped = part.mapped_table(table)
    with stage("waiting for the objective views and cell maps"):
        screens = made.result()

    def basis_alone():
        ca, rec_a = refine_coefficients(part, table, c0, cfg, trust=DEFAULT_TRUST, screens=screens)
        err_a = min(rec_a["heldout"]) if rec_a["heldout"] else heldout_error(part, table, ca, cfg, None, screens)
        return err_a, ca, rec_a, None

    with stage("refine the basis alone"):
        alone = beside(basis_alone)
    starts, lives = [], {}  # each member's projection (the study's best for half the materials at 9 numbers) and fit
    for member in residual.members(k):
        with stage("correction at the held-out cells"):
            lives[member] = screens.with_extra(correction_fn(residual, k, member), fits=False)
        with stage("fit through the correction"):
            fitted = fit_through(residual, mapped, c0, member=member)
        with stage("held-out errors of the starts"):
            starts += [(lives[member].held_error(c), c, member) for c in (c0, fitted)]
    with stage("waiting for the basis alone"):
        cands = [alone.result()]
    _, cs, best = min(starts, key=lambda x: x[0])
    with stage("refine with the correction"):
        c2, rec_b = refine_coefficients(part, table, cs, cfg, trust=DEFAULT_TRUST, screens=screens,
                                        extra=frozen_correction_fn(residual, k, cs, best))
    unrefined = dict(rec_b, best_step=0)
    cands += [(e, c, unrefined, m) for e, c, m in starts]
    if steps:
        with stage("held-out errors of the starts"):
            cands.append((lives[best].held_error(c2), c2, rec_b, best))
    err, c, rec, member = min(cands, key=lambda x: x[0])
    measured = int(np.isfinite(np.asarray(table).reshape(-1, 3)).all(axis=1).sum())
    record = refinement_record(rec) if steps else None
    return Embedding(np.asarray(c, np.float32).reshape(-1), "residual", digest, source, measured, refinement=record,
                     parts={"basis": residual.basis_digest, "residual": digest}, options=gain_options(member))
