"""Decided: no correction of the learnt prior's sparse fits ships as ``brdfkit sparse``'s
default yet; none of the designs measured on the validation split gains 1 dB over the prior
at N >= 160 (issue 49's bar), and the one that gains anything (a residual of the basis's
30 components trained on projections, the coefficients fitted through it from the samples,
kept by the held-out choice) gains +0.1 to +0.2 dB. Reported in
``docs/notes/generalisation.md``, "Lever 9".

Each design is a residual file of the validation split's basis (a basis and a learnt prior
fitted on the 64 MERL training proxies outside ``benchmarks/validation.txt``, the mapping with
the grazing share), scored on the 16 validation materials: the six judged scenes at the
render-aligned error's 32 px, for N uniform samples (seed 0):

* ``prior``: the learnt prior's fit, decoded by the basis (``--method prior``);
* ``corrected``: the same coefficients (a network of sparse fits, ``brdfkit fit --method
  correction``) or the coefficients fitted through the correction from the samples
  (:func:`brdfkit.prior.corrected.fit_through`; a network trained on projections,
  ``brdfkit fit --method residual -O sizes=90``), decoded by the basis plus the correction;
* ``auto``: the held-out choice between the two (:class:`brdfkit.prior.corrected.CorrectedPrior`);
* for a network of projections, also the projection of the whole table with and without
  the fit through the correction (what ``encode`` would do at that size).

A network with a set encoder (``-O latent=L``) is read from its training checkpoint and
run in torch (its decode is not in the library).

    python benchmarks/studies/study_sparse_correction.py --prior runs/lev/prior64.safetensors \\
        --basis runs/lev/basis64.safetensors --residual runs/lev/res-90-39.safetensors -n 160 400 2000 -o b30.json
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))


def _psnr(table, refs, screens) -> dict:
    from brdfkit.render.screen import screen_psnr

    return {s: float(screen_psnr(sc.render_table(table), refs[s])) for s, sc in screens.items()}


def _set_network(path, k, latent):
    """A set-encoder correction's torch module, from its training checkpoint."""
    import torch

    from brdfkit.residual.network import ResidualConfig, ResidualNet

    net = ResidualNet(ResidualConfig(k, k, 32, 64, 0, count=True, latent=latent))
    net.load_state_dict(torch.load(path, weights_only=True)["net"])
    return net.eval()


def _set_correction(net, basis, pf):
    """The set-encoder network's correction ``(P, 3)`` of a prior's fit ``pf``."""
    import torch

    from brdfkit.geometry import grid_hd
    from brdfkit.residual.network import COUNT_REF

    c, k = pf.coefficients, pf.coefficients.shape[0]
    r = pf.b - pf.tab[:, 2:] @ c
    z = np.concatenate([(c / basis.sigma.astype(np.float64)[:, None]).T, np.ones((3, k)),
                        np.full((3, 1), math.log(pf.count) / math.log(COUNT_REF))], 1)
    hd = torch.as_tensor(np.ascontiguousarray(grid_hd()[basis.cells]))
    with torch.no_grad():
        out = [net(torch.as_tensor(z[ch:ch + 1], dtype=torch.float32), hd,
                   (torch.as_tensor(pf.hd[None]), torch.as_tensor(r[None, :, ch], dtype=torch.float32)))[0].numpy()
               for ch in range(3)]
    return np.stack(out, 1)


def _material(name, folder, prior, model, a, screens):
    """The scores of one material: ``{row: {scene: PSNR}}``."""
    from brdfkit.acquisition.sampling import draw_samples
    from brdfkit.io.merl import read_merl

    t = read_merl(os.path.join(folder, name + ".binary"))
    refs = {s: sc.render_table(t) for s, sc in screens.items()}
    basis, out = prior.basis, {}
    if a.residual and not model.residual.nets[-1][0].count:
        from brdfkit.residual.encoding import fit_through

        part = basis.leading(basis.n_components)
        c0 = part.project(t)
        out["projection"] = _psnr(part.decode(c0), refs, screens)
        out["projection+fit"] = _psnr(model.residual.decode(fit_through(model.residual, part.mapped_table(t), c0), 1.0),
                                      refs, screens)
    for n in a.n:
        samples = draw_samples(t, n, seed=0)
        pf = prior.fit(samples)
        out[f"prior/{n}"] = _psnr(basis.decode(pf.coefficients), refs, screens)
        if a.residual:
            forced = model.fit(samples, correction="on")
            out[f"corrected/{n}"] = _psnr(model.decode(forced), refs, screens)
            out[f"auto/{n}"] = _psnr(model.decode(model.fit(samples)), refs, screens)
        else:
            mapped = basis.mapped_values(pf.coefficients) + _set_correction(model, basis, pf)
            out[f"corrected/{n}"] = _psnr(basis.decode_mapped(mapped), refs, screens)
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--prior", required=True)
    ap.add_argument("--basis", required=True)
    ap.add_argument("--residual", help="a residual file (a network of sparse fits or of projections)")
    ap.add_argument("--set-checkpoint", help="a set-encoder correction's training checkpoint")
    ap.add_argument("--latent", type=int, default=16)
    ap.add_argument("--proxies", default="proxies/merl")
    ap.add_argument("--names", default=os.path.join(HERE, "..", "validation.txt"))
    ap.add_argument("-n", type=int, nargs="+", default=[160, 400, 2000])
    ap.add_argument("-o", "--output", required=True)
    a = ap.parse_args(sys.argv[1:] if argv is None else argv)
    from brdfkit.basis import load_basis
    from brdfkit.io.digest import file_digest
    from brdfkit.prior.corrected import CorrectedPrior
    from brdfkit.prior.prior_file import load_prior
    from brdfkit.render.scene_suite import SUITE, scene_env
    from brdfkit.render.screen import screen
    from brdfkit.residual.residual_file import load_residual

    prior = load_prior(a.prior)
    if a.residual:
        res = load_residual(a.residual, basis=(load_basis(a.basis), file_digest(a.basis)))
        model = CorrectedPrior(prior, res, file_digest(a.residual))
    else:
        model = _set_network(a.set_checkpoint, prior.basis.n_components, a.latent)
    screens = {s: screen(None, 32, env=scene_env(s)) for s in SUITE}
    names = open(a.names, encoding="utf-8").read().split()
    doc = {"prior": os.path.basename(a.prior), "residual": os.path.basename(a.residual or a.set_checkpoint),
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
