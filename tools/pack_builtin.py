"""Pack trained models into the package's built-in folder and write its manifest.

A built-in is a *bundle* of parts (``network``, ``basis``, ``prior``, ``residual``;
:mod:`brdfkit.models.builtin`), listed in a version 2 manifest with each part's file and
digest. The parts are trained by the ``brdfkit fit`` commands listed in
``docs/models.md`` (recorded again in each manifest entry); this script only re-saves
them for shipping (:data:`PACKERS`, one packer a part): hypernetworks in float16 with one
shared reference file (they were all trained against the reference of ``merl80-l40``,
``-O reference=``), learnt priors each with the basis file it was trained on
(``merl80-basis`` fitted on the 80 training materials of ``merl80-l40``,
``merl-rgl-basis`` on all 151), bases copied as they are. Validation figures come from
``benchmarks/eval_sparse.py --json`` or ``brdfkit bench``'s ``bench.json``: the learnt
prior's mean log RMSE per N from uniform samples (held-out materials only), and the
renders' figures (``renders``: PSNR and Delta E per N, and ``encode`` from a compression
run of the model), as ``brdfkit models`` shows them.

    python tools/pack_builtin.py --src runs/models --dst brdfkit/models \
        --validation merl80-l40=bench-sparse/bench.json
    python tools/pack_builtin.py --dst brdfkit/models --validation-only \
        --validation merl80-l40=bench-sparse/bench.json     # the manifest's figures alone
    python tools/pack_builtin.py --src runs/models --dst brdfkit/models --priors-only
                                                            # new bases and learnt priors, the hypernetworks kept
    python tools/pack_builtin.py --src runs/l7 --dst brdfkit/models --networks-only merl-rgl-l7=l7-floor2.safetensors \
        --validation merl-rgl-l7=bench151/bench.json        # a hypernetwork tuned further from the shipped one

A manifest of version 1 in ``--dst`` (``--validation-only``, ``--priors-only``) is
rewritten as version 2.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil

_PAPER = ("brdfkit fit PROXIES/merl PROXIES/rgl {latent}-O reference=merl80-l40.safetensors --minutes 14 --seed 0 "
          "-o {name}-paper.safetensors")
_BASIS = ("brdfkit fit --method basis {data} --components 30 -O half=true -O phi_stride=2 -O int8=true -O deflate=true "
          "-O w_floor=0.005 -O eps_share=0.03 -o {basis}")
_PRIOR = ("brdfkit fit --method prior {data} -O basis={basis} -O weight=energy -O s2=0.03 "
          "--steps 3000 --seed 0 -o {name}.safetensors")
_RESIDUAL = ("brdfkit fit --method residual {data} -O basis={basis} --steps 4000 -O lr_end=0.05 -O members={members} "
             "--seed 0 -o {name}.safetensors")
_MERL80 = "PROXIES/merl --exclude-list merl-test.txt"
_ALL = "PROXIES/merl PROXIES/rgl"
# The tuning's stages (brdfkit tune, docs/training.md): each a --resume of the last with
# its learning rates; --steps is the stage's last step (the first two stages ran to a
# time limit, and stopped there).
_STAGES = ("", " -O lr_encoder=1e-3", " -O lr_decoder=3e-5 -O lr_latent=1e-3 -O lr_encoder=1e-3",
           " -O lr_decoder=1e-5 -O lr_latent=3e-4 -O lr_encoder=1e-3")


def _tuned(name, ends):
    return "; ".join(f"brdfkit tune PROXIES/merl PROXIES/rgl -m {name}-paper.safetensors -o {name}.safetensors "
                     f"--steps {end}" + (" --resume" if i else "") + _STAGES[i] for i, end in enumerate(ends))


# merl-rgl-l7's ratio floor (issue 58): two tunes on from the network packed before them
# (the built-in of that day, float16), the second drawing the floor's cells where the
# material is far below the reference (`--networks-only` writes these from their records).
_L7_FLOOR = ("brdfkit tune PROXIES/merl PROXIES/rgl -m merl-rgl-l7 -o merl-rgl-l7-tune1.safetensors --steps 4000 "
             "--seed 0 -O floor_weight=1.0 -O lr_decoder=3e-05 -O lr_encoder=0.001 -O lr_latent=0.001; "
             "brdfkit tune PROXIES/merl PROXIES/rgl -m merl-rgl-l7-tune1.safetensors -o merl-rgl-l7.safetensors "
             "--steps 4000 --seed 1 -O floor_candidates=65536 -O floor_weight=3.0 -O lr_decoder=3e-05 "
             "-O lr_encoder=0.001 -O lr_latent=0.001")


MODELS = [  # name, {part: file} (the network first), materials list, fit commands
    ("merl-rgl-l40", {"network": "merl-rgl-l40.safetensors", "basis": "merl-rgl-basis.safetensors",
                      "prior": "merl-rgl-prior.safetensors", "residual": "merl-rgl-residual.safetensors"},
     "MERL + RGL (151)",
     _PAPER.format(name="merl-rgl-l40", latent="") + "; " + _tuned("merl-rgl-l40", (8965, 13633, 19735, 27242))
     + "; " + _BASIS.format(data=_ALL, basis="merl-rgl-basis.safetensors")
     + "; " + _PRIOR.format(data=_ALL, basis="merl-rgl-basis.safetensors", name="merl-rgl-prior")
     + "; " + _RESIDUAL.format(data=_ALL, basis="merl-rgl-basis.safetensors", name="merl-rgl-residual", members=1)),
    ("merl80-l40", {"network": "merl80-l40.safetensors", "basis": "merl80-basis.safetensors",
                    "prior": "merl80-prior.safetensors", "residual": "merl80-residual.safetensors"},
     "MERL less merl-test.txt (80)",
     "brdfkit fit PROXIES/merl --exclude-list merl-test.txt --minutes 14 --seed 0 -o merl80-l40.safetensors; "
     + _BASIS.format(data=_MERL80, basis="merl80-basis.safetensors") + "; "
     + _PRIOR.format(data=_MERL80, basis="merl80-basis.safetensors", name="merl80-prior") + "; "
     + _RESIDUAL.format(data=_MERL80, basis="merl80-basis.safetensors", name="merl80-residual", members=2)),
    ("merl-rgl-l7", {"network": "merl-rgl-l7.safetensors"}, "MERL + RGL (151)",
     _PAPER.format(name="merl-rgl-l7", latent="--latent-dim 7 ") + "; " + _tuned("merl-rgl-l7", (9710, 14495, 20283))
     + "; " + _L7_FLOOR),
]
REFERENCE = "merl80-reference.safetensors"
BASES = sorted({m[1]["basis"] for m in MODELS if "basis" in m[1]})


def _pack_network(src, dst, parts):
    from brdfkit.hypernet.packing import pack_network

    return pack_network(src, dst, half=True, reference_file=REFERENCE)


def _pack_basis(src, dst, parts):
    from brdfkit.io.digest import file_digest

    if os.path.abspath(src) != os.path.abspath(dst):
        shutil.copyfile(src, dst)
    return file_digest(dst)


def _pack_prior(src, dst, parts):
    from brdfkit.prior.prior_file import basis_entry, pack_prior

    digest = pack_prior(src, dst, parts["basis"])
    basis = basis_entry(dst).get("basis")
    if basis is not None and basis["file"] != parts["basis"]:
        raise SystemExit(f"{dst}: its basis is {basis['file']}, the bundle's {parts['basis']}")
    return digest


OFFERED: dict = {}
"""``{bundle: sizes}`` a residual is offered at (``--offered NAME=9,21,39``): where it won
on held-out materials; none given: every size it serves."""


MEMBERS: dict = {}
"""``{bundle: members}`` of a residual that ship (``--members NAME=0``): the built-ins' 60 MB
cap holds one network a size for both built-ins (0.1 MB a network); none given: all."""


def _with_members(bundle: str, command: str) -> str:
    """A bundle's fit commands, with the residual's members that ship when not all do."""
    if bundle not in MEMBERS:
        return command
    shipped = ",".join(map(str, MEMBERS[bundle]))
    return f"{command} (member {shipped} of each size ships: --members {bundle}={shipped})"


def _pack_residual(src, dst, parts):
    """A residual re-saved for shipping: its heads in int8, its basis named as the bundle's
    (the same file, by digest), the sizes it is offered at (:data:`OFFERED`) and the members
    that ship (:data:`MEMBERS`)."""
    from brdfkit.basis.basis_file import load_basis
    from brdfkit.io.digest import file_digest
    from brdfkit.residual.residual_file import load_residual, save_residual

    bpath = os.path.join(os.path.dirname(os.path.abspath(dst)), parts["basis"])
    basis = (load_basis(bpath), file_digest(bpath))  # load_residual refuses a file of another basis
    res = load_residual(src, basis=basis)
    bundle = next(m[0] for m in MODELS if m[1].get("residual") == os.path.basename(dst))
    nets, meta = res.nets, dict(res.meta or {})
    if bundle in MEMBERS:
        nets = [(cfg, state) for cfg, state in nets if cfg.member in MEMBERS[bundle]]
        meta["shipped_members"] = ",".join(map(str, MEMBERS[bundle]))
    save_residual(dst, nets, basis_digest=res.basis_digest, basis_file=parts["basis"],
                  offered=OFFERED.get(bundle, ()), meta=meta, storage="int8")
    return file_digest(dst)


PACKERS = {"network": _pack_network, "basis": _pack_basis, "prior": _pack_prior, "residual": _pack_residual}
"""How each part is packed: ``packer(src, dst, parts) -> digest`` (``parts``: the bundle's
``{part: file}``), in this order (a prior names the basis packed before it). A new part
(``residual``) is one more entry."""


def _pack_parts(args, parts: dict, only=None) -> dict:
    """Pack the ``parts`` of a bundle (``{part: file}``; ``only``: those part names
    alone) from ``args.src`` into ``args.dst``; returns the manifest's ``parts``
    (``{part: {"file", "digest"}}``) of those packed."""
    missing = sorted(set(parts) - set(PACKERS))
    if missing:
        raise SystemExit(f"no packer for the part(s) {', '.join(missing)}: add them to PACKERS")
    out = {}
    for part in PACKERS:
        if part in parts and (only is None or part in only):
            file = parts[part]
            if only is not None and not os.path.exists(os.path.join(args.src, file)):
                print(f"{file}: not in {args.src}, the bundle's part kept as it is")
                continue
            out[part] = {"file": file, "digest": PACKERS[part](os.path.join(args.src, file),
                                                               os.path.join(args.dst, file), parts)}
    return out


def _entries(doc: dict) -> list:
    """The entries of a manifest document as version 2 writes them (a version 1
    document's ``file`` / ``fingerprint``, ``prior`` / ``prior_fingerprint`` and
    ``basis`` / ``basis_fingerprint`` moved into ``parts``)."""
    if doc.get("version") != 1:
        return doc["bundles"]
    entries = []
    for e in doc["models"]:
        e = dict(e)
        parts = {"network": {"file": e.pop("file"), "digest": e.pop("fingerprint")}}
        for key in ("basis", "prior"):
            file, digest = e.pop(key, None), e.pop(f"{key}_fingerprint", None)
            if file is not None:
                parts[key] = {"file": file, "digest": digest}
        entries.append({"name": e.pop("name"), "parts": parts, **e})
    return entries


def _tune_record(path):
    """A model file's ``meta["tune"]`` (``brdfkit tune``), or ``None``."""
    from brdfkit.api import load_model

    return load_model(path, "cpu").meta.get("tune")


def _labels(name) -> tuple:
    """What a bench calls bundle ``name``'s default compressions: its name (a latent, as
    ``hypernet-40 (NAME)``), its basis file's stem (``basis-39 (merl80-basis)``)."""
    parts = next((m[1] for m in MODELS if m[0] == name), {})
    return (name, *(os.path.splitext(parts[p])[0] for p in ("basis",) if p in parts))


def _renders(name, doc) -> dict:
    """The renders' figures of model ``name`` in a ``bench.json``: the learnt prior's mean
    PSNR and Delta E per N (uniform samples), and ``encode`` from the compression records
    of the hypernetwork ``(name)``; with how they were measured."""
    cfg = doc.get("config", {})
    ok = [r for r in doc.get("records", []) if "error" not in r and r.get("psnr") is not None]
    groups = {}
    for r in ok:
        if r["kind"] == "sparse" and r["method"] == "prior" and r.get("sampling", "uniform") == "uniform":
            groups.setdefault(str(r["n"]), []).append(r)
        elif r["kind"] == "compression" and r["method"].endswith(f"({name})"):
            groups.setdefault("encode", []).append(r)  # the latent: one size
        elif r["kind"] == "compression" and r["method"].endswith(tuple(f"({stem})" for stem in _labels(name)[1:])):
            groups.setdefault(f"encode-{r['size']}", []).append(r)
    if not groups:
        return {}
    n_mats = len({r["material"] for g in groups.values() for r in g})
    encodes = [r for k, g in groups.items() if k.startswith("encode") for r in g]
    trained = sum(1 for r in encodes if r.get("trained_on"))
    held = "in its training set" if trained and trained == len(encodes) else \
        "held out" if not trained else f"{trained} of {len(encodes)} compressions in its training set"
    return {"psnr": {k: round(sum(r["psnr"] for r in g) / len(g), 2) for k, g in groups.items()},
            "delta_e": {k: round(sum(r["delta_e"] for r in g) / len(g), 3) for k, g in groups.items()},
            "scenes": list(cfg.get("scenes") or ["reference"]), "resolution": cfg.get("resolution"),
            "materials": f"{n_mats} materials of "
                         f"{os.path.basename(str(cfg.get('data') or cfg.get('compression_data')))} ({held})"}


def _residual_renders(name, doc) -> dict:
    """The renders' figures of bundle ``name``'s residual in a compression ``bench.json``:
    mean PSNR and Delta E per size (``encode-SIZE``) of the records ``residual-SIZE
    (STEM)``, ``STEM`` its file's (the bench labels a file by its stem)."""
    stem = os.path.splitext(next(m[1]["residual"] for m in MODELS if m[0] == name))[0]
    cfg = doc.get("config", {})
    groups = {}
    for r in doc.get("records", []):
        if r.get("kind") == "compression" and "error" not in r and r.get("psnr") is not None \
                and r["method"].startswith("residual-") and r["method"].endswith(f"({stem})"):
            groups.setdefault(f"encode-{r['size']}", []).append(r)
    if not groups:
        return {}
    n_mats = len({r["material"] for g in groups.values() for r in g})
    trained = any(r.get("trained_on") for g in groups.values() for r in g)
    return {"psnr": {k: round(sum(r["psnr"] for r in g) / len(g), 2) for k, g in sorted(groups.items())},
            "delta_e": {k: round(sum(r["delta_e"] for r in g) / len(g), 3) for k, g in sorted(groups.items())},
            "scenes": list(cfg.get("scenes") or ["reference"]), "resolution": cfg.get("resolution"),
            "materials": f"{n_mats} materials of {os.path.basename(str(cfg.get('compression_data')))} "
                         f"({'in its training set' if trained else 'held out'})"}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--src", help="folder of the trained model files")
    ap.add_argument("--dst", required=True, help="the built-in folder (brdfkit/models)")
    ap.add_argument("--validation", nargs="*", default=[], metavar="NAME=JSON",
                    help="eval_sparse.py --json output of a model's held-out materials")
    ap.add_argument("--validation-only", action="store_true",
                    help="only set the manifest's validation figures; no model file is touched")
    ap.add_argument("--priors-only", action="store_true",
                    help="only the bases and learnt priors of --src, the shipped hypernetworks kept as they are")
    ap.add_argument("--networks-only", nargs="*", default=None, metavar="NAME=FILE",
                    help="only these bundles' hypernetworks, each tuned on from the shipped one (`brdfkit tune -m "
                         "NAME`, then tunes of tunes, all in --src): every other part kept as it is")
    ap.add_argument("--residuals-only", action="store_true",
                    help="only the residuals of --src, every other part kept as it is")
    ap.add_argument("--members", nargs="*", default=[], metavar="NAME=MEMBERS",
                    help="the members of a bundle's residual that ship, e.g. merl80-l40=0 (default: all)")
    ap.add_argument("--offered", nargs="*", default=[], metavar="NAME=SIZES",
                    help="the sizes a bundle's residual is offered at (where it won), e.g. merl80-l40=9,21,39")
    args = ap.parse_args()
    if not args.validation_only and not args.src:
        ap.error("--src is required (unless --validation-only)")

    from brdfkit.models.builtin import write_manifest
    from brdfkit.hypernet.packing import manifest_entry

    for item in args.members:
        name, _, members = item.partition("=")
        MEMBERS[name] = tuple(int(x) for x in members.split(",") if x)
    for item in args.offered:
        name, _, sizes = item.partition("=")
        OFFERED[name] = tuple(int(x) for x in sizes.split(",") if x)

    validation, renders = {}, {}
    for item in args.validation:
        name, _, path = item.partition("=")
        try:
            with open(path) as f:
                doc = json.load(f)
            recs = [r for r in doc["records"] if r["method"] == "prior"
                    and r.get("sampling", "uniform") == "uniform" and r.get("log_rmse") is not None]
        except (OSError, ValueError, KeyError, TypeError) as e:
            ap.error(f"--validation {item}: not a readable bench.json or eval_sparse.py --json record ({e})")
        found = _residual_renders(name, doc) if args.residuals_only else _renders(name, doc)
        if recs and "in its training set" not in found.get("materials", ""):  # held-out log RMSE only
            validation[name] = {str(n): round(sum(r["log_rmse"] for r in recs if r["n"] == n)
                                              / sum(1 for r in recs if r["n"] == n), 4)
                                for n in sorted({r["n"] for r in recs})}
        if found:
            renders.setdefault(name, {"psnr": {}, "delta_e": {}}).update(
                {k: v for k, v in found.items() if k not in ("psnr", "delta_e")})
            for key in ("psnr", "delta_e"):
                renders[name][key].update(found[key])
    if args.validation_only:
        try:
            with open(os.path.join(args.dst, "manifest.json")) as f:
                doc = json.load(f)
        except (OSError, ValueError) as e:
            ap.error(f"--dst {args.dst}: no readable manifest.json ({e})")
        entries = _entries(doc)
        for entry in entries:
            if entry["name"] in validation:
                entry["validation"] = validation[entry["name"]]
            if entry["name"] in renders:
                entry["renders"] = renders[entry["name"]]
        write_manifest(args.dst, entries, default=doc["default"])
        print(f"set the validation of {', '.join(sorted(validation)) or 'no model'} in {args.dst}/manifest.json")
        return
    if args.networks_only is not None:
        return _networks(args, write_manifest, renders)
    if args.priors_only or args.residuals_only:
        return _some_parts(args, write_manifest, ("basis", "prior") if args.priors_only else ("residual",), renders)
    os.makedirs(args.dst, exist_ok=True)
    for stale in (REFERENCE, *BASES):
        if os.path.exists(os.path.join(args.dst, stale)):
            os.remove(os.path.join(args.dst, stale))
    entries = []
    # merl80-l40 first: its reference is the one the others were trained against.
    for name, parts, mats, command in sorted(MODELS, key=lambda m: m[0] != "merl80-l40"):
        packed = _pack_parts(args, parts)
        dst = os.path.join(args.dst, parts["network"])
        entry = manifest_entry(dst, name, command=_with_members(name, command), validation=validation.get(name, {}),
                               materials_list=mats)
        entry["parts"].update(packed)
        if name in renders:
            entry["renders"] = renders[name]
        tuned = _tune_record(dst)
        if tuned:  # the manifest counts the paper's steps and the screen tuning's together
            entry["steps"] += int(tuned["steps"])
            entry["train_seconds"] = round(entry["train_seconds"] + float(tuned["wall_time_s"]), 1)
        entries.append(entry)
        sizes = [f"{part} {os.path.getsize(os.path.join(args.dst, p['file'])) / 1e6:.2f} MB"
                 for part, p in entry["parts"].items()]
        print(f"{name}: {' + '.join(sizes)}")
    order = [m[0] for m in MODELS]
    entries.sort(key=lambda e: order.index(e["name"]))
    write_manifest(args.dst, entries, default="merl-rgl-l40")
    total = sum(os.path.getsize(os.path.join(args.dst, f)) for f in os.listdir(args.dst) if f.endswith(".safetensors"))
    print(f"built-in folder {args.dst}: {total / 1e6:.1f} MB of model files")


def _some_parts(args, write_manifest, only: tuple, renders: dict) -> None:
    """Replace the parts ``only`` of ``args.dst``'s bundles by those of ``args.src``; the
    other parts stay, the entries' commands updated. New bases and priors clear the
    bundle's figures (measured with the old basis); a residual takes its own
    (``renders``, from a compression bench of it)."""
    with open(os.path.join(args.dst, "manifest.json")) as f:
        doc = json.load(f)
    entries = _entries(doc)
    by_name = {m[0]: m for m in MODELS}
    for entry in entries:
        _, parts, _, command = by_name[entry["name"]]
        entry["command"] = _with_members(entry["name"], command)
        packed = _pack_parts(args, parts, only=only)
        if packed and "residual" not in only:
            entry["parts"].update(packed)
            entry.pop("renders", None)  # measured with the old basis
            entry["validation"] = {}
        elif packed:
            entry["parts"].update(packed)
            if entry["name"] in renders:
                entry["parts"]["residual"]["renders"] = renders[entry["name"]]
    write_manifest(args.dst, entries, default=doc["default"])
    total = sum(os.path.getsize(os.path.join(args.dst, f)) for f in os.listdir(args.dst) if f.endswith(".safetensors"))
    print(f"built-in folder {args.dst}: {total / 1e6:.1f} MB of model files")


def _tune_chain(src_folder: str, path: str, shipped: str) -> list:
    """The ``meta["tune"]`` records from the shipped network (digest ``shipped``) to the
    file ``path``, oldest first: each tune names the network it started from (``from``),
    found by digest among the files of ``src_folder``."""
    from brdfkit.api import load_model

    by_digest = {}
    for f in os.listdir(src_folder):
        if f.endswith(".safetensors"):
            try:
                by_digest[load_model(os.path.join(src_folder, f), "cpu").digest] = os.path.join(src_folder, f)
            except Exception:  # not a network file (a checkpoint, a basis): not in the chain
                continue
    chain, at = [], path
    while True:
        tuned = _tune_record(at)
        if not tuned:
            raise SystemExit(f"{at}: not tuned from {shipped[:12]} (no tune record)")
        chain.insert(0, tuned)
        if tuned["from"] == shipped:
            return chain
        if tuned["from"] not in by_digest:
            raise SystemExit(f"{at}: tuned from {tuned['from'][:12]}, neither shipped nor in {src_folder}")
        at = by_digest[tuned["from"]]


def _tune_command(name: str, record: dict, start: str, out: str) -> str:
    """The ``brdfkit tune`` command of one tune record (its non-default options)."""
    from brdfkit.hypernet.tuning import TuneOptions

    defaults = TuneOptions().__dict__
    opts = "".join(f" -O {k}={v}" for k, v in record["options"].items()
                   if k != "scenes" and v != defaults.get(k))
    return (f"brdfkit tune PROXIES/merl PROXIES/rgl -m {start} -o {out} --steps {record['steps']} "
            f"--seed {record['seed']}{opts}")


def _networks(args, write_manifest, renders: dict) -> None:
    """Replace bundles' hypernetworks by files of ``args.src`` tuned on from the shipped
    ones (``--networks-only NAME=FILE``): packed as the others, the tunes added to the
    entry's steps, seconds and command, its figures those of ``renders`` (or none)."""
    from brdfkit.hypernet.packing import pack_network

    with open(os.path.join(args.dst, "manifest.json")) as f:
        doc = json.load(f)
    entries = _entries(doc)
    for item in args.networks_only:
        name, _, file = item.partition("=")
        entry = next((e for e in entries if e["name"] == name), None)
        if entry is None or not file:
            raise SystemExit(f"--networks-only {item}: give NAME=FILE, NAME a bundle of {args.dst}")
        shipped = entry["parts"]["network"]
        chain = _tune_chain(args.src, os.path.join(args.src, file), shipped["digest"])
        start, commands = name, []
        for i, record in enumerate(chain):
            out = f"{name}.safetensors" if i == len(chain) - 1 else f"{name}-tune{i + 1}.safetensors"
            commands.append(_tune_command(name, record, start, out))
            entry["steps"] += int(record["steps"])
            entry["train_seconds"] = round(entry["train_seconds"] + float(record["wall_time_s"]), 1)
            start = out
        entry["command"] += "; " + "; ".join(commands)
        digest = pack_network(os.path.join(args.src, file), os.path.join(args.dst, shipped["file"]), half=True,
                              reference_file=REFERENCE)
        entry["parts"]["network"] = {"file": shipped["file"], "digest": digest}
        entry.pop("renders", None)  # measured with the network before
        if name in renders:
            entry["renders"] = renders[name]
        print(f"{name}: {shipped['file']} packed from {file} ({len(chain)} tune(s) on from the shipped network)")
    write_manifest(args.dst, entries, default=doc["default"])


if __name__ == "__main__":
    main()
