"""Dense MERL tables from published NBRDF networks: the real materials of ``brdfkit demo``.

The raw MERL measurements (Matusik et al. 2003, "A Data-Driven Reflectance Model") may
not be redistributed, but the NBRDF networks their authors fitted to them may (Sztrajman,
Rainer, Ritschel and Weyrich 2021, "Neural BRDF Representation and Importance Sampling",
Computer Graphics Forum 40(6); MIT licence, ``brdfkit/data/README.md``). Each network is
a 6 -> 21 -> 21 -> 3 MLP: input the Rusinkiewicz half and difference unit vectors
``(hx, hy, hz, dx, dy, dz)`` with ``phi_h = 0`` (:func:`brdfkit.geometry.grid_hd`), ReLU,
ReLU, then ``max(exp(x) - 1, 0)``; output the RGB BRDF in 1/sr (MERL's colour scales
applied). Evaluated on the MERL grid it gives the closest stand-in for the measurement
that can be shipped: a smooth fit, without the measurement noise, with slightly softened
specular peaks.

The package ships the networks of four of the 20 test materials of the benchmark (never
seen by ``merl80-l40``, ``docs/models.md``): :data:`DEMO_WEIGHTS`, a NumPy ``.npz`` of
``names (M,)`` and stacked ``w1 (M, 6, 21)``, ``b1 (M, 21)``, ``w2 (M, 21, 21)``,
``b2 (M, 21)``, ``w3 (M, 21, 3)``, ``b3 (M, 3)``, float32, read without pickle.
"""

from __future__ import annotations

import os

import numpy as np

from brdfkit.errors import FormatError, InputError

__all__ = ["DEMO_WEIGHTS", "LAYERS", "MATERIAL_NOTES", "load_nbrdf_weights", "nbrdf_table", "material_names",
           "material_table", "write_material"]

DEMO_WEIGHTS = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "data", "nbrdf-merl-demo.npz")
"""The shipped networks: blue-metallic-paint, teflon, chrome-steel, violet-rubber."""

MATERIAL_NOTES = {
    "blue-metallic-paint": "coloured metallic flakes: a blue glossy lobe over a dark base",
    "teflon": "a bright, nearly white diffuser",
    "chrome-steel": "mirror-like: a very narrow, very high specular peak, black elsewhere",
    "violet-rubber": "a coloured rough dielectric with a faint broad sheen",
}
"""What each shipped material looks like (``brdfkit material --list``; ``brdfkit/data/README.md``)."""

LAYERS = {"w1": (6, 21), "b1": (21,), "w2": (21, 21), "b2": (21,), "w3": (21, 3), "b3": (3,)}
"""Each array of a network and its shape (the published NBRDF architecture)."""

# Rows per evaluation chunk: the (rows, 21) activations of a chunk stay in cache, which
# makes the ReLUs and the exponential several times faster than on the whole grid.
_CHUNK = 1 << 16


def load_nbrdf_weights(path: str | os.PathLike = DEMO_WEIGHTS) -> dict[str, dict[str, np.ndarray]]:
    """The networks of an NBRDF ``.npz`` (the format of :data:`DEMO_WEIGHTS`), by name.

    Returns
    -------
    dict
        ``{material: {"w1": ..., "b3": ...}}`` in the file's order, float32 arrays of the
        shapes in :data:`LAYERS`.

    Raises
    ------
    FormatError
        Not such a file (missing arrays, other shapes, non-finite weights); it is never
        unpickled.
    """
    path = os.fspath(path)
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
    except OSError as e:
        raise InputError(f"{path}: {e.strerror or e}") from None
    except ValueError as e:
        raise FormatError(path, f"not an NBRDF weights .npz ({e})") from None
    missing = [k for k in ("names", *LAYERS) if k not in arrays]
    if missing:
        raise FormatError(path, f"not an NBRDF weights .npz: no {', '.join(missing)}")
    names = arrays["names"]
    if names.ndim != 1 or names.dtype.kind != "U":
        raise FormatError(path, "'names' must be a 1-D array of strings")
    m = len(names)
    out = {}
    for key, shape in LAYERS.items():
        a = arrays[key]
        if a.shape != (m, *shape) or a.dtype.kind != "f" or not np.isfinite(a).all():
            raise FormatError(path, f"{key!r} must be finite floats of shape {(m, *shape)}, got {a.shape} {a.dtype}")
    for i, name in enumerate(names):
        out[str(name)] = {k: arrays[k][i].astype(np.float32) for k in LAYERS}
    return out


def nbrdf_table(net: dict[str, np.ndarray], device=None) -> np.ndarray:
    """The dense MERL table of one NBRDF network.

    Parameters
    ----------
    net
        ``{"w1": (6, 21), "b1": (21,), ..., "b3": (3,)}`` (:func:`load_nbrdf_weights`).
    device
        Torch device (:func:`brdfkit.runtime.resolve_device`; default CUDA when available).

    Returns
    -------
    numpy.ndarray
        float64 ``(90, 90, 180, 3)``, 1/sr, NaN below the horizon (the cells a MERL file
        marks -1, :func:`brdfkit.geometry.valid_cells`). Evaluated in float32 like the
        published networks; about 0.2 s on one CPU core (``docs/demo.md``).
    """
    import torch

    from brdfkit.runtime import resolve_device
    from brdfkit.geometry import N_CELLS, TABLE_SHAPE, grid_hd, valid_cells

    dev = resolve_device(device)
    cells = valid_cells()
    w = {k: torch.as_tensor(np.asarray(net[k], dtype=np.float32), device=dev) for k in LAYERS}
    x = torch.as_tensor(grid_hd()[cells], device=dev)
    rgb = torch.empty((len(cells), 3), dtype=torch.float32, device=dev)
    with torch.inference_mode():
        for s in range(0, len(cells), _CHUNK):
            a = torch.addmm(w["b1"], x[s:s + _CHUNK], w["w1"]).clamp_(min=0)
            a = torch.addmm(w["b2"], a, w["w2"]).clamp_(min=0)
            rgb[s:s + _CHUNK] = torch.addmm(w["b3"], a, w["w3"]).exp_().sub_(1.0).clamp_(min=0)
    table = np.full((N_CELLS, 3), np.nan)
    table[cells] = rgb.cpu().numpy()
    return table.reshape(TABLE_SHAPE)


def material_names(path: str | os.PathLike = DEMO_WEIGHTS) -> list[str]:
    """The materials of an NBRDF ``.npz`` (default the shipped four), in the file's order."""
    return list(load_nbrdf_weights(path))


def material_table(name: str, device="cpu", path: str | os.PathLike = DEMO_WEIGHTS) -> np.ndarray:
    """The dense MERL table of the shipped material ``name`` (:func:`nbrdf_table` of its
    network; ``brdfkit demo``'s ``materials/NAME.binary``).

    Parameters
    ----------
    name
        One of :func:`material_names`.
    device
        Torch device of the decode (default the CPU: 0.2 s, no GPU to start).
    path
        The NBRDF ``.npz`` (default :data:`DEMO_WEIGHTS`).

    Returns
    -------
    numpy.ndarray
        float64 ``(90, 90, 180, 3)``, 1/sr, NaN below the horizon.

    Raises
    ------
    InputError
        An unknown name; the message lists the known ones.
    """
    return nbrdf_table(_network(name, path), device=device)


def _network(name: str, path=DEMO_WEIGHTS) -> dict:
    """The arrays of material ``name``'s network; :class:`InputError` listing the known ones."""
    nets = load_nbrdf_weights(path)
    if name not in nets:
        raise InputError(f"unknown material {name!r}; the shipped ones are {', '.join(nets)} "
                         f"(brdfkit material --list)")
    return nets[name]


def write_material(name: str, output: str | os.PathLike | None = None, device="cpu") -> str:
    """Write the shipped material ``name`` as a MERL ``.binary`` table (34,992,012 bytes,
    atomically: :func:`brdfkit.io.merl.write_merl`): the work of ``brdfkit material``.

    Parameters
    ----------
    name
        One of :func:`material_names`.
    output
        The file (its name must end in ``.binary``), or an existing folder to write
        ``NAME.binary`` into; ``None``: ``NAME.binary`` in the working folder.
    device
        Torch device of the decode (:func:`material_table`).

    Returns
    -------
    str
        The path written.

    Raises
    ------
    InputError
        An unknown name, or an output that cannot be written (its folder missing, not
        writable, or a name not ending in ``.binary``); both before any work.
    """
    from brdfkit.atomic import refuse_overwrite_of_inputs
    from brdfkit.io.merl import write_merl

    net = _network(name)  # an unknown name before any work
    output = os.fspath(output) if output is not None else f"{name}.binary"
    if os.path.isdir(output):
        output = os.path.join(output, f"{name}.binary")
    if not output.lower().endswith(".binary"):
        raise InputError(f"{output}: brdfkit material writes a MERL table; name it .binary "
                         f"(brdfkit convert then makes an RGL .bsdf of it)")
    refuse_overwrite_of_inputs(output, [DEMO_WEIGHTS])
    write_merl(output, nbrdf_table(net, device=device))
    return output
