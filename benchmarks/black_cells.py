"""Nothing black where the material is not: the cells each decoder decodes far below the
material's own value.

For every material of a folder (or of a list) and every row, the table is made as the
command line makes it (``brdfkit encode -m MODEL --kind KIND --size N`` then ``decode``;
``brdfkit sparse`` from ``N`` samples; IPCA from ``N`` samples) and compared with the
material's own table, cell by cell:

* the share of the cells where the material is above 0 that decode to less than 1% of
  its value (the black bands of the grazing half-angles, the latent's black corner);
* the cells of at least 1 /sr that decode to 0 (below 1e-6 of their value);
* the grazing rows: the median decoded / true ratio over the cells with ``theta_h >= 80
  deg`` (:func:`brdfkit.evaluation.metrics.grazing_ratio`; it follows the material when
  it lies in [0.5, 2]).

Nothing is rendered. Rows: ``MODEL:KIND-SIZE`` (an embedding), ``sparse:MODEL:N`` (the
default reconstruction from ``N`` uniform samples, seed 0), ``ipca:MODEL:N``.

    python benchmarks/black_cells.py proxies/merl --list merl-test.txt --first 10 \\
        --rows merl80-l40:basis-9 merl80-l40:basis-39 merl-rgl-l40:residual-39 merl-rgl-l7:hypernet-7 \\
               sparse:merl-rgl-l40:40 sparse:merl-rgl-l40:400 ipca:merl-rgl-l40:40 -o black-cells.json
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))


def counts(pred, ref) -> dict:
    """``{"positive", "below_1pct", "bright", "bright_zero", "grazing_ratio"}``: the cell
    counts of one table and its grazing rows' median ratio."""
    from brdfkit.evaluation.metrics import grazing_ratio

    ok = np.isfinite(ref) & np.isfinite(pred)
    pos = ok & (ref > 0)
    bright = ok & (ref >= 1.0)
    return {"positive": int(pos.sum()), "below_1pct": int((pos & (pred < 0.01 * ref)).sum()),
            "bright": int(bright.sum()), "bright_zero": int((bright & (pred < 1e-6 * ref)).sum()),
            "grazing_ratio": grazing_ratio(pred, ref)}


def _maker(spec: str):
    """``(label, make(table, name) -> table)`` of one row."""
    import brdfkit
    from brdfkit.acquisition.sampling import draw_samples

    head, _, rest = spec.partition(":")
    if head in ("sparse", "ipca"):
        model, _, n = rest.rpartition(":")
        method = "auto" if head == "sparse" else "ipca"

        def make(table, name, model=model, n=int(n), method=method):
            return brdfkit.sparse(draw_samples(table, n, seed=0), model, method=method)[0]
        return spec, make
    from brdfkit.bench.config import compression_entry
    from brdfkit.embeddings import choose_decoder

    model, kind, size = compression_entry(spec)
    dec = choose_decoder(kind, model, size=size)

    def make(table, name, dec=dec, size=size):
        return brdfkit.decode(brdfkit.encode(table, dec, size=size, source=name), dec)
    return f"{model}:{dec.kind}-{size or dec.default_size}", make


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folder")
    ap.add_argument("--list", help="names to take (one a line), in order; default: every table of the folder")
    ap.add_argument("--first", type=int, default=None, help="only the first N names")
    ap.add_argument("--rows", nargs="+", required=True)
    ap.add_argument("-o", "--output", required=True)
    a = ap.parse_args(sys.argv[1:] if argv is None else argv)
    from brdfkit.io.folders import read_exclude_list
    from brdfkit.io.merl import read_merl
    from brdfkit.runtime import set_torch_threads

    set_torch_threads()
    names = read_exclude_list(a.list) if a.list else sorted(f[:-7] for f in os.listdir(a.folder)
                                                            if f.endswith(".binary"))
    names = names[:a.first] if a.first else names
    rows = [_maker(spec) for spec in a.rows]
    recs = {label: {} for label, _ in rows}
    for name in names:
        ref = read_merl(os.path.join(a.folder, name + ".binary"))
        for label, make in rows:
            t = time.perf_counter()
            recs[label][name] = counts(make(ref, name), ref)
            c = recs[label][name]
            print(f"{name} {label}: {100 * c['below_1pct'] / max(c['positive'], 1):.4f}% below 1%, "
                  f"{c['bright_zero']} cells of >= 1 /sr at 0, grazing ratio {c['grazing_ratio']:.2f} "
                  f"({time.perf_counter() - t:.1f} s)", file=sys.stderr, flush=True)
    summary = {}
    for label, per in recs.items():
        tot = {k: sum(c[k] for c in per.values()) for k in ("positive", "below_1pct", "bright", "bright_zero")}
        ratios = {n: c["grazing_ratio"] for n, c in per.items() if c["grazing_ratio"] is not None}
        summary[label] = {"share_below_1pct": tot["below_1pct"] / max(tot["positive"], 1),
                          "worst_material": max(per, key=lambda n: per[n]["below_1pct"] / max(per[n]["positive"], 1)),
                          "bright_zero": tot["bright_zero"],
                          "materials_with_bright_zero": sorted(n for n, c in per.items() if c["bright_zero"]),
                          "grazing_in_range": sum(0.5 <= r <= 2.0 for r in ratios.values()),
                          "grazing_lowest": min(ratios.items(), key=lambda x: x[1], default=None),
                          "grazing_highest": max(ratios.items(), key=lambda x: x[1], default=None)}
    doc = {"folder": os.path.basename(os.path.normpath(a.folder)), "materials": names, "rows": a.rows,
           "records": recs, "summary": summary}
    with open(a.output + ".tmp", "w", encoding="utf-8") as fh:
        json.dump(doc, fh, indent=1)
    os.replace(a.output + ".tmp", a.output)
    print("| row | share below 1% | worst material | cells of >= 1 /sr at 0 | grazing ratio in [0.5, 2] | lowest | "
          "highest |\n| --- | ---: | --- | ---: | ---: | --- | --- |")
    for label, s in summary.items():
        lo, hi = (f"{m} {r:.2f}" if m else "" for m, r in (s["grazing_lowest"] or ("", 0), s["grazing_highest"] or ("", 0)))
        print(f"| {label} | {100 * s['share_below_1pct']:.4f}% | {s['worst_material']} | {s['bright_zero']} | "
              f"{s['grazing_in_range']} of {len(names)} | {lo} | {hi} |")


if __name__ == "__main__":
    main()
