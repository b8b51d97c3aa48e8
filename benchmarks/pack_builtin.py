"""Pack trained models into the package's built-in folder and write its manifest.

The models are trained by the ``brdfkit fit`` commands listed in ``docs/models.md``
(recorded again in each manifest entry); this script only re-saves them for shipping:
hypernetworks in float16 with one shared reference file (they were all trained against
the reference of ``merl80-l40``, ``-O reference=``), learnt priors with the one shared
basis file they were trained on. Validation figures come from
``benchmarks/eval_sparse.py --json`` (held-out materials only).

    python benchmarks/pack_builtin.py --src /work/models --dst brdfkit/models \
        --validation merl80-l40=eval-merl80-test.json
"""

from __future__ import annotations

import argparse
import json
import os
import shutil

MODELS = [  # name, hypernetwork file, learnt-prior file, materials list, fit commands
    ("merl-rgl-l40", "merl-rgl-l40.safetensors", "merl-rgl-prior.safetensors", "MERL + RGL (151)",
     "brdfkit fit PROXIES/merl PROXIES/rgl -O reference=merl80-l40.safetensors --minutes 14 --seed 0 "
     "-o merl-rgl-l40-paper.safetensors; brdfkit tune PROXIES/merl PROXIES/rgl -m merl-rgl-l40-paper.safetensors "
     "-o merl-rgl-l40.safetensors --minutes 50; brdfkit tune PROXIES/merl PROXIES/rgl -m merl-rgl-l40-paper.safetensors "
     "-o merl-rgl-l40.safetensors --minutes 44 --resume -O lr_encoder=1e-3; brdfkit fit --method prior PROXIES/merl PROXIES/rgl "
     "-O basis=merl80-basis.safetensors -O weight=energy -O s2=0.03 --steps 3000 --seed 0 -o merl-rgl-prior.safetensors"),
    ("merl80-l40", "merl80-l40.safetensors", "merl80-prior.safetensors", "MERL less merl-test.txt (80)",
     "brdfkit fit PROXIES/merl --exclude-list merl-test.txt --minutes 14 --seed 0 -o merl80-l40.safetensors; "
     "brdfkit fit --method ipca PROXIES/merl --exclude-list merl-test.txt -O half=true -O phi_stride=2 "
     "-o merl80-basis.safetensors; brdfkit fit --method prior PROXIES/merl --exclude-list merl-test.txt "
     "-O basis=merl80-basis.safetensors -O weight=energy -O s2=0.03 --steps 3000 --seed 0 -o merl80-prior.safetensors"),
    ("merl-rgl-l7", "merl-rgl-l7.safetensors", None, "MERL + RGL (151)",
     "brdfkit fit PROXIES/merl PROXIES/rgl --latent-dim 7 -O reference=merl80-l40.safetensors --minutes 14 "
     "--seed 0 -o merl-rgl-l7-paper.safetensors; brdfkit tune PROXIES/merl PROXIES/rgl -m merl-rgl-l7-paper.safetensors "
     "-o merl-rgl-l7.safetensors --minutes 50; brdfkit tune PROXIES/merl PROXIES/rgl -m merl-rgl-l7-paper.safetensors "
     "-o merl-rgl-l7.safetensors --minutes 44 --resume -O lr_encoder=1e-3"),
]
REFERENCE = "merl80-reference.safetensors"
BASIS = "merl80-basis.safetensors"


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--src", required=True, help="folder of the trained model files")
    ap.add_argument("--dst", required=True, help="the built-in folder (brdfkit/models)")
    ap.add_argument("--validation", nargs="*", default=[], metavar="NAME=JSON",
                    help="eval_sparse.py --json output of a model's held-out materials")
    args = ap.parse_args()

    from brdfkit.methods.prior.file import pack_prior
    from brdfkit.model.builtin import manifest_entry, pack_model, write_manifest

    validation = {}
    for item in args.validation:
        name, path = item.split("=", 1)
        with open(path) as f:
            recs = [r for r in json.load(f)["records"] if r["method"] == "prior"]
        validation[name] = {str(n): round(sum(r["log_rmse"] for r in recs if r["n"] == n)
                                          / sum(1 for r in recs if r["n"] == n), 4)
                            for n in sorted({r["n"] for r in recs})}
    os.makedirs(args.dst, exist_ok=True)
    for stale in (REFERENCE, BASIS):
        if os.path.exists(os.path.join(args.dst, stale)):
            os.remove(os.path.join(args.dst, stale))
    shutil.copyfile(os.path.join(args.src, BASIS), os.path.join(args.dst, BASIS))
    entries = []
    # merl80-l40 first: its reference is the one the others were trained against.
    for name, hyper, prior, mats, command in sorted(MODELS, key=lambda m: m[0] != "merl80-l40"):
        dst = os.path.join(args.dst, hyper)
        pack_model(os.path.join(args.src, hyper), dst, half=True, reference_file=REFERENCE)
        entry = manifest_entry(dst, name, command=command, validation=validation.get(name, {}),
                               materials_list=mats)
        if prior:
            entry["prior"] = prior
            entry["prior_fingerprint"] = pack_prior(os.path.join(args.src, prior), os.path.join(args.dst, prior), BASIS)
        entries.append(entry)
        print(f"{name}: {os.path.getsize(dst) / 1e6:.2f} MB" + (f" + prior {os.path.getsize(os.path.join(args.dst, prior)) / 1e6:.2f} MB" if prior else ""))
    order = [m[0] for m in MODELS]
    entries.sort(key=lambda e: order.index(e["name"]))
    write_manifest(args.dst, entries, default="merl-rgl-l40")
    total = sum(os.path.getsize(os.path.join(args.dst, f)) for f in os.listdir(args.dst) if f.endswith(".safetensors"))
    print(f"built-in folder {args.dst}: {total / 1e6:.1f} MB of model files")


if __name__ == "__main__":
    main()
