"""A PCA basis plus a hypernetwork residual: :class:`BasisResidual`.

A material of ``K`` coefficients per channel ``c`` decodes, channel by channel, to the
mapped table (:mod:`brdfkit.basis.mapping`)::

    x'(cell) = mean + U_K c + sum_m g_m f_m(HD(cell); W_m(c / sigma))

the basis's closed form plus, for each *member* ``m`` (the networks that serve ``K``
components: a file may hold several, :mod:`brdfkit.residual.network`), ``g_m`` times its
correction. The gains are the embedding's options (:func:`gains`): ``correction`` is member
0's, ``correction.M`` member ``M``'s; the encoder sets the one member it chose to 1 (or
every gain to 0: the basis alone), and a blend of two materials blends the gains, so a blend
of two members is the blend of their corrections. Channels are separate observations, as
they are to the basis. Decoding is NumPy only.
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np

from brdfkit.errors import InputError
from brdfkit.residual.network import evaluate, hyponet_weights, net_input

__all__ = ["BasisResidual", "OPTION_DEFAULTS", "gains", "gain_options", "offered_sizes", "components_of"]

OPTION_DEFAULTS = {"correction": 1.0}
"""The decode options an embedding may leave out that are not 0 then: member 0's gain
(embeddings written before the members were one network's, always on)."""


def gains(options: dict | None) -> dict:
    """``{member: gain}`` of an embedding's options: ``correction`` (member 0; 1 when
    absent) and ``correction.M`` (member ``M``), the zero gains left out.

    Examples
    --------
    >>> gains({"correction": 0.0, "correction.2": 1.0})
    {2: 1.0}
    >>> gains(None)
    {0: 1.0}
    """
    options = options or {}
    out = {0: float(options.get("correction", OPTION_DEFAULTS["correction"]))}
    for key, value in options.items():
        if key.startswith("correction."):
            out[int(key.split(".", 1)[1])] = float(value)
    return {m: g for m, g in sorted(out.items()) if g}


def gain_options(member: int | None) -> dict:
    """The options of an embedding whose correction is member ``member``'s (``None``: the
    basis alone).

    Examples
    --------
    >>> gain_options(None), gain_options(0), gain_options(2)
    ({'correction': 0.0}, {'correction': 1.0}, {'correction': 0.0, 'correction.2': 1.0})
    """
    if member is None:
        return {"correction": 0.0}
    return {"correction": 1.0} if member == 0 else {"correction": 0.0, f"correction.{member}": 1.0}


def components_of(configs, n_components: int) -> tuple:
    """The numbers of components (ascending) that networks of ``configs`` decode with a
    basis of ``n_components``.

    Examples
    --------
    >>> from brdfkit.residual.network import ResidualConfig
    >>> components_of([ResidualConfig(3, 3), ResidualConfig(7, 7, member=1)], 30)
    (3, 7)
    """
    return tuple(sorted({k for cfg in configs for k in range(cfg.k_min, cfg.k_max + 1) if k <= n_components}))


def offered_sizes(components, offered) -> tuple:
    """The sizes ``encode`` offers (ascending): ``3 K`` for each of ``components``, those of
    ``offered`` alone when the file records any.

    Examples
    --------
    >>> offered_sizes((3, 7, 13), ()), offered_sizes((3, 7, 13), (9, 39))
    ((9, 21, 39), (9, 39))
    """
    served = tuple(3 * k for k in components)
    return tuple(s for s in served if s in offered) if offered else served


@functools.lru_cache(maxsize=2)
def _cell_hd(cells_key: bytes, n: int) -> np.ndarray:
    from brdfkit.geometry import grid_hd

    cells = np.frombuffer(cells_key, dtype=np.int64, count=n)
    return np.ascontiguousarray(grid_hd()[cells])


PIECE_CELLS = 16384
"""Cells of one piece of a correction's evaluation (a channel's hyponet at that many cells;
:func:`brdfkit.residual.network.evaluate`'s block), the pieces on
:func:`brdfkit.runtime.thread_map`'s threads."""


def _as_gains(gain) -> dict:
    """``{member: gain}`` of a gain (member 0's) or of such a dict, the zero gains left out."""
    g = gain if isinstance(gain, dict) else {0: float(gain)}
    return {m: v for m, v in g.items() if v}


@dataclasses.dataclass
class BasisResidual:
    """A basis and the residual network that corrects it.

    Attributes
    ----------
    basis
        :class:`~brdfkit.basis.model.PcaBasis` (all its components).
    basis_digest
        SHA-256 of the basis file (what the residual was trained on).
    nets
        ``[(ResidualConfig, state)]``: the networks, each serving the component counts of
        its config (one a size, the shipped way: ``docs/notes/compression.md``), its
        tensors by name as float32 NumPy arrays.
    offered
        The sizes (numbers per material, ``3 K``) ``encode`` offers it at: where it won
        on held-out materials (the file records them); the rest of ``cfg``'s range still
        decodes.
    meta
        The training record (materials, steps, seed, command).
    """

    basis: object
    basis_digest: str
    nets: list
    offered: tuple = ()
    meta: dict = dataclasses.field(default_factory=dict)

    @property
    def components(self) -> tuple:
        """The numbers of components it decodes, ascending (its networks', within the basis's)."""
        return components_of([cfg for cfg, _ in self.nets], self.basis.n_components)

    def sizes(self) -> tuple:
        """Sizes ``encode`` offers (ascending): ``3 K`` for each ``K`` it decodes, less those
        its file does not offer (:func:`offered_sizes`)."""
        return offered_sizes(self.components, self.offered)

    def check_k(self, k: int) -> None:
        if k not in self.components:
            shown = ", ".join(str(3 * c) for c in self.components)
            raise InputError(f"this basis residual decodes embeddings of {shown} numbers, not {3 * k}")

    def members(self, k: int) -> tuple:
        """The members (ascending) of the networks that serve ``k`` components."""
        self.check_k(k)
        return tuple(sorted({cfg.member for cfg, _ in self.nets if cfg.k_min <= k <= cfg.k_max}))

    def net_for(self, k: int, member: int = 0) -> tuple:
        """``(index, cfg, state)`` of member ``member``'s network that serves ``k``
        components (the narrowest when several do)."""
        self.check_k(k)
        found = [(cfg.k_max - cfg.k_min, i) for i, (cfg, _) in enumerate(self.nets)
                 if cfg.k_min <= k <= cfg.k_max and cfg.member == member]
        if not found:
            raise InputError(f"this basis residual has no member {member} for {3 * k} numbers "
                             f"(members {', '.join(map(str, self.members(k)))})")
        i = min(found)[1]
        return (i, *self.nets[i])

    def cell_hd(self) -> np.ndarray:
        """float32 ``(P, 6)`` HD vectors of the basis's cells (cached)."""
        cells = np.ascontiguousarray(self.basis.cells, dtype=np.int64)
        return _cell_hd(cells.tobytes(), cells.size)

    def correction(self, coefficients: np.ndarray, hd: np.ndarray | None = None, member=0) -> np.ndarray:
        """The mapped correction ``(N, 3)`` float32 of coefficients ``(K, 3)`` at HD
        vectors ``hd (N, 6)`` (default: every cell of the basis), of one member or of the
        gains ``{member: gain}`` (:func:`gains`) summed."""
        if isinstance(member, dict):
            parts = [np.float32(g) * self.correction(coefficients, hd, m) for m, g in member.items()]
            return sum(parts[1:], parts[0]) if parts else None
        c = np.asarray(coefficients, np.float64)
        _, cfg, state = self.net_for(c.shape[0], member)
        z = net_input((c / self.basis.sigma[:c.shape[0], None].astype(np.float64)).T, cfg.k_max)
        from brdfkit.runtime import thread_map

        hd = self.cell_hd() if hd is None else hd
        weights = hyponet_weights(state, cfg, z)
        out = np.empty((hd.shape[0], 3), np.float32)

        def piece(p):  # a channel at PIECE_CELLS cells: evaluate's own blocks, the same bytes on any threads
            ch, s = p
            out[s:s + PIECE_CELLS, ch] = evaluate(weights, hd[s:s + PIECE_CELLS], ch, PIECE_CELLS)

        list(thread_map(piece, [(ch, s) for ch in range(3) for s in range(0, hd.shape[0], PIECE_CELLS)]))
        return out

    def correction_channel(self, coefficients: np.ndarray, hd: np.ndarray, member: int = 0) -> np.ndarray:
        """One channel's mapped correction ``(N,)`` float32 of its coefficients ``(K,)`` at
        HD vectors ``hd (N, 6)`` (each channel's correction depends on its own
        coefficients alone)."""
        c = np.asarray(coefficients, np.float64)
        _, cfg, state = self.net_for(c.shape[0], member)
        z = net_input((c / self.basis.sigma[:c.shape[0]].astype(np.float64))[None], cfg.k_max)
        return evaluate(hyponet_weights(state, cfg, z), hd, 0)

    def mapped(self, coefficients: np.ndarray, gain=1.0) -> np.ndarray:
        """Mapped values ``(P, 3)`` at the basis's cells, the mean included; ``gain`` member
        0's gain, or the gains ``{member: gain}`` (:func:`gains`)."""
        c = np.asarray(coefficients, np.float32)
        out = self.basis.leading(c.shape[0]).mapped_values(c)
        g = _as_gains(gain)
        if g:
            out = out + self.correction(c, None, g)
        return out

    def decode_at(self, coefficients: np.ndarray, cells, gain=1.0) -> tuple:
        """:meth:`decode` at some cells only: ``(at, values)``, the flat MERL ``cells``
        the basis covers (ascending) and the BRDF there, float64 ``(n, 3)``, 1/sr (the
        hyponet evaluated at those cells alone)."""
        from brdfkit.geometry import grid_hd

        c = np.asarray(coefficients, np.float32)
        part = self.basis.leading(c.shape[0])
        cells = np.unique(np.asarray(cells, np.int64))
        pos = np.searchsorted(part.cells, cells).clip(0, part.cells.size - 1)
        hit = part.cells[pos] == cells
        pos, at = pos[hit], cells[hit]
        mapped = part.mean[pos, None] + part.rows_at(pos).T @ c
        g = _as_gains(gain)
        if g:
            mapped = mapped + self.correction(c, np.ascontiguousarray(grid_hd()[at]), g)
        ref = part.reference[pos, None].astype(np.float64)
        return at, part.mapping.from_mapped(mapped, part.cell_weight(at)[:, None], ref)

    def decode(self, coefficients: np.ndarray, gain=1.0) -> np.ndarray:
        """Dense table float64 ``(90, 90, 180, 3)``, 1/sr, ``> 0``, NaN off the basis's
        cells."""
        return self.basis.decode_mapped(self.mapped(coefficients, gain))
