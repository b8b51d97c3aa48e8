"""Image files: linear float32 OpenEXR and tone-mapped sRGB PNG.

EXR holds scene-referred linear-sRGB radiance, float32, channels ``R, G, B`` (ZIP
compression). PNG holds the display image of :func:`brdfkit.render.display.display_encode`:
radiance times :data:`brdfkit.render.display.EXPOSURE` (1.0), clipped to ``[0, 1]``, sRGB OETF,
quantised to 8 bits; the same encoding the image metrics see, so a PNG shows what PSNR
and SSIM compare. Both writers are atomic (:func:`brdfkit.atomic.atomic_path`).
"""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile

import numpy as np

from brdfkit.atomic import atomic_path, check_input_file
from brdfkit.errors import FormatError, InputError

__all__ = ["write_exr", "read_exr", "write_png", "is_exr_file"]

_EXR_MAGIC = b"\x76\x2f\x31\x01"


def _as_rgb(image, what: str) -> np.ndarray:
    img = np.asarray(image, dtype=np.float32)
    if img.ndim != 3 or img.shape[-1] != 3 or min(img.shape[:2]) < 1:
        raise InputError(f"{what}: image of shape {img.shape}, expected (H, W, 3)")
    return np.ascontiguousarray(img)


def is_exr_file(path) -> bool:
    """True if ``path`` starts with the OpenEXR magic number."""
    try:
        with open(path, "rb") as f:
            return f.read(4) == _EXR_MAGIC
    except OSError:
        return False


def write_exr(path, image) -> None:
    """Write a linear RGB image ``(H, W, 3)`` as float32 OpenEXR, atomically.

    Raises
    ------
    InputError
        Not an ``(H, W, 3)`` image, or non-finite pixels.
    """
    import OpenEXR

    img = _as_rgb(image, os.fspath(path))
    if not np.isfinite(img).all():
        raise InputError(f"{os.fspath(path)}: image holds NaN or infinite pixels")
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    channels = {"R": img[..., 0].copy(), "G": img[..., 1].copy(), "B": img[..., 2].copy()}
    with atomic_path(path) as tmp:
        OpenEXR.File(header, channels).write(tmp)


@contextlib.contextmanager
def _library_output():
    """Capture what C code prints to file descriptors 1 and 2 while the block runs;
    yields a list that holds its lines afterwards.

    The OpenEXR library reports a damaged file by printing lines such as
    ``x.exr: (EXR_ERR_BAD_CHUNK_LEADER) ...`` to stderr and ``Warning: Exception raised
    reading pixel data ...`` to stdout, around or instead of a Python exception: a user
    got three lines instead of one, and ``--json`` output on stdout was broken (found by
    ``benchmarks/fuzz_parsers.py``; docs/stability.md).
    """
    lines: list[str] = []
    try:
        sys.stdout.flush()
        sys.stderr.flush()
        saved = (os.dup(1), os.dup(2))
    except (OSError, ValueError):  # no usable descriptors: nothing to capture
        yield lines
        return
    with tempfile.TemporaryFile() as tmp:
        os.dup2(tmp.fileno(), 1)
        os.dup2(tmp.fileno(), 2)
        try:
            yield lines
        finally:
            for fd, old in zip((1, 2), saved):
                os.dup2(old, fd)
                os.close(old)
            tmp.seek(0)
            lines.extend(ln.strip() for ln in tmp.read().decode("utf-8", "replace").splitlines() if ln.strip())


def read_exr(path) -> np.ndarray:
    """Read an OpenEXR image as linear float32 ``(H, W, 3)``.

    Channels ``R, G, B`` are used (any layer prefix such as Mitsuba's is accepted if it is
    the only one); a single ``Y`` channel is repeated to grey. Half floats are widened.

    Raises
    ------
    FormatError
        Not an OpenEXR file, unreadable, or without RGB / Y channels.
    """
    import OpenEXR

    path = check_input_file(path)
    if not is_exr_file(path):
        raise FormatError(path, "not an OpenEXR image (bad magic number)")
    try:
        with _library_output() as said, OpenEXR.File(path, separate_channels=True) as f:
            chans = {name: np.asarray(c.pixels) for name, c in f.channels().items()}
    except Exception as e:  # OpenEXR raises RuntimeError with a vague message
        raise FormatError(path, f"cannot read OpenEXR image ({_library_reason(said) or e})") from None
    if said:  # pixel data it could not read, reported as a warning only
        raise FormatError(path, f"cannot read OpenEXR image ({_library_reason(said)})")
    short = {name.rsplit(".", 1)[-1]: a for name, a in chans.items()}
    if all(c in short for c in "RGB"):
        img = np.stack([short[c] for c in "RGB"], -1)
    elif "Y" in short:
        img = np.repeat(short["Y"][..., None], 3, -1)
    else:
        raise FormatError(path, f"OpenEXR image without R, G, B or Y channels (has {sorted(chans)})")
    img = img.astype(np.float32)
    if not np.isfinite(img).all():
        raise FormatError(path, "OpenEXR image holds NaN or infinite pixels")
    return img


def _library_reason(lines: list[str]) -> str:
    """The first error the OpenEXR library printed, as ``EXR_ERR_CODE: text``."""
    for line in lines:
        if "(EXR_ERR_" in line:
            code, _, text = line[line.index("(EXR_ERR_") + 1:].partition(") ")
            return f"{code}: {text}"
    return lines[0] if lines else ""


def write_png(path, image) -> None:
    """Write the display encoding of a linear RGB image as an 8-bit sRGB PNG, atomically
    (see the module docstring for the tone mapping)."""
    from PIL import Image

    from brdfkit.render.display import display_encode

    img = _as_rgb(image, os.fspath(path))
    if not np.isfinite(img).all():
        raise InputError(f"{os.fspath(path)}: image holds NaN or infinite pixels")
    u8 = np.round(display_encode(img) * 255.0).astype(np.uint8)
    with atomic_path(path) as tmp:
        Image.fromarray(u8, "RGB").save(tmp, format="PNG", optimize=True)
