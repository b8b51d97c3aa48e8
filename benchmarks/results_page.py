"""The page ``docs/notes/results.md``, composed from two ``brdfkit bench`` results.

Everything that depends on a number is computed here from the records of the sparse
and compression ``bench.json`` (means and spreads by :func:`brdfkit.bench.summarise`,
the function ``bench.md`` uses); fixed prose is kept to the caveats and the method
descriptions. The paper's figures are those of Gokbudak et al. 2024 (Table 1 and the
compression table); FreNBRDF's from ``../shared/anchors.md``. Used by
``benchmarks/results.py``; not part of the library.
"""

from __future__ import annotations

import os

from brdfkit.bench import summarise
from brdfkit.bench.summary import mean, record_size

METHOD_ORDER = ("prior", "prior (planned)", "ipca", "ipca (planned)", "nbrdf", "nbrdf (planned)", "hypernet",
                "hypernet (planned)")
DONE_N = (40, 160, 400, 2000, 4000)
DONE_SEEDS = (0, 1, 2)
DONE_MARGIN_DB = 1.0
DONE_RMSE_RATIO = 0.8
DONE_PLANNED = (20, 40)

PAPER_SPARSE = {40: (29.58, 3.19), 160: (31.34, 2.68), 400: (32.74, 2.27), 2000: (34.53, 2.26), 4000: (33.17, 2.14)}
"""The paper's hypernetwork on MERL: ``{N: (PSNR dB, Delta E 2000)}``."""
PAPER_SSIM = (0.968, 0.979)
PAPER_COMPRESSION = {("hypernet", 7): 47.49, ("hypernet", 40): 47.68, ("ipca", None): 29.89}
PAPER_NPS = 46.13

METHOD_TEXT = {
    "prior": "**prior**: `brdfkit sparse`'s default as shipped, the learnt prior of the built-in "
             "`merl80-l40`: its 32-component PCA basis fitted to the samples in closed form around a "
             "prior mean of its coefficients that a set encoder predicts. Not the paper's architecture "
             "([generalisation.md](generalisation.md)).",
    "ipca": "**ipca**: the PCA baseline (Nielsen et al. 2015), a basis fitted on the same 80 training "
            "materials, ridge fit to the samples ([baselines.md](../baselines.md)).",
    "nbrdf": "**nbrdf**: a 6-21-21-3 NBRDF network (Sztrajman et al. 2021) fitted to the samples of each "
             "material from scratch ([baselines.md](../baselines.md)).",
    "hypernet": "**hypernet**: the paper's method, the encoder / decoder of the built-in `merl80-l40` "
                "(set encoder of the samples, hypernetwork decoder of a neural BRDF), as `brdfkit sparse "
                "--method hypernet` runs it: then refined on the samples (the latent, then the hyponet's "
                "weights, early-stopped on held-out samples; the paper does not refine; "
                "[generalisation.md](generalisation.md), Lever 4).",
}
PLANNED_TEXT = ("**M (planned)**: method M from samples measured at the directions `brdfkit plan -n N -m "
                "merl80-l40 --design render` chooses for the learnt prior ([planning.md](../planning.md)); the same "
                "directions for every material and method, another plan (seed) per draw.")
COMPRESSION_TEXT = ("**Compressors**: `basis-39 (B)` is `brdfkit encode` then `decode` with the built-in "
                    "M as it runs by default, a basis embedding: the coefficients of the 13 leading components of "
                    "M's PCA basis B (39 numbers), refined on the objective scenes' renders "
                    "([compression.md](compression.md)); `hypernet-40 (M)` / `hypernet-7` is the hypernetwork's "
                    "latent (`encode --kind hypernet`, the paper's compression, refined on screen; `latent-40 (M)` in "
                    "earlier runs); `basis-K (3K numbers, B)`, `basis-K (3K numbers)`: least-squares projection onto "
                    "the K leading components of a PCA basis fitted on the same materials (`pca-K` in earlier runs).")
_HIGHER = {"psnr": True, "ssim": True, "delta_e": False, "log_rmse": False}


def scene_text(cfg) -> str:
    """Where the image metrics were taken: the suite's mean or one scene."""
    scenes = cfg.get("scenes") or ["reference"]
    res = cfg["resolution"]
    if len(scenes) == 1:
        return f"{scenes[0]} scene {res} x {res}"
    return f"mean of {len(scenes)} scenes, {res} x {res}"


def scene_section(rows, key_cols, cfg, what: str) -> list[str]:
    """Each scene's mean PSNR / Delta E per summary row, and the worst scene: the per-scene
    view of a run in the scene suite (empty for a one-scene run)."""
    from brdfkit.bench.report import scene_table

    scenes = cfg.get("scenes") or ["reference"]
    if len(scenes) < 2:
        return []
    return [f"#### {what}, per scene: PSNR (dB) / Delta E 2000", "",
            "Each scene of the suite ([render.md](../render.md#the-scene-suite)). Today's built-in models were "
            "tuned on renders of the **reference** environment (issue 21): its column is in-sample for them "
            "and given for continuity. No objective fitted the others (`brdfkit encode` refines on the "
            "objective scenes `studio-0..3`, never a judged one; [render-error.md](render-error.md)).", "",
            *scene_table(rows, key_cols, scenes), ""]


def plural(k: int, word: str) -> str:
    return f"{k} {word}" + ("" if k == 1 else "s")


def fmt(x, digits):
    return "n/a" if x is None else f"{x:.{digits}f}"


def cell(row, metric, digits, spread="_sd_seeds"):
    """``mean ± spread`` of a summary row (``n/a`` when missing)."""
    if row is None or row.get(metric) is None:
        return "n/a"
    s = row.get(metric + spread)
    return fmt(row[metric], digits) + ("" if s is None else f" ± {s:.{digits}f}")


def ok_records(result, kind):
    return [r for r in result["records"] if r["kind"] == kind and "error" not in r]


def methods_of(result) -> list[str]:
    got = list(dict.fromkeys(r["method"] for r in result["records"] if r["kind"] == "sparse"))
    return [m for m in METHOD_ORDER if m in got] + [m for m in got if m not in METHOD_ORDER]


def per_material(records, metric) -> dict:
    """``{(method, N, material): mean over draws}`` of ``metric``."""
    cells: dict = {}
    for r in records:
        cells.setdefault((r["method"], r["n"], r["material"]), []).append(r.get(metric))
    return {k: mean(v) for k, v in cells.items()}


def wins(pm, a, b, n, metric):
    """Materials where method ``a`` is better than ``b`` at ``N``, and those compared."""
    mats = sorted(m for (meth, k, m), v in pm.items()
                  if meth == a and k == n and v is not None and pm.get((b, n, m)) is not None)
    higher = _HIGHER[metric]
    won = [m for m in mats if (pm[(a, n, m)] > pm[(b, n, m)]) == higher and pm[(a, n, m)] != pm[(b, n, m)]]
    return won, mats


def win_text(won, mats) -> str:
    k, t = len(won), len(mats)
    if not t:
        return "n/a"
    if 0 < k <= 4 and k < t:
        return f"{k} / {t} ({', '.join(won)})"
    if 0 < t - k <= 4 and k > 0:
        return f"{k} / {t} (all but {', '.join(m for m in mats if m not in won)})"
    return f"{k} / {t}"


def with_sampling_labels(result) -> dict:
    """``result`` with each planned-sampling sparse record's method named ``"M (planned)"``,
    so that a table has a column per method and sampling (uniform keeps the bare name)."""
    recs = [dict(r, method=f"{r['method']} (planned)") if r["kind"] == "sparse" and r.get("sampling") == "planned"
            else r for r in result["records"]]
    return dict(result, records=recs)


def done_when(sparse) -> dict:
    """Issue 22's check, over draws :data:`DONE_SEEDS` and the (material, draw) pairs both
    methods of a comparison finished: at each N of :data:`DONE_N`, the default (``prior``,
    uniform samples) against ``ipca`` (PSNR at least IPCA's + :data:`DONE_MARGIN_DB` (0 dB
    at the first N), log RMSE at most :data:`DONE_RMSE_RATIO` of IPCA's); and ``prior`` from
    :data:`DONE_PLANNED` planned directions against ``prior`` from as many uniform samples as
    the second number (PSNR at least as high)."""
    ok = {(r["method"], r.get("sampling", "uniform"), r["n"], r["material"], r.get("seed")): r
          for r in ok_records(sparse, "sparse") if r.get("seed") in DONE_SEEDS}

    def compare(a, b):
        pairs = [(mat, s) for (meth, smp, k, mat, s) in ok if (meth, smp, k) == a and (*b, mat, s) in ok]
        if not pairs:
            return None
        rs = {key: [ok[(*key, mat, s)] for mat, s in pairs] for key in (a, b)}
        means = {key: {m: mean([r[m] for r in v]) for m in ("psnr", "log_rmse")} for key, v in rs.items()}
        return {"materials": len({m for m, _ in pairs}), "seeds": sorted({s for _, s in pairs}),
                "a": means[a], "b": means[b]}

    rows = []
    for i, n in enumerate(DONE_N):
        c = compare(("prior", "uniform", n), ("ipca", "uniform", n))
        margin = 0.0 if i == 0 else DONE_MARGIN_DB
        if c is None:
            rows.append({"what": f"N = {n}", "measured": False})
            continue
        ratio = c["a"]["log_rmse"] / c["b"]["log_rmse"]
        rows.append({"what": f"N = {n}", "measured": True, **c, "margin": margin, "ratio": ratio,
                     "met": [c["a"]["psnr"] >= c["b"]["psnr"] + margin, ratio <= DONE_RMSE_RATIO]})
    planned, uniform = DONE_PLANNED
    c = compare(("prior", "planned", planned), ("prior", "uniform", uniform))
    rows.append({"what": f"{planned} planned against {uniform} uniform", "measured": c is not None,
                 **(c or {}), "planned": True, "met": [c["a"]["psnr"] >= c["b"]["psnr"]] if c else []})
    complete = all(r["measured"] and r["seeds"] == list(DONE_SEEDS) for r in rows)
    verdicts = [v for r in rows for v in r.get("met", [])]
    verdict = ("no" if not all(verdicts) else "yes" if complete else
               "not established (the run lacks some N, sampling or draws 0, 1, 2)")
    return {"rows": rows, "verdict": verdict, "complete": complete}


def done_lines(check) -> list[str]:
    """The check as plain lines (printed by the script and put on the page)."""
    yn = {True: "met", False: "**missed**"}
    out = []
    for r in check["rows"]:
        if not r["measured"]:
            out.append(f"{r['what']}: not measured")
            continue
        tail = f"{plural(r['materials'], 'material')}, draws {', '.join(map(str, r['seeds']))}"
        if r.get("planned"):
            out.append(f"{r['what']}: prior PSNR {r['a']['psnr']:.2f} vs {r['b']['psnr']:.2f} dB, at least as "
                       f"high: {yn[r['met'][0]]}; {tail}")
            continue
        out.append(f"{r['what']}: prior PSNR {r['a']['psnr']:.2f} vs ipca {r['b']['psnr']:.2f} dB (target "
                   f"ipca + {r['margin']:g}): {yn[r['met'][0]]}; log RMSE {r['a']['log_rmse']:.4f} vs "
                   f"{r['b']['log_rmse']:.4f}, ratio {r['ratio']:.2f} (target <= {DONE_RMSE_RATIO:g}): "
                   f"{yn[r['met'][1]]}; {tail}")
    out.append(f"Done when met: {check['verdict']}")
    return out


def _listed(path) -> list[str]:
    """The names of a test list (empty when it cannot be read here)."""
    from brdfkit.io.folders import read_exclude_list

    try:
        return list(read_exclude_list(path)) if path and os.path.isfile(path) else []
    except Exception:  # a list that does not parse: coverage is then not stated
        return []


def _ns(records):
    return sorted({r["n"] for r in records})


def _n_list(ns) -> str:
    return ", ".join(map(str, ns)) if ns else "none"


def sparse_section(sparse) -> list[str]:
    recs = ok_records(sparse, "sparse")
    methods, ns = methods_of(sparse), _ns(recs)
    rows = {(r["method"], r["n"]): r for r in summarise(recs)["sparse"]}
    cfg = sparse["config"]
    seeds = sorted({r.get("seed") for r in recs})
    failed = [r for r in sparse["records"] if r["kind"] == "sparse" and "error" in r]
    mats = sparse["materials"]["sparse"]
    listed = _listed(cfg.get("test_list"))
    missing = sorted(set(listed) - set(mats))
    coverage = (f"**Coverage: {len(mats)} of the {len(listed)} test materials** of "
                f"`{os.path.basename(cfg['test_list'])}` (missing: {', '.join(missing)}). " if missing else "")
    by_method = {m: sum(1 for r in failed if r["method"] == m) for m in methods}
    lines = ["## Sparse reconstruction (the paper's Table 1 setting)", "",
             coverage + f"{plural(len(mats), 'test material')}, {plural(len(seeds), 'draw')} per (material, N) "
             f"(seeds {', '.join(map(str, seeds))}), the same samples for every method. `±` is the standard "
             f"deviation over the draws of the mean over materials (per-material figures are in `bench.json`). "
             + (f"**{plural(len(failed), 'reconstruction')} failed** ("
                + ", ".join(f"{m} {k}" for m, k in by_method.items() if k)
                + "), left out of the means (`bench.md` lists them)." if failed else "No reconstruction failed.")
             + ("" if sparse.get("complete") else " **The run did not finish**: these are the materials it did."),
             ""]
    if not recs:
        return lines + ["No sparse record.", ""]
    where = scene_text(cfg)
    for metric, digits, title in (("psnr", 2, f"PSNR (dB), {where}"),
                                  ("delta_e", 2, f"Delta E 2000, {where}"),
                                  ("ssim", 3, f"SSIM, {where}"),
                                  ("log_rmse", 4, "BRDF log RMSE (cosine-weighted, lower is better)")):
        paper = metric in ("psnr", "delta_e", "ssim")
        lines += [f"#### {title}", "",
                  "| N |" + (" paper hypernet |" if paper else "") + "".join(f" {m} |" for m in methods),
                  "| ---: |" + (" ---: |" if paper else "") + " ---: |" * len(methods)]
        for n in ns:
            if metric == "ssim":
                ref = f" {PAPER_SSIM[0]:.3f} ... {PAPER_SSIM[1]:.3f} |"
            elif paper:
                got = PAPER_SPARSE.get(n)
                ref = f" {got[0 if metric == 'psnr' else 1]:.2f} |" if got else " - |"
            else:
                ref = ""
            lines.append(f"| {n} |{ref}" + "".join(f" {cell(rows.get((m, n)), metric, digits)} |" for m in methods))
        lines.append("")
    lines += scene_section([rows[(m, n)] for m in methods for n in ns if (m, n) in rows],
                           [("method", lambda r: r["method"]), ("N", lambda r: str(r["n"]))], cfg,
                           "Sparse reconstruction")
    lines += ["#### Run time per reconstruction (samples in, dense table out; one torch thread)", "",
              "| N |" + "".join(f" {m} CPU s |" for m in methods) + "".join(f" {m} wall s |" for m in methods),
              "| ---: |" + " ---: |" * (2 * len(methods))]
    for n in ns:
        lines.append(f"| {n} |" + "".join(f" {fmt((rows.get((m, n)) or {}).get('cpu_s'), 2)} |" for m in methods)
                     + "".join(f" {fmt((rows.get((m, n)) or {}).get('time_s'), 2)} |" for m in methods))
    lines.append("")
    if "prior" in methods and len(methods) > 1:
        # each against the same samples: the uniform rows here; planned against uniform is the done-when's
        others = [m for m in methods if m != "prior" and not m.endswith("(planned)")]
        pm = {metric: per_material(recs, metric) for metric in ("psnr", "log_rmse")}
        lines += ["#### The learnt prior against each other method, per material (mean over the draws)", "",
                  "| N |" + "".join(f" prior PSNR higher than {m} |" for m in others)
                  + "".join(f" prior log RMSE lower than {m} |" for m in others),
                  "| ---: |" + " ---: |" * (2 * len(others))]
        for n in ns:
            lines.append(f"| {n} |" + "".join(f" {win_text(*wins(pm['psnr'], 'prior', m, n, 'psnr'))} |"
                                              for m in others)
                         + "".join(f" {win_text(*wins(pm['log_rmse'], 'prior', m, n, 'log_rmse'))} |"
                                   for m in others))
        lines.append("")
    return lines


def sparse_findings(sparse) -> list[str]:
    """Generated bullets: every figure in them comes from the records."""
    recs = ok_records(sparse, "sparse")
    methods, ns = methods_of(sparse), _ns(recs)
    if not recs:
        return []
    rows = {(r["method"], r["n"]): r for r in summarise(recs)["sparse"]}
    get = lambda m, n, k: (rows.get((m, n)) or {}).get(k)  # noqa: E731
    out = ["### What the numbers say", ""]
    best = []
    for n in ns:
        ranked = {k: [m for m in methods if get(m, n, k) is not None] for k in ("psnr", "log_rmse")}
        bp = max(ranked["psnr"], key=lambda m: get(m, n, "psnr"), default=None)
        br = min(ranked["log_rmse"], key=lambda m: get(m, n, "log_rmse"), default=None)
        best.append(f"N = {n}: {bp} / {br}")
    out.append("* Best mean PSNR / best mean BRDF log RMSE: " + "; ".join(best) + ".")
    if "prior" in methods:
        pm = {metric: per_material(recs, metric) for metric in ("psnr", "log_rmse")}
        for m in methods:
            if m == "prior" or m.endswith("(planned)"):  # prior's uniform samples against the same samples
                continue
            hi = [n for n in ns if None not in (get("prior", n, "psnr"), get(m, n, "psnr"))
                  and get("prior", n, "psnr") > get(m, n, "psnr")]
            lo = [n for n in ns if None not in (get("prior", n, "log_rmse"), get(m, n, "log_rmse"))
                  and get("prior", n, "log_rmse") < get(m, n, "log_rmse")]
            per = [f"{len(wins(pm['log_rmse'], 'prior', m, n, 'log_rmse')[0])}/"
                   f"{len(wins(pm['log_rmse'], 'prior', m, n, 'log_rmse')[1])}" for n in ns]
            out.append(f"* prior against {m}: higher mean PSNR at N = {_n_list(hi)} (of {len(ns)} N), lower mean "
                       f"log RMSE at N = {_n_list(lo)}; lower log RMSE per material at N = {_n_list(ns)}: "
                       f"{', '.join(per)}.")
    for m in methods:
        own = [n for n in ns if get(m, n, "psnr") is not None] or ns
        first, last = own[0], own[-1]
        out.append(f"* {m}: log RMSE {fmt(get(m, first, 'log_rmse'), 4)} (N = {first}) to "
                   f"{fmt(get(m, last, 'log_rmse'), 4)} (N = {last}), PSNR {fmt(get(m, first, 'psnr'), 2)} to "
                   f"{fmt(get(m, last, 'psnr'), 2)} dB; CPU time {_range([get(m, n, 'cpu_s') for n in own], 2)} s "
                   f"per reconstruction.")
    out.append("")
    return out


def _range(values, digits) -> str:
    v = [x for x in values if x is not None]
    if not v:
        return "n/a"
    lo, hi = min(v), max(v)
    return fmt(lo, digits) if fmt(lo, digits) == fmt(hi, digits) else f"{fmt(lo, digits)}-{fmt(hi, digits)}"


def paper_section(sparse, model_name: str) -> list[str]:
    recs = ok_records(sparse, "sparse")
    rows = {(r["method"], r["n"]): r for r in summarise(recs)["sparse"]}
    diffs = []
    for n, (psnr, de) in PAPER_SPARSE.items():
        row = rows.get(("hypernet", n))
        if row and row.get("psnr") is not None:
            diffs.append(f"N = {n}: {row['psnr']:.2f} dB ({row['psnr'] - psnr:+.2f} dB), "
                         f"Delta E {fmt(row.get('delta_e'), 2)} ({(row.get('delta_e') or 0) - de:+.2f})")
    ssim = [r.get("ssim") for (m, _), r in rows.items() if m == "hypernet"]
    lines = ["### Against the paper's figures", "",
             "The paper reports, for its hypernetwork on MERL, PSNR " + " / ".join(f"{v[0]:.2f}" for v in
                                                                                    PAPER_SPARSE.values())
             + " dB and Delta E " + " / ".join(f"{v[1]:.2f}" for v in PAPER_SPARSE.values())
             + " at N = " + " / ".join(map(str, PAPER_SPARSE)) + f", SSIM {PAPER_SSIM[0]} ... {PAPER_SSIM[1]}. "
             "FreNBRDF (Zhou, Hu, Oztireli 2025) publish, for MERL reconstruction, HyperBRDF 26.3 dB against "
             "NBRDF 29.2 dB PSNR (SSIM 0.926 against 0.950).", ""]
    if diffs:
        lines.append(f"* What differs, generated: our hypernetwork (`{model_name}`, refined on the samples as "
                     f"shipped) against the paper's (one encoder pass): "
                     + "; ".join(diffs) + f"; SSIM {_range(ssim, 3)}.")
    lines += ["* The scene, the resolution, the data (proxies) and the training budget differ (table at the "
              "top), so equal figures would be a coincidence and unequal ones do not refute the paper; the "
              "comparison that holds is between the methods of this page, which saw the same samples and "
              "were scored in the same scene.", ""]
    return lines


def family_of(name: str, proxies: str) -> str:
    """``MERL`` / ``RGL`` by the proxies folder that holds ``NAME.binary`` (else ``other``)."""
    for sub, label in (("merl", "MERL"), ("rgl", "RGL")):
        if os.path.exists(os.path.join(proxies, sub, name + ".binary")):
            return label
    return "other"


def _paper_comp(label: str, latent) -> str:
    """The paper's figure beside a row: its IPCA beside the 8-component PCA (Nielsen et al.'s
    IPCA-8, the brief's baseline: ``basis-8 (24 numbers ...)``, a projection; ``pca-8`` in
    earlier runs), its hypernetwork beside a latent of its size (``hypernet-40 (M)``; the
    older labels ``latent-40 (M)`` and ``hypernet 40-D (M)`` too), none beside the rest (a
    basis embedding ``basis-39 (B)`` among them)."""
    head = label.split()[0]
    projection = head.startswith("pca-") or (head.startswith("basis-") and " numbers" in label)
    if projection or head in ("pca", "ipca"):
        k = head.partition("-")[2] if projection else (label.split() + [""])[1]
        got = PAPER_COMPRESSION[("ipca", None)] if k == "8" else None
    elif head.startswith(("latent-", "hypernet-")) or head == "hypernet":
        got = PAPER_COMPRESSION.get(("hypernet", latent))
    else:
        got = None
    return "-" if got is None else f"{got:.2f}"


def compression_section(comp, proxies, figure=True, title="Compression (the paper's compression table)",
                        intro="") -> list[str]:
    recs = ok_records(comp, "compression")
    failed = [r for r in comp["records"] if r["kind"] == "compression" and "error" in r]
    mats = comp["materials"]["compression"]
    fam = {m: family_of(m, proxies) for m in mats}
    counts = {f: sum(1 for v in fam.values() if v == f) for f in ("MERL", "RGL", "other")}
    lines = [f"## {title}", "",
             (intro + " " if intro else "") + f"{len(mats)} materials ({counts['MERL']} MERL, {counts['RGL']} RGL"
             + (f", {counts['other']} neither" if counts["other"] else "") + "), each table encoded whole and "
             f"decoded (IPCA and PCA-K: least-squares projection onto its components, then decode; PCA-K stores 3 K "
             f"numbers, so PCA-13 sits beside a 40-D latent and PCA-2 beside 7-D). Renders: "
             f"{scene_text(comp['config'])}. `±` is the standard "
             "deviation over materials; time = encode + decode. "
             + (f"**{len(failed)} failed** (left out)." if failed else "No reconstruction failed.")
             + ("" if comp.get("complete") else " **The run did not finish.**"),
             f"The paper: 7-D {PAPER_COMPRESSION[('hypernet', 7)]} dB, 40-D {PAPER_COMPRESSION[('hypernet', 40)]} "
             f"dB, NPs {PAPER_NPS} dB, IPCA {PAPER_COMPRESSION[('ipca', None)]} dB (PSNR, MERL).", ""]
    if not recs:
        return lines + ["No compression record.", ""]
    lines += ["| model | materials | n | PSNR (dB) | paper PSNR | Delta E 2000 | SSIM | BRDF log RMSE | CPU s "
              "| wall s |",
              "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    groups = [("all", recs)] + [(f, [r for r in recs if fam.get(r["material"]) == f])
                                for f in ("MERL", "RGL", "other") if counts[f]]
    table = {}
    for gname, grecs in groups:
        for row in summarise(grecs)["compression"]:
            table[(row["method"], gname)] = row
    labels = list(dict.fromkeys(r["method"] for r in recs))
    paper_row = "MERL" if counts["MERL"] else "all"  # the paper's figures are on MERL
    latent = {r["method"]: record_size(r) for r in recs}
    for label in labels:
        for gname, _ in groups:
            row = table.get((label, gname))
            if row is None:
                continue
            lines.append(f"| {label} | {gname} | {row['materials']} | {cell(row, 'psnr', 2, '_sd_materials')} | "
                         f"{_paper_comp(label, latent[label]) if gname == paper_row else '-'} | "
                         f"{cell(row, 'delta_e', 2, '_sd_materials')} | {cell(row, 'ssim', 4, '_sd_materials')} | "
                         f"{cell(row, 'log_rmse', 4, '_sd_materials')} | {fmt(row['cpu_s'], 2)} | "
                         f"{fmt(row['time_s'], 2)} |")
    lines.append("")
    lines += scene_section([table[(label, "all")] for label in labels], [("model", lambda r: r["method"])],
                           comp["config"], "Compression")
    if figure:
        lines += ["![compression per material](images/bench-compression.png)", ""]
    lines += highlight_lines(recs, labels)
    for label in labels:
        trained = sum(1 for r in recs if r["method"] == label and r.get("trained_on"))
        total = sum(1 for r in recs if r["method"] == label)
        row, paper = table[(label, "all")], _paper_comp(label, latent[label])
        diff = "" if paper == "-" else f" ({row['psnr'] - float(paper):+.2f} dB against the paper's {paper} dB)"
        lines.append(f"* {label}: {fmt(row['psnr'], 2)} dB on all {row['materials']}{diff}; "
                     + "; ".join(f"{g} {fmt(table[(label, g)]['psnr'], 2)} dB" for g, _ in groups[1:]
                                 if (label, g) in table)
                     + f"; {trained} of its {total} materials were in its training set.")
    lines.append("")
    return lines


def highlight_lines(recs, labels, worst: int = 3) -> list[str]:
    """Invented or lost highlights (:func:`brdfkit.evaluation.metrics.highlights`, in the
    records as ``highlights``): per model, the materials whose peak region (and grazing
    band) is furthest from the table's, in log10 of the mean luminance."""
    have = [r for r in recs if isinstance(r.get("highlights"), dict)]
    if not have:
        return []
    out = ["#### Invented or lost highlights", "",
           "The peak region (`theta_h` < 5 degrees) of each decoded table against the material's, as "
           "`brdfkit metrics` checks it: log10 of the ratio of their mean luminance below (`peak`) and above "
           "(`grazing`) `theta_d` = 60 degrees; +0.30 is a peak twice as bright (invented), -1.00 ten times "
           "darker (lost). Per model, the mean absolute value and the materials furthest off:", "",
           "| model | mean abs peak | worst peak | mean abs grazing | worst grazing |",
           "| --- | ---: | --- | ---: | --- |"]
    for label in labels:
        rs = [r for r in have if r["method"] == label]
        cells = []
        for key in ("peak", "grazing"):
            vals = [(r["highlights"].get(key), r["material"]) for r in rs if r["highlights"].get(key) is not None]
            if not vals:
                cells += ["n/a", "n/a"]
                continue
            vals.sort(key=lambda v: -abs(v[0]))
            cells += [f"{sum(abs(v) for v, _ in vals) / len(vals):.3f}",
                      ", ".join(f"{m} {v:+.2f}" for v, m in vals[:worst])]
        out.append(f"| {label} | " + " | ".join(cells) + " |")
    return out + [""]

