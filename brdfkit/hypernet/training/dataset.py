"""Training data for the hypernetwork: MERL tables held compactly, batches drawn on the fly.

Gokbudak et al. 2024 train on MERL tables mapped by the log-relative mapping of eq. (1)
with ``rho_ref`` the per-cell median of the training materials. A table is 1,458,000
cells; expanding every cell into its 6 HD numbers (plus 3 values) would take 52 MB per
material in float32. Instead :class:`TrainingSet` keeps, per material, only the mapped
values of the *measured* cells (float32 ``(n_cells, 3)``, about 13 MB) and, once, the flat
indices of those cells; :class:`BatchSampler` draws cell indices for each step and turns
them into HD vectors and ``cos(theta_i)`` on the training device
(:func:`brdfkit.geometry.cell_angles`, :func:`~brdfkit.geometry.hd_vectors`,
:func:`~brdfkit.geometry.cos_theta_i`, which accept tensors).

Sampling scheme (``docs/training.md``): each step takes ``B`` materials; for each, a
*query* set (uniform over the measured cells, the cells :func:`brdfkit.evaluation.metrics.brdf_log_rmse`
averages over) carries the loss, and a separate *context* set, of one size per step drawn
log-uniformly in ``[context_min, context_max]``, feeds the set encoder. Half of the
context sets are uniform over the measured cells and half uniform over the Rusinkiewicz
angles, the default of :func:`brdfkit.acquisition.sampling.draw_samples` and of real gonioreflectometer
sweeps, so that one model serves any number of samples drawn either way.

The reference may instead come from another model (:func:`given_reference`, ``fit(...,
reference=MODEL)``), so that models trained on different materials share one reference
table, and one shared reference file once packed (``docs/training.md``).
"""

from __future__ import annotations

import dataclasses
import hashlib
import os
from typing import Callable, Sequence

import numpy as np

from brdfkit.errors import BrdfkitError, FormatError, InputError
from brdfkit.geometry import N_CELLS, N_PHI_D, N_THETA_D, TABLE_SHAPE

__all__ = ["TrainingSet", "BatchSampler", "GivenReference", "given_reference"]


@dataclasses.dataclass(frozen=True)
class GivenReference:
    """Where a training run's reference table comes from (:func:`given_reference`).

    Attributes
    ----------
    path, digest
        The network file it was taken from and that network's weights digest; ``None``:
        the median of the training materials (eq. 1).
    table
        float32 ``(90, 90, 180, 3)``, 1/sr, NaN where unmeasured; ``None`` for the median.
    """

    path: str | None = None
    table: np.ndarray | None = None
    digest: str | None = None

    def check_resumable(self, ckpt: str, state: dict) -> None:
        """Refuse a checkpoint (``state``, its ``reference_from``) trained against
        another reference: the mapped values, and so the weights, depend on it."""
        was = state.get("reference_from")  # absent in older checkpoints: the median
        if was != self.digest:
            then, now = (f"model {str(fp)[:12]}" if fp else "the median" for fp in (was, self.digest))
            raise InputError(f"{ckpt}: checkpoint was trained against another reference table "
                             f"({then} then, {now} now); train afresh without --resume, or give "
                             f"the same reference")


def given_reference(spec) -> GivenReference:
    """The reference table of an existing model, to train another model against.

    Parameters
    ----------
    spec
        A brdfkit network file (``.safetensors``, loaded on the CPU, nothing
        unpickled) or the name of an installed built-in model
        (:func:`brdfkit.models.builtin.resolve_network`); ``None``: the median of the
        training materials.

    Raises
    ------
    InputError
        Not a string or path, no such file, or a name that is no installed built-in.
    FormatError
        Not a brdfkit network file, or a damaged one; a reference with negative values.
    """
    from brdfkit.models.builtin import resolve_network
    from brdfkit.hypernet.network_file import load_network

    if spec is None:
        return GivenReference()
    if not isinstance(spec, (str, os.PathLike)) or not os.fspath(spec):
        raise InputError(f"training option reference: {spec!r} is not a model file or built-in model name")
    path = resolve_network(spec)
    model = load_network(path, device="cpu")
    ref = np.ascontiguousarray(model.rho_ref, dtype=np.float32)
    if (ref < 0).any():  # the mapping divides by rho_ref + eps (eq. 1): a BRDF is never negative
        raise FormatError(path, "its reference table has negative values")
    return GivenReference(path, ref, model.digest)


class TrainingSet:
    """The training materials of one process, mapped and compact.

    Attributes
    ----------
    names, paths
        All training materials (every rank), sorted by name.
    rho_ref
        float32 ``(90, 90, 180, 3)``: per-cell median of *all* training materials, the
        same on every rank, NaN where none is measured; or the reference given to
        :meth:`load`.
    cells
        int64 ``(n_cells,)``: flat MERL indices of the cells measured in every training
        material, and where the reference is finite (the cells losses and contexts are
        drawn from).
    own
        Indices into ``names`` of this rank's share, ``range(rank, M, world)``.
    values
        float32 ``(len(own), n_cells, 3)``: mapped values ``rho'`` of the share at ``cells``.
    digest
        sha256 hex of the names and the reference table: identifies the data for resuming.
    """

    def __init__(self, names, paths, rho_ref, cells, own, values):
        self.names = list(names)
        self.paths = list(paths)
        self.rho_ref = rho_ref
        self.cells = cells
        self.own = list(own)
        self.values = values
        h = hashlib.sha256()
        for n in self.names:
            h.update(n.encode() + b"\0")
        h.update(np.ascontiguousarray(rho_ref, dtype=np.float32).tobytes())
        self.digest = h.hexdigest()

    @classmethod
    def load(cls, paths: Sequence[str], names: Sequence[str], rank: int = 0, world: int = 1,
             on_read: Callable[[int, str], None] | None = None,
             reference: np.ndarray | None = None) -> "TrainingSet":
        """Read every training file, compute the reference, keep this rank's share.

        Every rank reads every file: the reference table (the mapping's denominator) must
        be the median of *all* training materials and bit-identical across ranks.
        ``reference`` (float32 ``(90, 90, 180, 3)``, :func:`given_reference`) replaces
        that median; the cells where it is NaN are left out of training, since a value
        cannot be mapped without its reference.

        Raises
        ------
        FormatError
            A file that is not a MERL table (naming it).
        InputError
            No cell is measured in every training material (and in ``reference``).
        """
        from brdfkit.hypernet.mapping import median_reference, to_mapped
        from brdfkit.io.merl import read_merl

        own = list(range(rank, len(paths), world))
        if not own:
            raise InputError(f"{len(paths)} training material(s) cannot be shared among {world} "
                             f"processes: each needs at least one")
        stack = np.empty((len(paths), N_CELLS * 3), dtype=np.float32)
        measured = np.ones(N_CELLS, dtype=bool)
        for i, p in enumerate(paths):
            if on_read:
                on_read(i, p)
            try:
                table = read_merl(p)
            except BrdfkitError:
                raise
            except (OSError, MemoryError) as e:
                raise InputError(f"{p}: cannot read ({getattr(e, 'strerror', None) or e})") from None
            flat = table.reshape(N_CELLS, 3)
            measured &= np.isfinite(flat).all(axis=1)
            stack[i] = flat.reshape(-1)
            del table, flat
        if reference is None:
            rho_ref = median_reference(stack)
        else:
            rho_ref = np.ascontiguousarray(reference, dtype=np.float32).reshape(TABLE_SHAPE)
            measured &= np.isfinite(rho_ref.reshape(N_CELLS, 3)).all(axis=1)
        cells = np.flatnonzero(measured).astype(np.int64)
        if cells.size == 0:
            raise InputError("no MERL cell is measured in every training material"
                             + (" and in the given reference" if reference is not None else ""))
        ref_cells = rho_ref.reshape(N_CELLS, 3)[cells].astype(np.float64)
        values = np.empty((len(own), cells.size, 3), dtype=np.float32)
        for j, i in enumerate(own):
            rho = stack[i].reshape(N_CELLS, 3)[cells].astype(np.float64)
            values[j] = to_mapped(rho, ref_cells)
        del stack
        return cls(names, paths, rho_ref, cells, own, values)


class BatchSampler:
    """Draws one training step's batch on a device, reproducibly from ``(seed, rank, step)``.

    The generator is re-seeded from ``(seed, rank, step)`` at every step, so a run resumed
    from a checkpoint at step ``s`` draws exactly the batches the uninterrupted run would
    have drawn (the sampler has no other state to save).

    Parameters
    ----------
    tset
        The :class:`TrainingSet`.
    device
        ``torch.device`` for the tensors of the batch.
    batch, query, context_min, context_max
        Materials per step; query samples per material; context size range.
    angle_fraction
        Probability that a material's context is uniform over angles rather than cells.
    mixup
        Probability that a batch slot holds a mixture of two training materials instead
        of one: ``t v_a + (1 - t) v_b`` in mapped space, ``t ~ U(0, 1)``, context and
        query alike (mixup, Zhang et al. 2018; ``docs/notes/generalisation.md``). At 0 the batches are
        those drawn before the option existed.
    """

    def __init__(self, tset: TrainingSet, device, batch: int, query: int, context_min: int,
                 context_max: int, seed: int, rank: int = 0, angle_fraction: float = 0.5,
                 mixup: float = 0.0):
        import torch

        self.torch = torch
        self.device = device
        self.batch = min(batch, len(tset.own))
        self.query, self.cmin, self.cmax = query, context_min, context_max
        self.seed, self.rank, self.angle_fraction, self.mixup = seed, rank, angle_fraction, mixup
        self.values = torch.from_numpy(tset.values).to(device)
        self.cells = torch.from_numpy(tset.cells).to(device)
        # Uniform over (theta_h, theta_d, phi_d) gives theta_h row i the weight of its
        # angular width, proportional to (i+1)^2 - i^2 = 2i + 1 (square-root spacing);
        # theta_d and phi_d rows are equally wide.
        row = tset.cells // (N_THETA_D * N_PHI_D)
        w = torch.from_numpy((2 * row + 1).astype(np.float64))
        cdf = torch.cumsum(w, 0)
        self.cdf = cdf / cdf[-1]
        self.gen = torch.Generator()

    def _seed(self, step: int) -> int:
        return int(np.random.SeedSequence([self.seed, self.rank, step]).generate_state(1, np.uint64)[0])

    def context_size(self, step: int) -> int:
        """The context size of ``step`` (drawn first from the step's generator)."""
        self.gen.manual_seed(self._seed(step))
        u = float(self.torch.rand((), generator=self.gen, dtype=self.torch.float64))
        return int(round(np.exp(np.log(self.cmin) + u * (np.log(self.cmax) - np.log(self.cmin)))))

    def draw(self, step: int):
        """The batch of ``step``.

        Returns
        -------
        tuple
            ``(ctx_hd (B, C, 6), ctx_mapped (B, C, 3), q_hd (B, Q, 6), q_mapped (B, Q, 3),
            q_cos (B, Q))``, float32 on the device.
        """
        torch = self.torch
        g = self.gen
        n_ctx = self.context_size(step)  # re-seeds g
        n_cells = self.cells.numel()
        mats = torch.randperm(self.values.shape[0], generator=g)[: self.batch]
        q_pos = torch.randint(0, n_cells, (self.batch, self.query), generator=g)
        c_cell = torch.randint(0, n_cells, (self.batch, n_ctx), generator=g)
        c_ang = torch.searchsorted(self.cdf, torch.rand((self.batch, n_ctx), generator=g, dtype=torch.float64))
        c_ang = c_ang.clamp_(max=n_cells - 1)
        use_ang = torch.rand(self.batch, generator=g) < self.angle_fraction
        c_pos = torch.where(use_ang[:, None], c_ang, c_cell)
        mats, q_pos, c_pos = (t.to(self.device, non_blocking=True) for t in (mats, q_pos, c_pos))
        ctx_hd, _ = self._geometry(c_pos)
        q_hd, q_cos = self._geometry(q_pos)
        ctx_val = self.values[mats[:, None], c_pos]
        q_val = self.values[mats[:, None], q_pos]
        if self.mixup > 0:  # drawn after everything else: mixup = 0 keeps the old batches
            other = torch.randint(0, self.values.shape[0], (self.batch,), generator=g).to(self.device)
            t = torch.rand(self.batch, generator=g)
            t = torch.where(torch.rand(self.batch, generator=g) < self.mixup, t, torch.ones_like(t))
            t = t.to(self.device)[:, None, None]
            ctx_val = t * ctx_val + (1 - t) * self.values[other[:, None], c_pos]
            q_val = t * q_val + (1 - t) * self.values[other[:, None], q_pos]
        return ctx_hd, ctx_val, q_hd, q_val, q_cos

    def _geometry(self, pos):
        from brdfkit.geometry import cell_angles, cos_theta_i, hd_vectors

        th, td, pd = cell_angles(self.cells[pos])
        th, td, pd = th.float(), td.float(), pd.float()
        return hd_vectors(th, td, pd), cos_theta_i(th, td, pd).clamp_(min=0.0)
