"""A dense table as a residual embedding: ``3 K`` coefficients of a basis and the weight of
its residual's correction.

The encoder (:func:`encode_residual`) has the whole table, so it can afford to choose:

1. the projection onto the basis's ``K`` leading components, refined on renders of the
   objective scenes (never a judged one): the basis embedding
   (:mod:`brdfkit.basis.coefficients`);
2. the projection's coefficients with the correction; coefficients fitted again through
   the correction: Adam on the mapped error of
   :data:`FIT_CELLS` cells drawn once (:data:`FIT_STEPS` steps); then refined on the same
   renders with the correction held at its value there (the hyponet evaluated once at the
   cells the renders reach, not at every step: a fortieth of the time), and kept only
   where the true decode, correction re-evaluated, renders better;
3. of the basis embedding and the corrected one, the one with the lower render error on
   the objective scenes' held-out pixels: the basis alone (``correction`` 0) or the basis
   plus the correction (``correction`` 1). Where the correction does not help a
   material, it is not used.

Everything is seeded and counted in steps on a fixed thread count: the same table and
files give the same bytes.
"""

from __future__ import annotations

import numpy as np

from brdfkit.errors import InputError

__all__ = ["FIT_STEPS", "FIT_CELLS", "FIT_LR", "encode_residual", "torch_net", "fit_through", "correction_fn",
           "frozen_correction_fn"]

FIT_STEPS = 60
"""Adam steps of the fit through the correction (``docs/notes/compression.md``)."""
FIT_CELLS = 16384
"""Cells of the fit through the correction, drawn once with a fixed seed (the study drew
65,536; 3 K unknowns a channel need far fewer)."""
FIT_LR = 0.02
"""Its learning rate, in the components' training standard deviations."""


def torch_net(residual, k: int):
    """``(module, cfg)``: the residual's network for ``k`` components as a torch module
    (cached on the object), evaluation mode."""
    index, cfg, state = residual.net_for(k)
    cache = residual.__dict__.setdefault("_torch_nets", {})
    if index not in cache:
        import torch

        from brdfkit.residual.network import ResidualNet

        net = ResidualNet(cfg)
        net.load_state_dict({name: torch.as_tensor(v) for name, v in state.items()})
        net.eval()
        for p in net.parameters():
            p.requires_grad_(False)
        cache[index] = net
    return cache[index], cfg


def _inputs(c, sigma, k_max):
    """The network's input ``(3, 2 k_max)`` of coefficients ``c`` ``(K, 3)`` (torch, differentiable)."""
    import torch

    k = c.shape[0]
    z = (c / sigma[:, None]).T.float()
    pad = torch.zeros(3, k_max - k, dtype=z.dtype)
    mask = torch.cat([torch.ones(3, k), torch.zeros(3, k_max - k)], dim=1)
    return torch.cat([z, pad, mask], dim=1)


def correction_fn(residual, k: int):
    """``extra(cells) -> (c -> (U, 3))``: the correction at flat MERL cells, differentiable
    in coefficients ``c`` ``(k, 3)`` (as :func:`~brdfkit.basis.refine_on_screen.refine_coefficients`
    takes it)."""
    import torch

    from brdfkit.geometry import grid_hd

    net, cfg = torch_net(residual, k)
    k_max = cfg.k_max
    sigma = torch.tensor(residual.basis.sigma[:k], dtype=torch.float64)

    def extra(cells):
        hd = torch.as_tensor(np.ascontiguousarray(grid_hd()[cells]))
        return lambda c: net(_inputs(c, sigma, k_max), hd).T

    return extra


def frozen_correction_fn(residual, k: int, c: np.ndarray):
    """``extra`` as :func:`correction_fn` gives it, the correction held at its value for
    coefficients ``c`` ``(k, 3)``: evaluated once a set of cells, constant in the
    coefficients."""
    import torch

    live = correction_fn(residual, k)
    at = torch.tensor(np.asarray(c, np.float64))

    def extra(cells):
        with torch.no_grad():
            value = live(cells)(at)
        return lambda _c: value

    return extra


def fit_through(residual, mapped: np.ndarray, c0: np.ndarray, steps: int = FIT_STEPS, seed: int = 0) -> np.ndarray:
    """Coefficients ``(K, 3)`` minimising the mapped error of basis plus correction at
    :data:`FIT_CELLS` cells (``mapped`` ``(P, 3)``: the table's, the mean included; NaN
    unmeasured), from ``c0``."""
    import torch

    from brdfkit.render.objective import Adam

    k = c0.shape[0]
    part = residual.basis.leading(k)
    ok = np.flatnonzero(np.isfinite(mapped).all(axis=1))
    idx = np.sort(np.random.default_rng(seed).choice(ok, size=min(FIT_CELLS, ok.size), replace=False))
    target = torch.as_tensor(mapped[idx] - part.mean[idx, None], dtype=torch.float32)
    comp = torch.as_tensor(part.components[:, idx].T)  # (C, K)
    hd = torch.as_tensor(residual.cell_hd()[idx])
    (net, cfg), sigma = torch_net(residual, k), torch.tensor(part.sigma, dtype=torch.float64)
    z = torch.tensor(c0 / part.sigma[:, None].astype(np.float64), requires_grad=True)
    opt = Adam([z], lr=FIT_LR)
    for _ in range(steps):
        c = z * sigma[:, None]
        pred = comp @ c.float() + net(_inputs(c, sigma, cfg.k_max), hd).T
        loss = ((pred - target) ** 2).mean()
        opt.zero_grad()
        loss.backward()
        opt.step()
    return (z.detach() * sigma[:, None]).numpy()


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
        Most refinement steps of each candidate (default
        :data:`brdfkit.basis.coefficients.DEFAULT_STEPS`; 0: the projection and the fit
        through the correction, chosen between on the held-out pixels).

    Returns
    -------
    brdfkit.io.embedding.Embedding
        Kind ``"residual"``, the ``(K, 3)`` coefficients component-major, ``parts`` the
        residual's and its basis's digests, ``options`` ``{"correction": 0 or 1}``.
    """
    from brdfkit.basis.coefficients import DEFAULT_STEPS
    from brdfkit.basis.refine_on_screen import (DEFAULT_LR, DEFAULT_TRUST, heldout_error, prepare_screens,
                                                refine_coefficients)
    from brdfkit.io.embedding import Embedding
    from brdfkit.render.objective import THREADS, ObjectiveConfig
    from brdfkit.runtime import torch_threads

    if size % 3:
        raise InputError(f"a residual embedding holds 3 numbers a component, not {size}")
    k = size // 3
    residual.check_k(k)
    part = residual.basis.leading(k)
    steps = DEFAULT_STEPS if steps is None else int(steps)
    cfg = ObjectiveConfig(steps=steps, lr=DEFAULT_LR)
    extra = correction_fn(residual, k)
    c0 = part.project(table)
    with torch_threads(THREADS):
        c1 = fit_through(residual, part.mapped_table(table), c0)
    screens = prepare_screens(part, table, cfg)  # one set of renders and maps for every candidate
    ca, rec_a = refine_coefficients(part, table, c0, cfg, trust=DEFAULT_TRUST, screens=screens)
    err_a = rec_a["heldout"][1] if rec_a["heldout"] else heldout_error(part, table, ca, cfg, None, screens)
    cands = [(err_a, ca, rec_a, 0)]
    c2, rec_b = refine_coefficients(part, table, c1, cfg, trust=DEFAULT_TRUST, screens=screens,
                                    extra=frozen_correction_fn(residual, k, c1))
    unrefined = dict(rec_b, best_step=0)
    # The correction at the projection's own coefficients too: the study's best for half
    # the materials at 9 numbers (docs/notes/compression.md).
    for c, rec in ((c0, unrefined), (c1, unrefined), *(((c2, rec_b),) if steps else ())):
        cands.append((heldout_error(part, table, c, cfg, extra, screens), c, rec, 1))
    err, c, rec, use = min(cands, key=lambda x: x[0])
    measured = int(np.isfinite(np.asarray(table).reshape(-1, 3)).all(axis=1).sum())
    record = {key: rec[key] for key in ("steps", "best_step", "stopped")} if steps else None
    return Embedding(np.asarray(c, np.float32).reshape(-1), "residual", digest, source, measured, refinement=record,
                     parts={"basis": residual.basis_digest, "residual": digest}, options={"correction": float(use)})
