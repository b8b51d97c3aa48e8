"""Pack trained models into the package's built-in folder and write its manifest.

The models are trained by the ``brdfkit fit`` commands listed in ``docs/models.md``
(recorded again in each manifest entry); this script only re-saves them for shipping:
hypernetworks in float16 with one shared reference file (they were all trained against
the reference of ``merl80-l40``, ``-O reference=``), learnt priors each with the basis
file it was trained on (``merl80-basis`` fitted on the 80 training materials of
``merl80-l40``, ``merl-rgl-basis`` on all 151). Validation figures come from
``benchmarks/eval_sparse.py --json`` or ``brdfkit bench``'s ``bench.json``: the learnt
prior's mean log RMSE per N from uniform samples (held-out materials only), and the
renders' figures (``renders``: PSNR and Delta E per N, and ``encode`` from a compression
run of the model), as ``brdfkit models`` shows them.

    python benchmarks/pack_builtin.py --src runs/models --dst brdfkit/models \
        --validation merl80-l40=bench-sparse/bench.json
    python benchmarks/pack_builtin.py --dst brdfkit/models --validation-only \
        --validation merl80-l40=bench-sparse/bench.json     # the manifest's figures alone
    python benchmarks/pack_builtin.py --src runs/models --dst brdfkit/models --priors-only
                                                            # new bases and learnt priors, the hypernetworks kept
"""

from __future__ import annotations

import argparse
import json
import os
import shutil

_PAPER = ("brdfkit fit PROXIES/merl PROXIES/rgl {latent}-O reference=merl80-l40.safetensors --minutes 14 --seed 0 "
          "-o {name}-paper.safetensors")
_BASIS = ("brdfkit fit --method ipca {data} --components 30 -O half=true -O phi_stride=2 -O int8=true -O w_floor=0.005 "
          "-o {basis}")
_PRIOR = ("brdfkit fit --method prior {data} -O basis={basis} -O weight=energy -O s2=0.03 "
          "--steps 3000 --seed 0 -o {name}.safetensors")
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


MODELS = [  # name, hypernetwork file, learnt-prior file, its basis file, materials list, fit commands
    ("merl-rgl-l40", "merl-rgl-l40.safetensors", "merl-rgl-prior.safetensors", "merl-rgl-basis.safetensors",
     "MERL + RGL (151)",
     _PAPER.format(name="merl-rgl-l40", latent="") + "; " + _tuned("merl-rgl-l40", (8965, 13633, 19735, 27242))
     + "; " + _BASIS.format(data=_ALL, basis="merl-rgl-basis.safetensors")
     + "; " + _PRIOR.format(data=_ALL, basis="merl-rgl-basis.safetensors", name="merl-rgl-prior")),
    ("merl80-l40", "merl80-l40.safetensors", "merl80-prior.safetensors", "merl80-basis.safetensors",
     "MERL less merl-test.txt (80)",
     "brdfkit fit PROXIES/merl --exclude-list merl-test.txt --minutes 14 --seed 0 -o merl80-l40.safetensors; "
     + _BASIS.format(data=_MERL80, basis="merl80-basis.safetensors") + "; "
     + _PRIOR.format(data=_MERL80, basis="merl80-basis.safetensors", name="merl80-prior")),
    ("merl-rgl-l7", "merl-rgl-l7.safetensors", None, None, "MERL + RGL (151)",
     _PAPER.format(name="merl-rgl-l7", latent="--latent-dim 7 ") + "; " + _tuned("merl-rgl-l7", (9710, 14495, 20283))),
]
REFERENCE = "merl80-reference.safetensors"
BASES = sorted({m[3] for m in MODELS if m[3]})


def _tune_record(path):
    """A model file's ``meta["tune"]`` (``brdfkit tune``), or ``None``."""
    from brdfkit.api import load_model

    return load_model(path, "cpu").meta.get("tune")


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
            groups.setdefault("encode", []).append(r)
    if not groups:
        return {}
    n_mats = len({r["material"] for g in groups.values() for r in g})
    trained = sum(1 for r in groups.get("encode", []) if r.get("trained_on"))
    held = "in its training set" if trained and trained == len(groups.get("encode", [])) else \
        "held out" if not trained else f"{trained} of {len(groups['encode'])} compressions in its training set"
    return {"psnr": {k: round(sum(r["psnr"] for r in g) / len(g), 2) for k, g in groups.items()},
            "delta_e": {k: round(sum(r["delta_e"] for r in g) / len(g), 3) for k, g in groups.items()},
            "scenes": list(cfg.get("scenes") or ["reference"]), "resolution": cfg.get("resolution"),
            "materials": f"{n_mats} materials of "
                         f"{os.path.basename(str(cfg.get('data') or cfg.get('compression_data')))} ({held})"}


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
    args = ap.parse_args()
    if not args.validation_only and not args.src:
        ap.error("--src is required (unless --validation-only)")

    from brdfkit.methods.prior.prior_file import basis_entry, pack_prior
    from brdfkit.models.builtin import write_manifest
    from brdfkit.hypernet.packing import manifest_entry, pack_model

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
        if recs:
            validation[name] = {str(n): round(sum(r["log_rmse"] for r in recs if r["n"] == n)
                                              / sum(1 for r in recs if r["n"] == n), 4)
                                for n in sorted({r["n"] for r in recs})}
        found = _renders(name, doc)
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
        for entry in doc["models"]:
            if entry["name"] in validation:
                entry["validation"] = validation[entry["name"]]
            if entry["name"] in renders:
                entry["renders"] = renders[entry["name"]]
        write_manifest(args.dst, doc["models"], default=doc["default"])
        print(f"set the validation of {', '.join(sorted(validation)) or 'no model'} in {args.dst}/manifest.json")
        return
    if args.priors_only:
        return _priors_only(args, write_manifest, pack_prior, basis_entry)
    os.makedirs(args.dst, exist_ok=True)
    for stale in (REFERENCE, *BASES):
        if os.path.exists(os.path.join(args.dst, stale)):
            os.remove(os.path.join(args.dst, stale))
    for basis in BASES:
        shutil.copyfile(os.path.join(args.src, basis), os.path.join(args.dst, basis))
    entries = []
    # merl80-l40 first: its reference is the one the others were trained against.
    for name, hyper, prior, basis, mats, command in sorted(MODELS, key=lambda m: m[0] != "merl80-l40"):
        dst = os.path.join(args.dst, hyper)
        pack_model(os.path.join(args.src, hyper), dst, half=True, reference_file=REFERENCE)
        entry = manifest_entry(dst, name, command=command, validation=validation.get(name, {}),
                               materials_list=mats)
        if name in renders:
            entry["renders"] = renders[name]
        tuned = _tune_record(dst)
        if tuned:  # the manifest counts the paper's steps and the screen tuning's together
            entry["steps"] += int(tuned["steps"])
            entry["train_seconds"] = round(entry["train_seconds"] + float(tuned["wall_time_s"]), 1)
        if prior:
            entry["prior"] = prior
            entry["prior_fingerprint"] = pack_prior(os.path.join(args.src, prior), os.path.join(args.dst, prior), basis)
            entry.update(basis_entry(os.path.join(args.dst, prior)))
        entries.append(entry)
        print(f"{name}: {os.path.getsize(dst) / 1e6:.2f} MB" + (f" + prior {os.path.getsize(os.path.join(args.dst, prior)) / 1e6:.2f} MB" if prior else ""))
    order = [m[0] for m in MODELS]
    entries.sort(key=lambda e: order.index(e["name"]))
    write_manifest(args.dst, entries, default="merl-rgl-l40")
    total = sum(os.path.getsize(os.path.join(args.dst, f)) for f in os.listdir(args.dst) if f.endswith(".safetensors"))
    print(f"built-in folder {args.dst}: {total / 1e6:.1f} MB of model files")


def _priors_only(args, write_manifest, pack_prior, basis_entry) -> None:
    """Replace the bases and learnt priors of ``args.dst`` by those of ``args.src``; the
    hypernetwork entries stay, their commands updated for the new basis and prior."""
    with open(os.path.join(args.dst, "manifest.json")) as f:
        doc = json.load(f)
    for basis in BASES:
        shutil.copyfile(os.path.join(args.src, basis), os.path.join(args.dst, basis))
    by_name = {m[0]: m for m in MODELS}
    for entry in doc["models"]:
        _, _, prior, basis, _, command = by_name[entry["name"]]
        entry["command"] = command
        if prior:
            entry["prior"] = prior
            entry["prior_fingerprint"] = pack_prior(os.path.join(args.src, prior), os.path.join(args.dst, prior), basis)
            entry.update(basis_entry(os.path.join(args.dst, prior)))
            entry.pop("renders", None)  # measured with the old basis
            entry["validation"] = {}
    write_manifest(args.dst, doc["models"], default=doc["default"])
    total = sum(os.path.getsize(os.path.join(args.dst, f)) for f in os.listdir(args.dst) if f.endswith(".safetensors"))
    print(f"built-in folder {args.dst}: {total / 1e6:.1f} MB of model files")


if __name__ == "__main__":
    main()
