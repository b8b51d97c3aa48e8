"""Built-in models: bundles of pretrained files shipped inside the package, by name.

A *model* is what ``-m`` takes: a file, or the name of a built-in *bundle*. A bundle is a
set of *parts* (``network``, ``basis``, ``prior``, ``residual``: what each is as a file,
and the digest that names it, is :data:`brdfkit.models.parts.PARTS`), each one file
of the folder ``brdfkit/models/`` (or ``$BRDFKIT_BUILTIN_MODELS``, for tests and for
models kept elsewhere), listed in its ``manifest.json`` (``docs/models.md``):

::

    {"format": "brdfkit-builtin-models", "version": 2, "default": "merl-rgl-l40",
     "bundles": [{"name": "merl-rgl-l40", "latent_dim": 40, "materials": 151,
                  "parts": {"network": {"file": "merl-rgl-l40.safetensors", "digest": "3f2a..."},
                            "basis": {"file": "merl-rgl-basis.safetensors", "digest": "..."}},
                  "steps": 30000, "command": "brdfkit fit ...", "validation": {"40": 0.21},
                  "renders": {...}}]}

Version 1 manifests (``models``, with ``file`` / ``fingerprint``, ``prior`` /
``prior_fingerprint``, ``basis`` / ``basis_fingerprint``) still read. A bundle is
*installed* when all its parts' files are in the folder. Wherever a model is asked for, a
name resolves to the file of the part a job takes (:func:`resolve_part`); with none
given, an embedding finds the part whose digest it records (:func:`find_by_digest`),
anything else takes the manifest's default (:func:`default_bundle`). A resolved part is
checked against the digest the manifest records, so a damaged or replaced file is refused
(:class:`~brdfkit.errors.FormatError`).
"""

from __future__ import annotations

import dataclasses
import json
import os
import re

from brdfkit.atomic import atomic_open
from brdfkit.errors import FormatError, InputError
from brdfkit.models.parts import PARTS

__all__ = ["BUILTIN_ENV", "MANIFEST_FORMAT", "MANIFEST_VERSION", "PartEntry", "Bundle", "Manifest",
           "models_folder", "read_manifest", "installed_bundles", "is_path_spec", "find_bundle", "resolve_part",
           "resolve_network", "resolve_prior", "resolve_basis", "resolve_residual", "load_part", "default_bundle",
           "find_by_digest", "bundle_of_part", "is_builtin_part", "write_manifest"]

BUILTIN_ENV = "BRDFKIT_BUILTIN_MODELS"
MANIFEST = "manifest.json"
MANIFEST_FORMAT = "brdfkit-builtin-models"
MANIFEST_VERSION = 2
_READS = (1, 2)
_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]*\Z")
_HEX64 = re.compile(r"[0-9a-f]{64}\Z")
_V1_DIGEST = "fingerprint"  # version 1's name of a digest: keys fingerprint, basis_fingerprint, prior_fingerprint



@dataclasses.dataclass(frozen=True)
class PartEntry:
    """The manifest's entry of one part of a bundle: its ``file`` name in the folder, full
    ``path``, ``digest`` (64 hex digits: see the module's table) and its own held-out
    figures ``renders`` (as :attr:`Bundle.renders`; ``{}``: none). What the part is, is
    :data:`brdfkit.models.parts.PARTS`."""

    file: str
    path: str
    digest: str
    renders: dict = dataclasses.field(default_factory=dict)


@dataclasses.dataclass(frozen=True)
class Bundle:
    """One entry of the manifest: a built-in model.

    Attributes
    ----------
    name
        Its name (``-m NAME``).
    parts
        ``{part: PartEntry}`` (:data:`brdfkit.models.parts.PARTS` names the parts).
    latent_dim
        Size of its hypernetwork's latent, or ``None`` without a network.
    materials, materials_list
        Number of training materials, and the name of their list (or ``None``).
    steps, train_seconds, command
        Training steps, wall time (s) and the commands that trained it (or ``None``).
    validation
        ``{N: BRDF log RMSE}`` on held-out materials from ``N`` samples.
    renders
        The held-out figures as renders judge them: ``{"psnr": {key: dB}, "delta_e":
        {key: value}, "scenes": [...], "resolution": px, "materials": text}``, a key ``N``
        (sparse reconstruction from N samples) or ``"encode"`` / ``"encode-SIZE"``
        (compression); ``{}``: not measured.
    default, installed
        Whether it is the manifest's default, and whether all its parts' files are present.
    """

    name: str
    parts: dict
    latent_dim: int | None = None
    materials: int | None = None
    materials_list: str | None = None
    steps: int | None = None
    train_seconds: float | None = None
    command: str | None = None
    validation: dict = dataclasses.field(default_factory=dict)
    renders: dict = dataclasses.field(default_factory=dict)
    default: bool = False
    installed: bool = False

    def part(self, name: str) -> PartEntry | None:
        """Its part ``name`` (:data:`brdfkit.models.parts.PARTS`), or ``None``."""
        return self.parts.get(name)

    def to_json(self) -> dict:
        d = dataclasses.asdict(self)
        d["validation"] = {str(k): v for k, v in self.validation.items()}
        return d


@dataclasses.dataclass(frozen=True)
class Manifest:
    """The manifest of a built-in models folder: ``bundles`` in its order, installed or
    not; ``default`` the default's name (``None``: none)."""

    folder: str
    default: str | None
    bundles: tuple

    def installed(self) -> list[Bundle]:
        return [m for m in self.bundles if m.installed]


def models_folder() -> str:
    """``$BRDFKIT_BUILTIN_MODELS``, else the package's ``brdfkit/models``."""
    env = os.environ.get(BUILTIN_ENV)
    if env:
        return os.path.abspath(env)
    return os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "models")


def _v1_parts(d) -> dict:
    """A version 1 entry's parts, in version 2's shape."""
    parts = {"network": {"file": d.get("file"), "digest": d.get(_V1_DIGEST)}}
    for key in ("prior", "basis"):
        if d.get(key) is not None or d.get(f"{key}_{_V1_DIGEST}") is not None:
            parts[key] = {"file": d.get(key), "digest": d.get(f"{key}_{_V1_DIGEST}")}
    return parts


def _part(folder: str, name: str, p, bad) -> PartEntry:
    if name not in PARTS:
        raise bad(f"unknown part {name!r} (parts: {', '.join(PARTS)})")
    if not isinstance(p, dict):
        raise bad(f"part {name!r} must be an object")
    file, digest = p.get("file"), p.get("digest")
    if not isinstance(file, str) or os.path.basename(file) != file or not file.endswith(".safetensors"):
        raise bad(f"part {name!r}: 'file' must be a .safetensors file name in the folder")
    if not isinstance(digest, str) or not _HEX64.match(digest):
        raise bad(f"part {name!r}: 'digest' must be 64 lowercase hex digits")
    return PartEntry(file, os.path.join(folder, file), digest, _renders(p.get("renders"), bad))


def _entry(where: str, folder: str, d, default: str | None, version: int) -> Bundle:
    if not isinstance(d, dict):
        raise FormatError(where, "each entry of 'bundles' must be an object")

    def bad(msg):
        return FormatError(where, f"model {d.get('name')!r}: {msg}")

    name = d.get("name")
    if not isinstance(name, str) or not _NAME.match(name) or name.lower().endswith(".safetensors"):
        raise bad("'name' must be a word of letters, digits, '.', '_' or '-'")
    raw = _v1_parts(d) if version == 1 else d.get("parts")
    if not isinstance(raw, dict) or not raw:
        raise bad("'parts' must map part names to {'file', 'digest'}")
    parts = {k: _part(folder, k, v, bad) for k, v in raw.items()}
    latent = d.get("latent_dim")
    if ("network" in parts or latent is not None) and (isinstance(latent, bool) or not isinstance(latent, int)
                                                       or latent < 1):
        raise bad("'latent_dim' must be a positive whole number")
    mats = d.get("materials")
    if isinstance(mats, list):
        mats = len(mats)
    for key, types, value in (("materials", int, mats), ("steps", int, d.get("steps")),
                              ("train_seconds", (int, float), d.get("train_seconds")),
                              ("materials_list", str, d.get("materials_list")), ("command", str, d.get("command"))):
        if value is not None and (isinstance(value, bool) or not isinstance(value, types)):
            raise bad(f"'{key}' has the wrong type")
    val = d.get("validation") or {}
    try:
        validation = {int(k): float(v) for k, v in val.items()}
    except (AttributeError, TypeError, ValueError):
        raise bad("'validation' must map sample counts to log RMSE values") from None
    return Bundle(name=name, parts=parts, latent_dim=latent, materials=mats, materials_list=d.get("materials_list"),
                  steps=d.get("steps"), train_seconds=d.get("train_seconds"), command=d.get("command"),
                  validation=dict(sorted(validation.items())), renders=_renders(d.get("renders"), bad),
                  default=name == default, installed=all(os.path.isfile(p.path) for p in parts.values()))


def _renders(r, bad) -> dict:
    """An entry's (or a part's) ``renders`` checked (see :class:`Bundle`)."""
    if r is None:
        return {}
    ok = isinstance(r, dict) and all(isinstance(r.get(k, {}), dict) for k in ("psnr", "delta_e"))
    ok = ok and all(isinstance(v, (int, float)) and not isinstance(v, bool)
                    for k in ("psnr", "delta_e") for v in r.get(k, {}).values())
    if not ok:
        raise bad("'renders' must hold 'psnr' and 'delta_e' maps of numbers")
    return dict(r)


def read_manifest(folder: str | os.PathLike | None = None) -> Manifest:
    """The manifest of ``folder`` (default :func:`models_folder`); no manifest there:
    no built-in models.

    Raises
    ------
    FormatError
        A manifest that is not JSON, not this format or a version this brdfkit reads, or
        has a bad entry (one line naming the manifest).
    """
    folder = os.path.abspath(os.fspath(folder)) if folder is not None else models_folder()
    where = os.path.join(folder, MANIFEST)
    if not os.path.isfile(where):
        return Manifest(folder, None, ())
    try:
        with open(where, encoding="utf-8") as f:
            doc = json.load(f)
    except (OSError, UnicodeDecodeError, ValueError) as e:
        raise FormatError(where, f"not a built-in models manifest ({e})") from None
    if not isinstance(doc, dict) or doc.get("format") != MANIFEST_FORMAT:
        raise FormatError(where, f"not a built-in models manifest (format {MANIFEST_FORMAT!r} expected)")
    version = doc.get("version")
    if version not in _READS:
        raise FormatError(where, f"manifest version {version!r} is not supported "
                                 f"(this brdfkit reads versions {', '.join(map(str, _READS))})")
    default, entries = doc.get("default"), doc.get("bundles" if version == 2 else "models")
    if default is not None and not isinstance(default, str):
        raise FormatError(where, "'default' must be a model name")
    if not isinstance(entries, list):
        raise FormatError(where, f"'{'bundles' if version == 2 else 'models'}' must be a list")
    bundles = tuple(_entry(where, folder, d, default, version) for d in entries)
    names = [m.name for m in bundles]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise FormatError(where, f"model name {dup[0]!r} appears twice")
    return Manifest(folder, default, bundles)


def installed_bundles() -> list[Bundle]:
    """The installed built-in bundles, in the manifest's order."""
    return read_manifest().installed()


def is_path_spec(spec: str | os.PathLike) -> bool:
    """Whether a ``-m`` value means a file rather than a built-in name: it exists, holds
    a path separator, or ends with ``.safetensors``."""
    text = os.fspath(spec)
    return (os.path.exists(text) or any(sep in text for sep in ("/", os.sep, os.altsep) if sep)
            or text.lower().endswith(".safetensors"))


def _checked(m: Bundle, part: str) -> str:
    """The path of an installed bundle's ``part`` file after checking it against the
    digest the manifest records (by the part's rule, :meth:`brdfkit.models.parts.Part.recorded_digest`)."""
    p = m.parts[part]
    if not os.path.isfile(p.path):
        raise InputError(f"built-in model {m.name!r}: its file {p.file} is not installed")
    recorded = PARTS[part].recorded_digest(p.path)
    if recorded != p.digest:
        raise FormatError(p.path, f"built-in model {m.name!r}: the file's digest is {str(recorded)[:12]}, the "
                                  f"manifest's {p.digest[:12]}: the file is damaged or was replaced")
    return p.path


def _unknown(spec: str, installed: list[Bundle]) -> InputError:
    if installed:
        names = ", ".join(m.name for m in installed)
        return InputError(f"unknown model {spec!r}: no such file, and not a built-in model "
                          f"(built-in: {names}; `brdfkit models` lists them)")
    return InputError(f"unknown model {spec!r}: no such file, and no built-in models are installed "
                      "(pass a model file made by `brdfkit fit`)")


def find_bundle(name: str) -> Bundle:
    """The installed built-in called ``name``.

    Raises
    ------
    InputError
        No installed built-in of that name (one line listing those installed).
    """
    installed = installed_bundles()
    found = next((m for m in installed if m.name == name), None)
    if found is None:
        raise _unknown(name, installed)
    return found


def resolve_part(spec: str | os.PathLike, part: str) -> str:
    """The file of ``part`` (a name of :data:`brdfkit.models.parts.PARTS`) that a
    ``-m`` value names: a path as it is (:func:`is_path_spec`), else that part of the
    installed built-in of that name, its digest checked.

    Raises
    ------
    InputError
        Neither a file nor an installed built-in (one line listing the built-in names),
        or a built-in without that part (naming those that have it).
    FormatError
        The built-in's file records another digest than the manifest.
    """
    if is_path_spec(spec):
        return os.fspath(spec)
    m = find_bundle(os.fspath(spec))
    if m.part(part) is None:
        having = ", ".join(e.name for e in installed_bundles() if e.part(part)) or "none installed"
        raise InputError(f"built-in model {m.name!r} ships no {PARTS[part].label} (built-ins with one: "
                         f"{having}; `brdfkit models` lists them)")
    return _checked(m, part)


def resolve_network(spec: str | os.PathLike) -> str:
    """The hypernetwork file a ``-m`` value names (:func:`resolve_part`)."""
    return resolve_part(spec, "network")


def resolve_prior(spec: str | os.PathLike) -> str:
    """The learnt-prior file a ``-m`` value names (:func:`resolve_part`)."""
    return resolve_part(spec, "prior")


def resolve_basis(spec: str | os.PathLike) -> str:
    """The PCA basis file a ``-m`` value names (:func:`resolve_part`)."""
    return resolve_part(spec, "basis")


def resolve_residual(spec: str | os.PathLike) -> str:
    """The basis-residual file a ``-m`` value names (:func:`resolve_part`)."""
    return resolve_part(spec, "residual")


def load_part(spec: str | os.PathLike, part: str, device="cpu"):
    """Part ``part`` (a name of :data:`brdfkit.models.parts.PARTS`) of the model ``spec`` (a
    built-in's name or a file), loaded and checked: a built-in's file against the
    manifest's digest (:func:`resolve_part`), a file against the digest it records."""
    return PARTS[part].load(resolve_part(spec, part), device)[0]


def default_bundle() -> Bundle | None:
    """The manifest's default bundle if it is installed, else ``None``."""
    return next((m for m in installed_bundles() if m.default), None)


def find_by_digest(digest: str | None) -> str | None:
    """The installed built-in part whose digest is ``digest`` (the decoder an embedding
    records), checked, or ``None``."""
    if not digest:
        return None
    for m in installed_bundles():
        for part, p in m.parts.items():
            if p.digest == digest:
                return _checked(m, part)
    return None


def bundle_of_part(path: str | os.PathLike, part: str):
    """The installed built-in (:class:`Bundle`) whose ``part`` file ``path`` is, or ``None``."""
    real = os.path.realpath(os.fspath(path))
    return next((m for m in installed_bundles() if m.part(part) and os.path.realpath(m.parts[part].path) == real),
                None)


def is_builtin_part(path: str | os.PathLike, part: str) -> bool:
    """Whether ``path`` is the ``part`` file of an installed built-in."""
    return bundle_of_part(path, part) is not None


def write_manifest(folder: str | os.PathLike, entries: list[dict], default: str | None) -> str:
    """Write ``manifest.json`` (version 2) into ``folder`` atomically, its entries
    checked first."""
    doc = {"format": MANIFEST_FORMAT, "version": MANIFEST_VERSION, "default": default, "bundles": entries}
    path = os.path.join(os.fspath(folder), MANIFEST)
    for d in entries:  # refused before anything is written
        _entry(path, os.fspath(folder), d, default, MANIFEST_VERSION)
    with atomic_open(path, "w", encoding="utf-8") as f:
        f.write(json.dumps(doc, indent=1) + "\n")
    return path
