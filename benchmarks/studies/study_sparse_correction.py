"""Decided: no correction of the learnt prior's sparse fits ships as ``brdfkit sparse``'s
default; none of the designs measured on the validation split gains 1 dB over the prior at
N >= 160 (issue 49's bar), and the one that gains anything (a residual of the basis's 30
components trained on projections, the coefficients fitted through it from the samples,
kept by the held-out choice) gains +0.1 to +0.2 dB. Reported in
``docs/notes/generalisation.md``, "Lever 9"; the routes it measured (``brdfkit sparse
--method residual``, ``brdfkit fit --method correction`` and its ``-O latent``) left the
product on 2026-12-01 (issue 55, "What left the product" on the same page).

What still runs, and what is reduced to its record: each design is a residual file of the
validation split's basis (a basis and a learnt prior fitted on the 64 MERL training proxies
outside ``benchmarks/validation.txt``, the mapping with the grazing share), scored on the
16 validation materials: the six judged scenes at the render-aligned error's 32 px, for N
uniform samples (seed 0). This script still scores, with a residual trained on projections
(``brdfkit fit --method residual -O sizes=90``):

* ``prior``: the learnt prior's fit, decoded by the basis (``--method prior``);
* ``corrected``: the coefficients fitted through the correction from the samples
  (:func:`corrected_prior.fit_through`, beside this file), decoded by the basis plus the
  correction;
* ``auto``: the held-out choice between the two (:class:`corrected_prior.CorrectedPrior`);
* the projection of the whole table with and without the fit through the correction
  (what ``encode`` would do at that size).

The rows of a network of sparse fits (``fit --method correction``: the prior's
coefficients and the sample count in) and of a set encoder of the samples' residuals
(``-O latent=L``) are **reduced to their record**
(``benchmarks/results/2026-11-29-sparse-correction-levers-32.json``): their training and
decode left the library with the routes; the code that made them is this file, and
``brdfkit/prior/correction.py`` and ``brdfkit/prior/corrected.py``, at commit e81e1de.

    python benchmarks/studies/study_sparse_correction.py --prior runs/lev/prior64.safetensors \\
        --basis runs/lev/basis64.safetensors --residual runs/lev/res-90-39.safetensors -n 160 400 2000 -o b30.json
"""

from __future__ import annotations

import argparse
import json
import os
import sys

import numpy as np

from corrected_prior import CorrectedPrior  # beside this file: the study's own, not the library's

HERE = os.path.dirname(os.path.abspath(__file__))


def _psnr(table, refs, screens) -> dict:
    from brdfkit.render.screen import screen_psnr

    return {s: float(screen_psnr(sc.render_table(table), refs[s])) for s, sc in screens.items()}


def _material(name, folder, prior, model, a, screens):
    """The scores of one material: ``{row: {scene: PSNR}}``."""
    from brdfkit.acquisition.sampling import draw_samples
    from brdfkit.io.merl import read_merl

    t = read_merl(os.path.join(folder, name + ".binary"))
    refs = {s: sc.render_table(t) for s, sc in screens.items()}
    from brdfkit.residual.encoding import fit_through

    basis, out = prior.basis, {}
    part = basis.leading(basis.n_components)
    c0 = part.project(t)  # the projection, with and without the fit through the correction
    out["projection"] = _psnr(part.decode(c0), refs, screens)
    out["projection+fit"] = _psnr(model.residual.decode(fit_through(model.residual, part.mapped_table(t), c0), 1.0),
                                  refs, screens)
    for n in a.n:
        samples = draw_samples(t, n, seed=0)
        pf = prior.fit(samples)
        out[f"prior/{n}"] = _psnr(basis.decode(pf.coefficients), refs, screens)
        forced = model.fit(samples, correction="on")
        out[f"corrected/{n}"] = _psnr(model.decode(forced), refs, screens)
        out[f"auto/{n}"] = _psnr(model.decode(model.fit(samples)), refs, screens)
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--prior", required=True)
    ap.add_argument("--basis", required=True)
    ap.add_argument("--residual", required=True, help="a residual file of the basis, trained on projections")
    ap.add_argument("--proxies", default="proxies/merl")
    ap.add_argument("--names", default=os.path.join(HERE, "..", "validation.txt"))
    ap.add_argument("-n", type=int, nargs="+", default=[160, 400, 2000])
    ap.add_argument("-o", "--output", required=True)
    a = ap.parse_args(sys.argv[1:] if argv is None else argv)
    from brdfkit.basis import load_basis
    from brdfkit.io.digest import file_digest
    from brdfkit.prior.prior_file import load_prior
    from brdfkit.render.scene_suite import SUITE, scene_env
    from brdfkit.render.screen import screen
    from brdfkit.residual.residual_file import load_residual

    prior = load_prior(a.prior)
    model = CorrectedPrior(prior, load_residual(a.residual, basis=(load_basis(a.basis), file_digest(a.basis))))
    screens = {s: screen(None, 32, env=scene_env(s)) for s in SUITE}
    names = open(a.names, encoding="utf-8").read().split()
    doc = {"prior": os.path.basename(a.prior), "residual": os.path.basename(a.residual),
           "n": a.n, "resolution": 32, "scenes": list(SUITE), "materials": {}}
    for name in names:
        doc["materials"][name] = _material(name, a.proxies, prior, model, a, screens)
        print(name, file=sys.stderr, flush=True)
        with open(a.output + ".tmp", "w", encoding="utf-8") as f:
            json.dump(doc, f, indent=1)
        os.replace(a.output + ".tmp", a.output)
    rows = sorted({r for m in doc["materials"].values() for r in m})
    print("| row | suite PSNR (32 px) | " + " | ".join(SUITE) + " |")
    print("| --- | ---: | " + " | ".join("---:" for _ in SUITE) + " |")
    for r in rows:
        per = [m[r] for m in doc["materials"].values() if r in m]
        print(f"| {r} | {np.mean([np.mean(list(p.values())) for p in per]):.2f} | "
              + " | ".join(f"{np.mean([p[s] for p in per]):.2f}" for s in SUITE) + " |")


if __name__ == "__main__":
    main()
