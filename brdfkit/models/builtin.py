"""Built-in models: pretrained model files shipped inside the package, by name.

The folder ``brdfkit/models/`` (or ``$BRDFKIT_BUILTIN_MODELS``, for tests and for models
kept elsewhere) holds model files and ``manifest.json`` (``docs/models.md``)::

    {"format": "brdfkit-builtin-models", "version": 1, "default": "merl-rgl-l40",
     "models": [{"name": "merl-rgl-l40", "file": "merl-rgl-l40.safetensors",
                 "latent_dim": 40, "materials": 151, "materials_list": "MERL + RGL",
                 "steps": 30000, "train_seconds": 3000.0, "command": "brdfkit fit ...",
                 "validation": {"40": 0.21, "400": 0.13, "4000": 0.12},
                 "fingerprint": "3f2a..."}]}

A built-in model is *installed* when its file is in the folder. It has up to three parts:
its hypernetwork (``file``), and optionally a learnt prior (``prior``) and the PCA basis
that prior is fitted with (``basis``), each recorded with its SHA-256. Wherever a model is
asked for (``-m``, ``$BRDFKIT_MODEL``), a name resolves to the file of the part a job
takes (:func:`resolve_model`, :func:`resolve_prior`, :func:`resolve_basis`); with none
given, an embedding finds the part whose digest it records (:func:`find_by_digest`),
anything else takes the manifest's default (:func:`default_model`). A resolved part is
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

__all__ = ["BUILTIN_ENV", "MANIFEST_FORMAT", "MANIFEST_VERSION", "BuiltinModel", "Manifest", "models_folder",
           "read_manifest", "builtin_models", "is_path_spec", "resolve_model", "default_model",
           "find_by_digest", "resolve_prior", "resolve_basis", "is_builtin_basis", "write_manifest"]

BUILTIN_ENV = "BRDFKIT_BUILTIN_MODELS"
MANIFEST = "manifest.json"
MANIFEST_FORMAT = "brdfkit-builtin-models"
MANIFEST_VERSION = 1
_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]*\Z")
_HEX64 = re.compile(r"[0-9a-f]{64}\Z")


@dataclasses.dataclass(frozen=True)
class BuiltinModel:
    """One entry of the manifest.

    Attributes
    ----------
    name, file, path
        Its name (``-m NAME``), file name in the folder, and full path.
    latent_dim
        Size of its embeddings.
    fingerprint
        sha256 hex of its weights (:func:`brdfkit.hypernet.model_file.weights_fingerprint`).
    materials, materials_list
        Number of training materials, and the name of their list (or ``None``).
    steps, train_seconds, command
        Training steps, wall time (s) and the command that trained it (or ``None``).
    validation
        ``{N: BRDF log RMSE}`` on held-out materials from ``N`` samples.
    renders
        The held-out figures as renders judge them: ``{"psnr": {key: dB}, "delta_e":
        {key: value}, "scenes": [...], "resolution": px, "materials": text}``, a key ``N``
        (sparse reconstruction from N samples) or ``"encode"`` (compression); ``{}``: not
        measured.
    default, installed
        Whether it is the manifest's default, and whether its file is present.
    prior, prior_fingerprint
        Its learnt-prior file (a bare name in the folder) and that model's fingerprint, or
        ``None``.
    basis, basis_fingerprint
        The PCA basis file its learnt prior is fitted with (a bare name) and the SHA-256 of
        its bytes, or ``None``.
    """

    name: str
    file: str
    path: str
    latent_dim: int
    fingerprint: str
    materials: int | None = None
    materials_list: str | None = None
    steps: int | None = None
    train_seconds: float | None = None
    command: str | None = None
    validation: dict = dataclasses.field(default_factory=dict)
    renders: dict = dataclasses.field(default_factory=dict)
    default: bool = False
    installed: bool = False
    prior: str | None = None
    prior_fingerprint: str | None = None
    basis: str | None = None
    basis_fingerprint: str | None = None

    def to_json(self) -> dict:
        d = dataclasses.asdict(self)
        d["validation"] = {str(k): v for k, v in self.validation.items()}
        return d


@dataclasses.dataclass(frozen=True)
class Manifest:
    """The manifest of a built-in models folder: ``models`` in its order, installed or
    not; ``default`` the default's name (``None``: none)."""

    folder: str
    default: str | None
    models: tuple

    def installed(self) -> list[BuiltinModel]:
        return [m for m in self.models if m.installed]


def models_folder() -> str:
    """``$BRDFKIT_BUILTIN_MODELS``, else the package's ``brdfkit/models``."""
    env = os.environ.get(BUILTIN_ENV)
    if env:
        return os.path.abspath(env)
    return os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "models")


def _entry(where: str, folder: str, d, default: str | None) -> BuiltinModel:
    if not isinstance(d, dict):
        raise FormatError(where, "each entry of 'models' must be an object")

    def bad(msg):
        return FormatError(where, f"model {d.get('name')!r}: {msg}")

    name, file, fp = d.get("name"), d.get("file"), d.get("fingerprint")
    if not isinstance(name, str) or not _NAME.match(name) or name.lower().endswith(".safetensors"):
        raise bad("'name' must be a word of letters, digits, '.', '_' or '-'")
    if not isinstance(file, str) or os.path.basename(file) != file or not file.endswith(".safetensors"):
        raise bad("'file' must be a .safetensors file name in the folder")
    if not isinstance(fp, str) or not _HEX64.match(fp):
        raise bad("'fingerprint' must be 64 lowercase hex digits")
    latent = d.get("latent_dim")
    if isinstance(latent, bool) or not isinstance(latent, int) or latent < 1:
        raise bad("'latent_dim' must be a positive whole number")
    mats = d.get("materials")
    if isinstance(mats, list):
        mats = len(mats)
    for key, kinds, value in (("materials", int, mats), ("steps", int, d.get("steps")),
                              ("train_seconds", (int, float), d.get("train_seconds")),
                              ("materials_list", str, d.get("materials_list")), ("command", str, d.get("command"))):
        if value is not None and (isinstance(value, bool) or not isinstance(value, kinds)):
            raise bad(f"'{key}' has the wrong type")
    val = d.get("validation") or {}
    try:
        validation = {int(k): float(v) for k, v in val.items()}
    except (AttributeError, TypeError, ValueError):
        raise bad("'validation' must map sample counts to log RMSE values") from None
    renders = _renders(d.get("renders"), bad)
    parts = {key: _part(d, key, bad) for key in ("prior", "basis")}
    path = os.path.join(folder, file)
    return BuiltinModel(prior=parts["prior"][0], prior_fingerprint=parts["prior"][1], basis=parts["basis"][0],
                        basis_fingerprint=parts["basis"][1], name=name, file=file, path=path, latent_dim=latent, fingerprint=fp, materials=mats,
                        materials_list=d.get("materials_list"), steps=d.get("steps"),
                        train_seconds=d.get("train_seconds"), command=d.get("command"),
                        validation=dict(sorted(validation.items())), renders=renders, default=name == default,
                        installed=os.path.isfile(path))


def _part(d, key: str, bad) -> tuple:
    """An entry's optional part ``key`` (``"prior"``, ``"basis"``): ``(file, digest)``, or
    ``(None, None)``."""
    file, digest = d.get(key), d.get(f"{key}_fingerprint")
    if file is not None and (not isinstance(file, str) or os.path.basename(file) != file
                             or not file.endswith(".safetensors")):
        raise bad(f"'{key}' must be a .safetensors file name in the folder")
    if (file is None) != (digest is None) or (digest is not None and not (isinstance(digest, str)
                                                                          and _HEX64.match(digest))):
        raise bad(f"'{key}' and '{key}_fingerprint' (64 lowercase hex digits) go together")
    return file, digest


def _renders(r, bad) -> dict:
    """An entry's ``renders`` checked (see :class:`BuiltinModel`)."""
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
        A manifest that is not JSON, not this format or version, or has a bad entry (one
        line naming the manifest).
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
    if doc.get("version") != MANIFEST_VERSION:
        raise FormatError(where, f"manifest version {doc.get('version')!r} is not supported "
                                 f"(this brdfkit reads version {MANIFEST_VERSION})")
    default, models = doc.get("default"), doc.get("models")
    if default is not None and not isinstance(default, str):
        raise FormatError(where, "'default' must be a model name")
    if not isinstance(models, list):
        raise FormatError(where, "'models' must be a list")
    entries = tuple(_entry(where, folder, d, default) for d in models)
    names = [m.name for m in entries]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise FormatError(where, f"model name {dup[0]!r} appears twice")
    return Manifest(folder, default, entries)


def builtin_models() -> list[BuiltinModel]:
    """The installed built-in models, in the manifest's order."""
    return read_manifest().installed()


def is_path_spec(spec: str | os.PathLike) -> bool:
    """Whether a ``-m`` value means a file rather than a built-in name: it exists, holds
    a path separator, or ends with ``.safetensors``."""
    text = os.fspath(spec)
    return (os.path.exists(text) or any(sep in text for sep in ("/", os.sep, os.altsep) if sep)
            or text.lower().endswith(".safetensors"))


def _checked(m: BuiltinModel, part: str = "model") -> str:
    """The path of an installed built-in's ``part`` file (``"model"``, its hypernetwork;
    ``"prior"``, its learnt prior; ``"basis"``, its PCA basis) after checking it against
    the digest the manifest records: the fingerprint a model file records in its header
    (loading then checks the weights against it), a basis file's SHA-256."""
    from brdfkit.io.tensorfile import open_safetensors

    file, want = {"model": (m.file, m.fingerprint), "prior": (m.prior, m.prior_fingerprint),
                  "basis": (m.basis, m.basis_fingerprint)}[part]
    path = os.path.join(os.path.dirname(m.path), file)
    if not os.path.isfile(path):
        raise InputError(f"built-in model {m.name!r}: its file {file} is not installed")
    if part == "basis":
        from brdfkit.io.digest import cached_file_digest

        recorded = cached_file_digest(path)
    else:
        with open_safetensors(path, framework="numpy", diagnose="brdfkit model file") as f:
            recorded = (f.metadata() or {}).get("fingerprint")
    if recorded != want:
        raise FormatError(path, f"built-in model {m.name!r}: the file's digest is {str(recorded)[:12]}, the "
                                f"manifest's {want[:12]}: the file is damaged or was replaced")
    return path


def _builtin_part(spec, part: str) -> str:
    """An installed built-in's ``part`` file by name; :class:`InputError` otherwise (an
    unknown name, or a built-in without that part, naming the built-ins that have it)."""
    installed = builtin_models()
    for m in installed:
        if m.name == spec:
            if part != "model" and getattr(m, part) is None:
                what = {"prior": "learnt prior", "basis": "PCA basis"}[part]
                having = ", ".join(e.name for e in installed if getattr(e, part)) or "none installed"
                raise InputError(f"built-in model {m.name!r} ships no {what} (built-ins with one: {having}; "
                                 f"`brdfkit models` lists them)")
            return _checked(m, part)
    raise _unknown(os.fspath(spec), installed)


def resolve_prior(spec: str | os.PathLike) -> str:
    """The learnt-prior model file a ``-m`` value names: a path as it is, else the
    learnt prior of the installed built-in of that name (its fingerprint checked)."""
    if is_path_spec(spec):
        return os.fspath(spec)
    return _builtin_part(spec, "prior")


def resolve_basis(spec: str | os.PathLike) -> str:
    """The PCA basis file a ``-m`` value names: a path as it is, else the basis file of
    the installed built-in of that name (the one its learnt prior is fitted with), its
    SHA-256 checked against the manifest.

    Raises
    ------
    InputError
        An unknown name, or a built-in that ships no basis, the message naming the
        built-ins that do.
    """
    if is_path_spec(spec):
        return os.fspath(spec)
    return _builtin_part(spec, "basis")


def is_builtin_basis(path: str | os.PathLike) -> bool:
    """Whether ``path`` is the basis file of an installed built-in."""
    real = os.path.realpath(os.fspath(path))
    return any(m.basis and os.path.realpath(os.path.join(os.path.dirname(m.path), m.basis)) == real
               for m in builtin_models())


def _unknown(spec: str, installed: list[BuiltinModel]) -> InputError:
    if installed:
        names = ", ".join(m.name for m in installed)
        return InputError(f"unknown model {spec!r}: no such file, and not a built-in model "
                          f"(built-in: {names}; `brdfkit models` lists them)")
    return InputError(f"unknown model {spec!r}: no such file, and no built-in models are installed "
                      "(pass a model file made by `brdfkit fit`)")


def resolve_model(spec: str | os.PathLike) -> str:
    """The model file a ``-m`` value names: a path as it is (:func:`is_path_spec`), else
    the installed built-in of that name, its fingerprint checked.

    Raises
    ------
    InputError
        Neither a file nor an installed built-in (one line listing the built-in names).
    FormatError
        The built-in's file records another fingerprint than the manifest.
    """
    if is_path_spec(spec):
        return os.fspath(spec)
    installed = builtin_models()
    for m in installed:
        if m.name == spec:
            return _checked(m)
    raise _unknown(os.fspath(spec), installed)


def default_model() -> str | None:
    """The manifest's default built-in, checked, if it is installed; else ``None``."""
    man = read_manifest()
    for m in man.installed():
        if m.default:
            return _checked(m)
    return None


def find_by_digest(digest: str | None) -> str | None:
    """The installed built-in part whose digest is ``digest`` (an embedding's decoder: a
    hypernetwork's weights fingerprint or a basis file's SHA-256), checked, or ``None``."""
    if not digest:
        return None
    for m in builtin_models():
        for part, want in (("model", m.fingerprint), ("basis", m.basis_fingerprint)):
            if want == digest:
                return _checked(m, part)
    return None


def write_manifest(folder: str | os.PathLike, entries: list[dict], default: str | None) -> str:
    """Write ``manifest.json`` into ``folder`` atomically, its entries checked first."""
    doc = {"format": MANIFEST_FORMAT, "version": MANIFEST_VERSION, "default": default, "models": entries}
    path = os.path.join(os.fspath(folder), MANIFEST)
    for d in entries:  # refused before anything is written
        _entry(path, os.fspath(folder), d, default)
    with atomic_open(path, "w", encoding="utf-8") as f:
        f.write(json.dumps(doc, indent=1) + "\n")
    return path
