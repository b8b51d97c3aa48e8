"""Decided: the error that brdfkit's refinements and model choices descend is ``screen_obj``,
the 32 px render-aligned error (:mod:`brdfkit.render.screen`) averaged over the objective
scenes ``studio-0`` ... ``studio-3``, which ranks the suite's held-out scenes best (Spearman
0.966 with their PSNR); before it (issue 21) the reference scene's screen, which ranks as
the 128 px reference renders do (0.996). Reported in ``docs/notes/render-error.md``, "The
objective, in the scene suite (issue 28)" and "Result".

Which error ranks reconstructions as the renders do? (issue 21, deliverable 1)

A refinement, a compression or a model choice is only as good as the error it is judged
by, and the judges of brdfkit are renders (reference-scene PSNR and Delta E 2000,
:mod:`brdfkit.evaluation.metrics`). This study asks which cheap error orders reconstructions of one
material the way 128 px renders do, on the reference scene and on a second scene nothing
was tuned on (the environment turned half a turn, :func:`brdfkit.render.screen.rotated_envmap`).

Reconstructions, per material (the 20 test materials of ``merl-test.txt`` by default):

* sparse, from ``draw_samples(table, N, seed=sample_seed(seed, N, name))`` at every
  ``--n`` and ``--seeds`` (the draws of ``brdfkit bench``), with the built-in
  ``merl80-l40`` (trained without the test materials) through
  :func:`brdfkit.methods.reconstruct`: ``prior`` (its learnt prior), ``ipca`` (its PCA
  basis), ``hypernet`` (refined on the samples, the default) and ``hypernet-norefine``
  (``refine=False``: the paper's one encoder pass);
* compression of the full table (in-sample: ``merl-rgl-*`` were trained on these
  materials) with ``merl-rgl-l40`` and ``merl-rgl-l7``: the encoder's pass
  (:func:`brdfkit.api.encode` / :func:`brdfkit.api.decode`), or with ``--compress-steps
  S > 0`` :func:`brdfkit.hypernet.refine_on_screen.compress_table` refined on screen for at most ``S`` steps
  (``compress-MODEL``; the encoder pass it starts from is then scored too, as
  ``compress-MODEL-enc``, unless the refinement kept the encoder's latent).

Judges (``--px`` pixels, the whole image, as ``brdfkit bench`` scores): PSNR and
Delta E 2000 of :func:`brdfkit.render.quadrature.render` of the reconstruction against
that of the reference table, on the reference scene (``ref``) and the rotated one (``rot``);
with ``--judges suite`` (issue 28), in every scene of the suite
(:mod:`brdfkit.render.scene_suite`) instead, and ``heldout``: their mean over the suite's
scenes other than the reference (which today's built-ins were tuned on).

Candidate errors, each signed so that higher is better before ranking:

* ``log_rmse``: :func:`brdfkit.evaluation.metrics.brdf_log_rmse` (the paper's and NBRDF's metric);
* ``train_loss``: the paper's training loss in mapped space without its regularisers,
  ``mean((cos_i (to_mapped(pred, rho_ref) - to_mapped(ref, rho_ref)))^2)`` over the cells
  and channels measured in the table, the reconstruction and ``rho_ref`` (``merl80-l40``'s
  reference), ``cos_i`` at the grid angles (:func:`brdfkit.evaluation.metrics._grid_cos_i`);
* ``screen_psnr``: the render-aligned error of :mod:`brdfkit.render.screen` (32 px
  reference scene, trilinear table lookups at its quadrature pairs, display-encoded MSE
  as a PSNR);
* ``screen_obj``: the same error in the objective scenes of the suite (``--objective K``:
  ``studio-0`` ... ``studio-(K-1)``, :data:`brdfkit.render.scene_suite.OBJECTIVE_SCENES`,
  none of them judged), the mean of their PSNRs;
* ``lin_rmse``: ``sqrt(mean((cos_i (pred - ref))^2))``, the cosine-weighted *linear*
  RMSE (1/sr, no log) over the same cells;
* ``albedo_de``: Delta E 2000 of the two tables' albedo colours. The albedo is the
  bi-hemispherical (white-sky) one, ``(1 / pi) integral rho cos_i cos_o dw_i dw_o`` per
  channel, as a Riemann sum over the cells measured in both tables
  (:func:`albedo_weights`: ``dw_i dw_o = 4 cos theta_d dw_h dw_d``, the MERL grid's
  square-root ``theta_h`` spacing included) normalised by the same sum of the
  Lambertian ``rho = 1 / pi`` (so a Lambertian ``a / pi`` gives exactly ``a``, and the
  unmeasured grazing cells drop out of both). Both colours are divided by
  ``max(1, max(reference albedo))`` so the reference is never clipped, then compared as
  1x1 linear-sRGB images by :func:`brdfkit.evaluation.metrics.delta_e_2000`.

Score: per material, the Spearman rank correlation (``scipy.stats.spearmanr``; ties
averaged) between each candidate and each judge over that material's reconstructions;
the table gives its mean over materials, the JSON also its minimum and the pooled
correlation over every (material, reconstruction) pair. The ``(judge)`` rows rank by the
reference scene's 128 px judges themselves: the ceiling the rotated columns allow.

    python benchmarks/studies/study_error.py --proxies proxies --n 40 400 4000 --seeds 0 \
        --px 128 --json study_error.json

(tables ``PROXIES/NAME.binary`` or ``PROXIES/merl/NAME.binary``; ``proxies/merl`` is made by
``python ../shared/tools/nbrdf_to_merl.py merl proxies/merl``). Smoke test:
``--materials alum-bronze --n 40 --px 32``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import pathlib
import sys
import time

import numpy as np

BENCHMARKS = pathlib.Path(__file__).resolve().parent.parent
sys.path.insert(0, str(BENCHMARKS))  # benchmarks/common.py
TEST_LIST = BENCHMARKS.parent.parent / "shared" / "data" / "merl-test.txt"

SPARSE_MODEL = "merl80-l40"
COMPRESS_MODELS = ("merl-rgl-l40", "merl-rgl-l7")
METHODS = ("prior", "ipca", "hypernet", "hypernet-norefine")

CANDIDATES = ("log_rmse", "train_loss", "screen_psnr", "screen_obj", "lin_rmse", "albedo_de")
JUDGES = ("ref_psnr", "ref_delta_e", "rot_psnr", "rot_delta_e")
JUDGE_LABELS = {"ref_psnr": "ref PSNR", "ref_delta_e": "ref Delta E", "rot_psnr": "rotated PSNR",
                "rot_delta_e": "rotated Delta E"}
JUDGE_ROWS = ("ref_psnr", "ref_delta_e")  # the reference scene's judges, ranked against the rotated one's


def use_suite():
    """Judge in the scene suite: every scene's PSNR and Delta E, and ``heldout`` (the mean
    over the scenes other than the reference); the reference's own rows rank against them."""
    global JUDGES, JUDGE_LABELS, JUDGE_ROWS
    from brdfkit.render.scene_suite import SUITE

    keys = [s.replace("-", "_") for s in SUITE] + ["heldout"]
    JUDGES = tuple(f"{k}_{m}" for k in keys for m in ("psnr", "delta_e"))
    JUDGE_LABELS = {f"{k}_{m}": f"{k} {'PSNR' if m == 'psnr' else 'Delta E'}" for k in keys
                    for m in ("psnr", "delta_e")}
    JUDGE_ROWS = ("reference_psnr", "reference_delta_e")


def signed(key, value):
    """``value`` signed so that higher is better."""
    return value if (key.endswith("_psnr") or key in ("screen_obj",)) else -value


def spearman(a, b) -> float:
    """Spearman rank correlation, ties averaged; NaN for fewer than 3 pairs or a constant."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    ok = np.isfinite(a) & np.isfinite(b)
    a, b = a[ok], b[ok]
    if a.size < 3 or np.ptp(a) == 0 or np.ptp(b) == 0:
        return float("nan")
    try:
        from scipy.stats import spearmanr

        return float(spearmanr(a, b).statistic)
    except ImportError:
        def ranks(x):
            order = np.argsort(x, kind="stable")
            r = np.empty(x.size)
            r[order] = np.arange(x.size, dtype=np.float64)
            for v in np.unique(x):  # ties: their mean rank
                tie = x == v
                r[tie] = r[tie].mean()
            return r

        return float(np.corrcoef(ranks(a), ranks(b))[0, 1])


def table_path(proxies, name):
    for p in (os.path.join(proxies, name + ".binary"), os.path.join(proxies, "merl", name + ".binary")):
        if os.path.exists(p):
            return p
    raise SystemExit(f"{name}: no {name}.binary in {proxies} or {proxies}/merl")


def albedo_weights() -> np.ndarray:
    """Weight of each MERL cell in ``integral f cos_i cos_o dw_i dw_o``, flat ``(N_CELLS,)``
    (up to a constant): ``cos_i cos_o`` (:func:`brdfkit.geometry.grid_cosine_weight`) times
    the cell's measure ``4 cos theta_d sin theta_h sin theta_d dtheta_h dtheta_d dphi_d``
    (``phi_h`` integrated out by isotropy), ``dtheta_h`` the grid's
    ``d/di (i / 90)^2 pi / 2``."""
    from brdfkit.geometry import N_PHI_D, N_THETA_H, grid_angles, grid_cosine_weight

    th, td, _ = grid_angles()
    wh = np.sin(th) * 2.0 * np.arange(N_THETA_H) / N_THETA_H ** 2
    wd = np.sin(td) * np.cos(td)
    w = (wh[:, None, None] * wd[None, :, None] * np.ones(N_PHI_D)).reshape(-1)
    return w * grid_cosine_weight()


class Candidates:
    """The candidate errors of reconstructions against one reference table (``objective``:
    the screens of the objective scenes)."""

    def __init__(self, table, rho_ref, sc, objective=()):
        from brdfkit.geometry import N_CELLS
        from brdfkit.hypernet.mapping import to_mapped
        from brdfkit.evaluation.metrics import _grid_cos_i

        self.table = table
        self.flat = table.reshape(N_CELLS, 3)
        rref = np.asarray(rho_ref, np.float64).reshape(N_CELLS, 3)
        self.base = np.isfinite(self.flat).all(1) & np.isfinite(rref).all(1)
        self.cos = _grid_cos_i().reshape(N_CELLS)
        self.aw = albedo_weights()
        self.rref = rref
        self.mapped_ref = np.full_like(self.flat, np.nan)
        self.mapped_ref[self.base] = to_mapped(self.flat[self.base], rref[self.base])
        self.sc = sc
        self.screen_ref = sc.render_table(table).float()
        self.objective = [(o, o.render_table(table).float()) for o in objective]

    def __call__(self, pred):
        from brdfkit.geometry import N_CELLS
        from brdfkit.hypernet.mapping import to_mapped
        from brdfkit.evaluation.metrics import brdf_log_rmse, delta_e_2000
        from brdfkit.render.screen import screen_psnr

        out, secs = {}, {}
        t = time.perf_counter()
        out["log_rmse"] = float(brdf_log_rmse(pred, self.table))
        secs["log_rmse"] = time.perf_counter() - t

        t = time.perf_counter()
        p = pred.reshape(N_CELLS, 3)
        m = self.base & np.isfinite(p).all(1)
        cos = self.cos[m][:, None]
        d = cos * (to_mapped(p[m], self.rref[m]) - self.mapped_ref[m])
        out["train_loss"] = float(np.mean(d * d))
        secs["train_loss"] = time.perf_counter() - t

        t = time.perf_counter()
        out["screen_psnr"] = float(screen_psnr(self.sc.render_table(pred).float(), self.screen_ref))
        secs["screen_psnr"] = time.perf_counter() - t

        t = time.perf_counter()
        out["screen_obj"] = float(np.mean([screen_psnr(o.render_table(pred).float(), r) for o, r in self.objective])
                                  if self.objective else float("nan"))
        secs["screen_obj"] = time.perf_counter() - t

        t = time.perf_counter()
        r = self.flat[m]
        d = cos * (p[m] - r)
        out["lin_rmse"] = float(np.sqrt(np.mean(d * d)))
        secs["lin_rmse"] = time.perf_counter() - t

        t = time.perf_counter()
        aw = self.aw[m][:, None]
        w = aw.sum()  # the Lambertian rho = 1 / pi: albedo 1
        a_pred = math.pi * (p[m] * aw).sum(0) / w
        a_ref = math.pi * (r * aw).sum(0) / w
        s = max(1.0, float(a_ref.max()))
        out["albedo_de"] = float(delta_e_2000(np.clip(a_pred / s, 0, None)[None, None], (a_ref / s)[None, None]))
        out["albedo_pred"] = a_pred.tolist()
        out["albedo_ref"] = a_ref.tolist()
        secs["albedo_de"] = time.perf_counter() - t
        return out, secs


def reconstructions(name, table, args, models):
    """Yield ``(label, n, seed, pred, seconds, extra)`` for one material."""
    from brdfkit.api import decode, encode
    from brdfkit.bench.config import sample_seed
    from brdfkit.methods import get_method, reconstruct
    from brdfkit.acquisition.sampling import draw_samples

    for n in args.n:
        for seed in args.seeds:
            draw = sample_seed(seed, n, name)
            samples = draw_samples(table, n, seed=draw, source=name)
            for label in args.methods:
                method, opts = label, {}
                if label == "hypernet-norefine":
                    method, opts = "hypernet", {"refine": False}
                t = time.perf_counter()
                pred = reconstruct(samples, method=method, model=models[method], seed=seed, device="cpu",
                                   options=get_method(method).make_options(**opts))
                yield label, n, seed, pred, time.perf_counter() - t, {"sample_seed": draw}
    for mname in args.compress_models:
        model = models["compress:" + mname]
        t = time.perf_counter()
        if args.compress_steps > 0:
            from brdfkit.hypernet.refine_on_screen import compress_table
            from brdfkit.render.objective import ObjectiveConfig
            from brdfkit.hypernet.neural_brdf import NeuralBRDF

            res = compress_table(model, table, ObjectiveConfig(steps=args.compress_steps), source=name)
            pred = NeuralBRDF.from_embedding(model, res.embedding, name).to_table()
            extra = {"steps": res.steps, "best_step": res.best_step, "heldout": list(res.heldout),
                     "refine_s": res.seconds}
            yield f"compress-{mname}", None, None, pred, time.perf_counter() - t, extra
            if res.best_step == 0:
                continue  # the encoder's latent was kept: the same table again would only add a tie
            t = time.perf_counter()
            pred = NeuralBRDF.from_embedding(model, res.encoder, name).to_table()
            yield f"compress-{mname}-enc", None, None, pred, time.perf_counter() - t, {"decode_only": True}
        else:
            pred = decode(encode(table, model, source=name), model, source=name)
            yield f"compress-{mname}", None, None, pred, time.perf_counter() - t, {}


def score_material(recs):
    """Per-material Spearman of every candidate (and reference judge) against every judge."""
    out = {}
    for c in CANDIDATES + JUDGE_ROWS:
        xs = [signed(c, r[c]) for r in recs]
        out[c] = {j: spearman(xs, [signed(j, r[j]) for r in recs]) for j in JUDGES}
    return out


def summarise(records, per_material):
    summary = {}
    for c in CANDIDATES + JUDGE_ROWS:
        summary[c] = {}
        for j in JUDGES:
            vals = np.array([per_material[m][c][j] for m in per_material], np.float64)
            ok = vals[np.isfinite(vals)]
            pooled = spearman([signed(c, r[c]) for r in records], [signed(j, r[j]) for r in records])
            summary[c][j] = {"mean": float(ok.mean()) if ok.size else float("nan"),
                             "min": float(ok.min()) if ok.size else float("nan"),
                             "pooled": pooled, "materials": int(ok.size)}
    return summary


def print_tables(summary):
    def label(c):
        return f"(judge) {JUDGE_LABELS[c]}" if c in JUDGE_ROWS else c

    print("\nMean per-material Spearman (higher = ranks as the renders do):\n")
    print("| candidate | " + " | ".join(JUDGE_LABELS[j] for j in JUDGES) + " |")
    print("| --- |" + " ---: |" * len(JUDGES))
    for c, row in summary.items():
        print(f"| {label(c)} | " + " | ".join(f"{row[j]['mean']:.3f}" for j in JUDGES) + " |")
    print("\nMinimum over materials / pooled over all (material, reconstruction) pairs:\n")
    print("| candidate | " + " | ".join(f"{JUDGE_LABELS[j]} min / pooled" for j in JUDGES) + " |")
    print("| --- |" + " ---: |" * len(JUDGES))
    for c, row in summary.items():
        print(f"| {label(c)} | " + " | ".join(f"{row[j]['min']:.3f} / {row[j]['pooled']:.3f}" for j in JUDGES)
              + " |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--proxies", required=True, help="folder of MERL tables NAME.binary (or merl/NAME.binary)")
    ap.add_argument("--materials", nargs="*", default=None, help="material names (default: --test-list)")
    ap.add_argument("--test-list", default=str(TEST_LIST), help="file of material names, one a line")
    ap.add_argument("--limit", type=int, default=0, help="only the first K materials (smoke tests)")
    ap.add_argument("--n", type=int, nargs="+", default=[40, 400, 4000])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0])
    ap.add_argument("--methods", nargs="*", default=list(METHODS), choices=METHODS)
    ap.add_argument("--model", default=SPARSE_MODEL, help="built-in (or file) of the sparse methods")
    ap.add_argument("--compress-models", nargs="*", default=list(COMPRESS_MODELS))
    ap.add_argument("--compress-steps", type=int, default=0,
                    help="most steps of compress_table's refinement on screen (0: the encoder's pass alone)")
    ap.add_argument("--px", type=int, default=128, help="render size of the judges")
    ap.add_argument("--judges", choices=("ref-rot", "suite"), default="ref-rot",
                    help="the judged scenes: the reference and its half-turn, or the scene suite")
    ap.add_argument("--objective", type=int, default=4, help="objective scenes of the screen_obj candidate")
    ap.add_argument("--threads", type=int, default=1, help="torch threads")
    ap.add_argument("--json", default=None)
    args = ap.parse_args()

    import torch

    torch.set_num_threads(args.threads)

    from brdfkit.api import load_model
    from brdfkit.atomic import atomic_open
    from brdfkit.io.folders import read_exclude_list
    from brdfkit.io.merl import read_merl
    from brdfkit.methods import get_method
    from brdfkit.methods.choice import choose
    from brdfkit.evaluation.metrics import PSNR_CAP, delta_e_2000, psnr
    from brdfkit.render.renderable import TableBRDF
    from brdfkit.render.quadrature import render
    from brdfkit.render.scene import Scene
    from brdfkit.render.scene_suite import SUITE, objective_envmap, scene_env
    from brdfkit.render.screen import rotated_envmap, screen
    from common import load_average, machine

    if args.judges == "suite":
        use_suite()
    names = args.materials or read_exclude_list(args.test_list)
    if args.limit:
        names = names[:args.limit]
    paths = {n: table_path(args.proxies, n) for n in names}
    info = {"machine": machine(), "args": vars(args), "command": " ".join(sys.argv)}

    t0 = time.perf_counter()
    models, model_files = {}, {}
    for m in {"hypernet" if lbl.startswith("hypernet") else lbl for lbl in args.methods} | {"hypernet"}:
        choice = choose(m, args.model)
        model_files[m] = choice.path
        models[m] = get_method(m).load(choice.path, "cpu")
    for mname in args.compress_models:
        models["compress:" + mname] = load_model(mname, device="cpu")
        model_files["compress:" + mname] = mname
    rho_ref = models["hypernet"].rho_ref
    info["model_files"] = model_files
    info["load_s"] = time.perf_counter() - t0
    scene = Scene(resolution=args.px)
    envs = ({s.replace("-", "_"): scene_env(s) for s in SUITE} if args.judges == "suite"
            else {"ref": None, "rot": rotated_envmap()})
    sc = screen()
    objective = [screen(env=objective_envmap(i)) for i in range(args.objective)]

    def judge_images(t):
        bt = TableBRDF(t, device="cpu")
        return {k: render(bt, scene, env=env)[0] for k, env in envs.items()}

    records, per_material, timings = [], {}, {}
    for i, name in enumerate(names):
        tm = time.perf_counter()
        table = read_merl(paths[name])
        ref_imgs = judge_images(table)
        cands = Candidates(table, rho_ref, sc, objective)
        recs = []
        for label, n, seed, pred, rec_s, extra in reconstructions(name, table, args, models):
            rec = {"material": name, "reconstruction": label, "n": n, "seed": seed, "reconstruct_s": rec_s, **extra}
            t = time.perf_counter()
            imgs = judge_images(pred)
            rec["render_s"] = time.perf_counter() - t
            for k in envs:
                rec[f"{k}_psnr"] = min(float(psnr(imgs[k], ref_imgs[k])), PSNR_CAP)
                rec[f"{k}_delta_e"] = float(delta_e_2000(imgs[k], ref_imgs[k]))
            if args.judges == "suite":
                held = [k for k in envs if k != "reference"]
                for m in ("psnr", "delta_e"):
                    rec[f"heldout_{m}"] = float(np.mean([rec[f"{k}_{m}"] for k in held]))
            vals, secs = cands(pred)
            rec.update(vals)
            rec["candidate_s"] = secs
            recs.append(rec)
        per_material[name] = score_material(recs)
        records += recs
        timings[name] = {"seconds": time.perf_counter() - tm, "reconstructions": len(recs),
                         "load_average": load_average()}
        print(f"[{i + 1}/{len(names)}] {name}: {len(recs)} reconstructions, {timings[name]['seconds']:.0f} s "
              f"(load {' '.join(map(str, load_average()))})", flush=True)
        summary = summarise(records, per_material)
        if args.json:
            info.update(wall_s=time.perf_counter() - t0, load_average_end=load_average(), timings=timings,
                        summary=summary, per_material=per_material, records=records)
            with atomic_open(args.json) as f:
                json.dump(info, f, indent=1)

    if len(names) == 1:  # one material: its reconstructions, judges and candidates
        print("\n| reconstruction | N | " + " | ".join(JUDGE_LABELS[j] for j in JUDGES) + " | "
              + " | ".join(CANDIDATES) + " |")
        print("| --- | --- |" + " ---: |" * (len(JUDGES) + len(CANDIDATES)))
        for r in records:
            print(f"| {r['reconstruction']} | {r['n'] or '-'} | " + " | ".join(f"{r[j]:.3f}" for j in JUDGES)
                  + " | " + " | ".join(f"{r[c]:.4g}" for c in CANDIDATES) + " |")
    print_tables(summarise(records, per_material))
    print(f"\n{len(names)} materials, {len(records)} reconstructions, {time.perf_counter() - t0:.0f} s "
          f"(load {' '.join(map(str, load_average()))})")


if __name__ == "__main__":
    main()
