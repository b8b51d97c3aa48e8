"""The human-readable outputs of a benchmark result: ``bench.md`` and the plots."""

from __future__ import annotations

import os

from brdfkit.atomic import atomic_open, atomic_path
from brdfkit.bench.config import METRICS
from brdfkit.bench.summary import mean, record_size

__all__ = ["write_markdown", "write_plots", "label"]

_LABELS = {"psnr": "PSNR (dB)", "delta_e": "Delta E 2000", "ssim": "SSIM",
           "log_rmse": "BRDF log RMSE", "time_s": "time (s)", "cpu_s": "CPU time (s)"}


def _fmt(x, digits):
    return "n/a" if x is None else f"{x:.{digits}f}"


def _pm(row, m, digits):
    s = row.get(m + "_sd_seeds")
    return _fmt(row.get(m), digits) + ("" if s is None else f" ± {s:.{digits}f}")


_DIGITS = {"psnr": 2, "delta_e": 2, "ssim": 4, "log_rmse": 4, "time_s": 3}


def label(row) -> str:
    """A sparse row's or record's method as the tables and plots name it: the method,
    with its sampling in brackets unless uniform (``prior (planned)``)."""
    sampling = row.get("sampling") or "uniform"
    return row["method"] if sampling == "uniform" else f"{row['method']} ({sampling})"


def write_markdown(path: str, result: dict) -> None:
    """The human-readable tables of a bench result (``bench.md``)."""
    cfg, env, summ = result["config"], result["environment"], result["summary"]
    lines = ["# brdfkit bench", "",
             f"- command: `{cfg.get('command') or 'brdfkit bench'}`",
             f"- started {result['started']}, {result['elapsed_s']:.0f} s wall; "
             f"{'complete' if result['complete'] else 'INCOMPLETE (interrupted)'}"
             + (f"; merged from {len(result['merged_from'])} runs" if result.get("merged_from") else ""),
             *([f"- materials dropped because not every merged run covered them: "
                f"{', '.join(result['dropped_materials'])}"] if result.get("dropped_materials") else []),
             f"- machine: {env['machine']}, {env['cpus']} CPUs, torch {env['torch']} "
             f"({env['threads']} thread(s) per process, {cfg['jobs']} process(es)), device {env['device']}",
             _renders_text(cfg), ""]
    if summ["sparse"]:
        lines += ["## Sparse reconstruction", "",
                  f"{result['materials']['sparse_count']} test material(s) from `{cfg['data']}`, "
                  f"{_seed_text(cfg)} each; mean over materials and draws ± standard deviation "
                  f"over draws of the per-draw mean; wall time of one reconstruction: mean (median); "
                  f"CPU time: mean, all threads of the process.", "", _sampling_text(cfg), "",
                  "| method | N | PSNR (dB) | Delta E 2000 | SSIM | BRDF log RMSE | wall time (s) | CPU time (s) | "
                  "ok / failed |",
                  "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
        for row in summ["sparse"]:
            lines.append(f"| {label(row)} | {row['n']} | {_pm(row, 'psnr', 2)} | {_pm(row, 'delta_e', 2)} | "
                         f"{_pm(row, 'ssim', 4)} | {_pm(row, 'log_rmse', 4)} | {_fmt(row['time_s'], 3)} "
                         f"({_fmt(row['time_s_median'], 3)}) | {_fmt(row['cpu_s'], 3)} | "
                         f"{row['count']} / {row['failures']} |")
        if len(cfg.get("scenes") or ["reference"]) > 1:
            lines += ["", "### Sparse, per scene: PSNR (dB) / Delta E 2000, mean over materials and draws", ""]
            lines += scene_table(summ["sparse"], [("method", label), ("N", lambda r: str(r["n"]))],
                                 cfg["scenes"])
        lines += ["", "### Per material: PSNR (dB), mean over draws", ""]
        lines += _per_material_table(result["records"], "psnr", 2)
        lines += ["", "### Per material: BRDF log RMSE, mean over draws", ""]
        lines += _per_material_table(result["records"], "log_rmse", 4)
    if summ.get("sparse_by_family"):
        lines += ["", "### Sparse, per family", "", "| family | method | N | PSNR (dB) | Delta E 2000 | SSIM | "
                  "BRDF log RMSE | materials |", "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: |"]
        for row in summ["sparse_by_family"]:
            lines.append(f"| {row['family']} | {label(row)} | {row['n']} | {_fmt(row['psnr'], 2)} | "
                         f"{_fmt(row['delta_e'], 2)} | {_fmt(row['ssim'], 4)} | {_fmt(row['log_rmse'], 4)} | "
                         f"{row['materials']} |")
    if summ["compression"]:
        lines += ["", "## Compression (encode the full table, decode)", "",
                  f"{result['materials']['compression_count']} material(s) from `{cfg['compression_data']}`; "
                  f"mean ± standard deviation over materials; time = encode + decode.", "",
                  "| model | numbers | PSNR (dB) | Delta E 2000 | SSIM | BRDF log RMSE | wall time (s) | "
                  "CPU time (s) | ok / failed |", "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
        for row in summ["compression"]:
            lines.append(f"| {row['method']} | {record_size(row)} | {_pmm(row, 'psnr', 2)} | {_pmm(row, 'delta_e', 2)} | "
                         f"{_pmm(row, 'ssim', 4)} | {_pmm(row, 'log_rmse', 4)} | {_fmt(row['time_s'], 3)} | "
                         f"{_fmt(row['cpu_s'], 3)} | {row['count']} / {row['failures']} |")
    scenes = cfg.get("scenes") or ["reference"]
    if len(scenes) > 1 and summ["compression"]:
        lines += ["", "### Compression, per scene: PSNR (dB) / Delta E 2000, mean over materials", ""]
        lines += scene_table(summ["compression"], [("model", lambda r: r["method"])], scenes)
    if summ.get("compression_by_training") and any(r.get("trained_on") for r in summ["compression_by_training"]):
        lines += ["", "### Compression: training materials against held-out ones", "",
                  "| model | material in its training set | PSNR (dB) | Delta E 2000 | SSIM | BRDF log RMSE | "
                  "materials |", "| --- | --- | ---: | ---: | ---: | ---: | ---: |"]
        for row in summ["compression_by_training"]:
            lines.append(f"| {row['method']} | {'yes' if row['trained_on'] else 'no'} | {_pmm(row, 'psnr', 2)} | "
                         f"{_pmm(row, 'delta_e', 2)} | {_pmm(row, 'ssim', 4)} | {_pmm(row, 'log_rmse', 4)} | "
                         f"{row['materials']} |")
    if summ.get("compression_by_family"):
        lines += ["", "### Compression, per family", "", "| family | model | PSNR (dB) | Delta E 2000 | SSIM | "
                  "BRDF log RMSE | materials |", "| --- | --- | ---: | ---: | ---: | ---: | ---: |"]
        for row in summ["compression_by_family"]:
            lines.append(f"| {row['family']} | {row['method']} | {_pmm(row, 'psnr', 2)} | {_pmm(row, 'delta_e', 2)} | "
                         f"{_pmm(row, 'ssim', 4)} | {_pmm(row, 'log_rmse', 4)} | {row['materials']} |")
    failures = [r for r in result["records"] if "error" in r]
    if failures:
        lines += ["", f"## Failures ({len(failures)})", ""]
        seen = set()
        for r in failures:
            key = (r["material"], label(r), r["error"])
            if key not in seen:
                seen.add(key)
                lines.append(f"- {r['material']}, {label(r)}: {r['error']}")
    lines.append("")
    with atomic_open(path, "w", encoding="utf-8") as f:
        f.write("\n".join(lines))


def _renders_text(cfg) -> str:
    """How the image metrics were taken: the scenes, the renderer, the size."""
    scenes = cfg.get("scenes") or ["reference"]
    where = (f"the {scenes[0]} scene" if len(scenes) == 1 else
             f"{len(scenes)} scenes of the suite ({', '.join(scenes)}; PSNR, Delta E and SSIM are their means, "
             f"the per-scene tables give each)")
    return (f"- renders: {where}, quadrature renderer, {cfg['resolution']} x {cfg['resolution']} pixels, whole "
            f"image; PSNR capped at 100 dB")


def scene_table(rows, key_cols, scenes) -> list[str]:
    """A markdown table of each scene's mean PSNR (dB) and Delta E per summary row (the
    rows' ``scenes``), ``key_cols`` ``[(header, function of a row)]`` first."""
    head = [h for h, _ in key_cols] + [f"{s} PSNR / Delta E" for s in scenes] + ["worst scene PSNR"]
    out = ["| " + " | ".join(head) + " |", "| " + " | ".join(["---"] * len(key_cols) + ["---:"] * (len(scenes) + 1))
           + " |"]
    for row in rows:
        per = row.get("scenes") or {}
        psnrs = [per[s]["psnr"] for s in scenes if s in per and per[s]["psnr"] is not None]
        cells = [f(row) for _, f in key_cols]
        cells += [f"{_fmt(per.get(s, {}).get('psnr'), 2)} / {_fmt(per.get(s, {}).get('delta_e'), 2)}" for s in scenes]
        cells.append(_fmt(min(psnrs), 2) if psnrs else "n/a")
        out.append("| " + " | ".join(cells) + " |")
    return out


def _sampling_text(cfg) -> str:
    """How the samples were made (docs/bench.md, "Sampling")."""
    parts = []
    for s in cfg.get("sampling") or ["uniform"]:
        if s == "uniform":
            parts.append("uniform: drawn uniformly over the Rusinkiewicz angles, another draw for every "
                         "(draw, N, material), the same for every method")
        else:
            basis = os.path.basename(cfg.get("plan_model") or cfg.get("ipca") or "?")
            parts.append(f"{s} (rows marked so): the table measured at the directions of `brdfkit plan -n N "
                         f"-m {basis} --design {cfg.get('plan_design', 'nielsen')} --seed DRAW`, the same for "
                         f"every material")
    return "Samples: " + "; ".join(parts) + "."


def _seed_text(cfg) -> str:
    seeds = cfg.get("seed_values") or list(range(cfg.get("first_seed", 0), cfg.get("first_seed", 0) + cfg["seeds"]))
    return f"{len(seeds)} draw(s) (seeds {', '.join(map(str, seeds))})"


def _pmm(row, m, digits):
    s = row.get(m + "_sd_materials")
    return _fmt(row.get(m), digits) + ("" if s is None else f" ± {s:.{digits}f}")


def _per_material_table(records, metric, digits) -> list[str]:
    sparse = [r for r in records if r["kind"] == "sparse"]
    methods = list(dict.fromkeys(label(r) for r in sparse))
    ns = sorted({r["n"] for r in sparse})
    cols = [(m, k) for k in ns for m in methods]
    cell: dict = {}
    for r in sparse:
        if "error" not in r:
            cell.setdefault((r["material"], label(r), r["n"]), []).append(r[metric])
    better = max if metric in ("psnr", "ssim") else min
    out = ["| material | " + " | ".join(f"{m} {k}" for m, k in cols) + " |",
           "| --- | " + " | ".join("---:" for _ in cols) + " |"]
    for mat in dict.fromkeys(r["material"] for r in sparse):
        vals = {c: mean(cell.get((mat,) + c, [])) for c in cols}
        best = {}
        for k in ns:
            got = [vals[(m, k)] for m in methods if vals[(m, k)] is not None]
            best[k] = better(got) if got else None
        out.append(f"| {mat} | " + " | ".join(
            ("**" + _fmt(vals[c], digits) + "**") if vals[c] is not None and vals[c] == best[c[1]]
            else _fmt(vals[c], digits) for c in cols) + " |")
    return out


_GRID_2X2 = {"left": 0.08, "right": 0.985, "bottom": 0.075, "top": 0.93, "wspace": 0.22, "hspace": 0.25}
_GRID_1X2 = {"left": 0.08, "right": 0.985, "bottom": 0.2, "top": 0.88, "wspace": 0.25}


def write_plots(folder: str, result: dict) -> list[str]:
    """``error_vs_n.png``, ``error_vs_time.png`` (sparse) and ``compression.png``; returns
    the files written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    written = []
    rows = result["summary"]["sparse"]
    methods = list(dict.fromkeys(label(r) for r in rows))
    for xkey, fname, xlabel in (("n", "error_vs_n.png", "number of samples N"),
                                ("time_s", "error_vs_time.png", "wall time per reconstruction (s)"),
                                ("cpu_s", "error_vs_cpu_time.png", "CPU time per reconstruction (s, all threads)")):
        if not rows:
            break
        # margins fixed rather than by the constrained layout engine, which laid out every
        # text twice and took half the plotting time
        fig, axes = plt.subplots(2, 2, figsize=(9, 7), gridspec_kw=_GRID_2X2)
        for ax, metric in zip(axes.flat, METRICS):
            for m in methods:
                pts = [r for r in rows if label(r) == m and r[metric] is not None and r[xkey] is not None]
                pts.sort(key=lambda r: r["n"])
                if not pts:
                    continue
                x = [r[xkey] for r in pts]
                y = [r[metric] for r in pts]
                err = [r[metric + "_sd_seeds"] or 0.0 for r in pts]
                ax.errorbar(x, y, yerr=err, marker="o", capsize=3, label=m)
                if xkey != "n":
                    for r in pts:
                        ax.annotate(str(r["n"]), (r[xkey], r[metric]), textcoords="offset points",
                                    xytext=(4, 4), fontsize=7)
            ax.set_xscale("log")
            # labels at 1, 2, 5 x 10^k in plain numbers; matplotlib's default labels the
            # minor ticks of a short log axis so that they overlap
            ax.xaxis.set_major_locator(matplotlib.ticker.LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
            ax.xaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(lambda v, _: f"{v:g}"))
            ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
            ax.set_xlabel(xlabel)
            ax.set_ylabel(_LABELS[metric])
            ax.grid(True, which="both", alpha=0.3)
        axes.flat[0].legend()
        title = {"n": "error against N", "time_s": "error against wall time (points labelled with N)",
                 "cpu_s": "error against CPU time (points labelled with N)"}[xkey]
        fig.suptitle(f"brdfkit bench: {title}; {result['materials']['sparse_count']} materials, "
                     f"{_seed_text(result['config'])}", fontsize=10)
        out = os.path.join(folder, fname)
        with atomic_path(out) as tmp:
            fig.savefig(tmp, dpi=80, format="png")
        plt.close(fig)
        written.append(out)
    comp = [r for r in result["records"] if r["kind"] == "compression" and "error" not in r]
    if comp:
        labels = list(dict.fromkeys(r["method"] for r in comp))
        fig, axes = plt.subplots(1, 2, figsize=(9, 3.5), gridspec_kw=_GRID_1X2)
        for ax, metric in zip(axes, ("psnr", "log_rmse")):
            ax.boxplot([[r[metric] for r in comp if r["method"] == lab] for lab in labels])
            ax.set_xticks(range(1, len(labels) + 1), [lab.replace(" (", "\n(") for lab in labels], fontsize=7)
            ax.set_ylabel(_LABELS[metric])
            ax.grid(True, alpha=0.3)
        fig.suptitle("compression: encode the full table, decode (per material)", fontsize=10)
        out = os.path.join(folder, "compression.png")
        with atomic_path(out) as tmp:
            fig.savefig(tmp, dpi=80, format="png")
        plt.close(fig)
        written.append(out)
    return written

