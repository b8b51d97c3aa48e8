"""Decided: ``render`` and ``metrics`` evaluate an RGL ``.bsdf`` straight from the file,
conditioned on the view as Mitsuba 3 does (4 of 5 files agree with Mitsuba's renders to
45 dB or better, 35.6 to 43.0 dB through a table), and a file's MERL table is made by the
``least-squares`` reciprocity rule, the default (2.4 dB above the old ``grazing`` rule in
the mean over 27 files). Reported in ``docs/notes/rgl-bsdf.md``, "RGL's own files".

RGL's own measured files (``*_rgb.bsdf``): do they load, what does a MERL table of one
lose, and does brdfkit render one as Mitsuba 3 does?

The files are RGL's material database's (Dupuy and Jakob 2018), fetched from public
repositories; their licence keeps them out of the repository. They are read from the
folder ``$BRDFKIT_REAL_DATA/rgl`` (every ``*_rgb.bsdf`` in it). Jobs (any combination):

* ``--load``: every file read and checked; its non-reciprocity (the log RMS between its
  two conditionings over the MERL grid, :meth:`brdfkit.io.rgl_bsdf.RglBsdf.reciprocal_table`).
* ``--tables``: the loss of a MERL table: each file's quadrature render (the reference
  scene, ``--px``, 4 x 4 points a pixel) straight from the file (conditioned on the view,
  as Mitsuba does) against the renders of its MERL tables, one per reciprocity rule
  (:data:`brdfkit.io.rgl_bsdf.RULES`); PSNR over the sphere less its silhouette pixels.
* ``--mitsuba NAME ...``: Mitsuba 3's ``measured`` plugin path-traces the file (``scalar_rgb``,
  ``--spp``, ``--px``) against brdfkit's quadrature render of the file (4 x 4 points a
  pixel: Mitsuba box-filters a pixel) and of its tables (the ``mean`` rule, and the
  ``grazing`` rule, which is what brdfkit rendered before the file was evaluated directly).
  ``--integrator emitter`` renders by light sampling alone instead (Mitsuba's ``direct``
  integrator without BSDF samples: the file's BSDF is evaluated, never sampled; the lead
  of ``chm_mint``'s gap, ``docs/notes/rgl-bsdf.md``).
* ``--quadrature NAME ...``: brdfkit's render of the file at denser quadratures
  (:data:`DENSER`) against Mitsuba's path tracer (two seeds), and Mitsuba's render by light
  sampling alone (two seeds, ``--emitter-spp``) against both, by pixel and by region of the
  sphere: which of the two renderers leaves ``chm_mint``'s gap (``docs/notes/rgl-bsdf.md``).
* ``--sampling NAME ...``: where Mitsuba's ``measured`` plugin draws its BSDF samples
  against the density its ``pdf`` gives them (rings about the mirror direction, four
  quadrants each): the path tracer weighs a BSDF sample by that density.
  ``--seeds 2`` also renders each name with a second seed (Mitsuba's own noise
  floor, per material), and ``--control TABLE`` writes a MERL table as a ``.bsdf`` and compares
  brdfkit's render of that file with Mitsuba's (the renderers' agreement on a file
  brdfkit wrote).

``--json PATH`` writes the record: the command, the machine, the load average at start
and end, every row; no path of the machine (files by name). Example (the figures of
``docs/rgl-bsdf.md``)::

    BRDFKIT_REAL_DATA=DATA nice python benchmarks/studies/rgl_real.py --load --tables \\
        --mitsuba cardboard_rgb paper_white_rgb vch_golden_yellow_rgb ilm_solo_m_68_rgb chm_mint_rgb \\
        --seeds 2 --control PROXIES/merl/teflon.binary --json benchmarks/results/DATE-rgl-real.json

Benchmarks import nothing from ``tests/``; one torch thread (``--threads``).
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))  # benchmarks/common.py
from common import load_average, record_options, set_threads, write_record  # noqa: E402

SUPERSAMPLE = 4


def _files():
    root = os.environ.get("BRDFKIT_REAL_DATA")
    if not root or not os.path.isdir(os.path.join(root, "rgl")):
        sys.exit("rgl_real.py: error: set BRDFKIT_REAL_DATA to a folder holding rgl/*_rgb.bsdf")
    folder = os.path.join(root, "rgl")
    return {n[:-5]: os.path.join(folder, n) for n in sorted(os.listdir(folder)) if n.endswith("_rgb.bsdf")}


def _scene(px):
    from brdfkit.render.scene import REFERENCE

    return dataclasses.replace(REFERENCE, resolution=px, supersample=SUPERSAMPLE)


def inner_mask(px):
    """Pixels whose every sample point lies on the sphere: the sphere less its silhouette."""
    return _scene(px).pixel_normals()[1].all(2)


def _psnr(img, ref, mask):
    """PSNR over ``mask`` less the pixels not finite in either image (Mitsuba's
    ``measured`` returns NaN where a file's warp has an empty row; brdfkit returns 0)."""
    import numpy as np

    from brdfkit.evaluation.metrics import psnr

    ok = mask & np.isfinite(img).all(-1) & np.isfinite(ref).all(-1)
    return round(psnr(np.nan_to_num(img), np.nan_to_num(ref), ok), 3)


def _mean(img, mask):
    """Mean linear RGB over ``mask`` (finite pixels), 5 digits."""
    import numpy as np

    ok = mask & np.isfinite(img).all(-1)
    return [round(float(v), 5) for v in img[ok].mean(0)]


def _nonfinite(img, mask):
    import numpy as np

    return int((~np.isfinite(img).all(-1) & mask).sum())


def _renders(path, px, rules):
    """brdfkit's quadrature renders of a file: straight from it, and of its table per rule."""
    from brdfkit.files.brdf_file import load_brdf
    from brdfkit.io.rgl_bsdf import read_bsdf
    from brdfkit.render.quadrature import render, render_many
    from brdfkit.render.renderable import TableBRDF

    t0 = time.perf_counter()
    direct, _ = render(load_brdf(path), _scene(px))
    t1 = time.perf_counter()
    bsdf = read_bsdf(path)
    tables = [TableBRDF(bsdf.to_table(rule), device="cpu") for rule in rules]
    images = dict(zip(rules, (img for img, _ in render_many(tables, _scene(px)))))
    return direct, images, round(t1 - t0, 1)


def load(files):
    from brdfkit.io.rgl_bsdf import read_bsdf

    rows = []
    for name, path in files.items():
        t0 = time.perf_counter()
        bsdf = read_bsdf(path)
        _, asym = bsdf.reciprocal_table()
        rows.append({"material": name, "resolution": bsdf.resolution, "theta_i": int(bsdf.theta_i.size),
                     "non_reciprocity": round(asym, 4), "read_s": round(time.perf_counter() - t0, 2)})
        print(rows[-1], flush=True)
    return rows


def tables(files, px):
    from brdfkit.io.rgl_bsdf import RULES

    mask = inner_mask(px)
    rows = []
    for i, (name, path) in enumerate(files.items(), 1):
        direct, images, seconds = _renders(path, px, RULES)
        rows.append({"material": name, "direct_render_s": seconds,
                     **{f"psnr_{rule}": _psnr(images[rule], direct, mask) for rule in RULES}})
        print(f"[{i}/{len(files)}]", rows[-1], flush=True)
    return rows


RINGS = (0.0, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0, 30.0, 60.0, 180.0)
"""Rings of the sampling check, degrees from the mirror direction (each cut in four
quadrants about it)."""


def _bins(v, mirror, e1, e2):
    """(ring, quadrant) of unit directions ``v (M, 3)`` about ``mirror``."""
    import numpy as np

    a = np.degrees(np.arccos(np.clip(v @ mirror, -1, 1)))
    q = (((np.arctan2(v @ e2, v @ e1) + 2 * np.pi) % (2 * np.pi)) // (np.pi / 2)).astype(int) % 4
    return np.clip(np.searchsorted(RINGS, a, side="right") - 1, 0, len(RINGS) - 2), q


def sampling(files, names, n=60000, per_bin=2000, angles=(30, 60), seed=0):
    """Mitsuba's ``measured`` BSDF: where ``bsdf.sample`` puts its directions against the
    density ``bsdf.pdf`` says they follow, in rings about the mirror direction, at a few
    view angles (``n`` samples; the pdf integrated over each bin by ``per_bin`` stratified
    points). Its path tracer weighs each BSDF sample by ``pdf``: where the two disagree its
    render is biased, and a render by light sampling alone is not."""
    import numpy as np

    from brdfkit.testing.mitsuba_measured import measured_sampling

    rng = np.random.default_rng(seed)
    rows = []
    nb = len(RINGS) - 1
    for name in names:
        for ti in angles:
            t = np.radians(ti)
            mirror, e1, e2 = np.array([-np.sin(t), 0, np.cos(t)]), np.array([np.cos(t), 0, np.sin(t)]), np.array([0, 1.0, 0])
            pts, where, dw = [], [], []
            for i in range(nb):  # stratified points of each bin, and the solid angle each stands for
                c0, c1 = np.cos(np.radians(RINGS[i])), np.cos(np.radians(RINGS[i + 1]))
                for q in range(4):
                    uu, vv = (np.arange(per_bin) + rng.random(per_bin)) / per_bin, rng.permutation(
                        (np.arange(per_bin) + rng.random(per_bin)) / per_bin)
                    cz, ph = c0 + (c1 - c0) * uu, (q + vv) * np.pi / 2
                    sz = np.sqrt(1 - cz ** 2)
                    pts.append(cz[:, None] * mirror + sz[:, None] * (np.cos(ph)[:, None] * e1 + np.sin(ph)[:, None] * e2))
                    where += [(i, q)] * per_bin
                    dw.append(np.full(per_bin, (c0 - c1) * (np.pi / 2) / per_bin))
            pts, dw = np.concatenate(pts), np.concatenate(dw)
            m = max(n, pts.shape[0])
            wo = np.zeros((m, 3))
            wo[:pts.shape[0]] = pts
            wo[pts.shape[0]:, 2] = 1.0
            out = measured_sampling(files[name], np.tile([np.sin(t), 0.0, np.cos(t)], (m, 1)), rng.random((m, 3)), wo,
                                    timeout=7200)
            ok = out["sampled_pdf"][:n] > 0
            counts = np.zeros((nb, 4))
            np.add.at(counts, _bins(out["sampled"][:n][ok], mirror, e1, e2), 1)
            expected = np.zeros((nb, 4))
            above = pts[:, 2] > 0
            np.add.at(expected, tuple(np.array(where)[above].T), (out["pdf"][:pts.shape[0]] * dw)[above])
            frac = counts / n
            z = (frac - expected) / np.sqrt(np.maximum(expected, 1e-9) / n)
            rows.append({"material": name, "theta_i": ti, "samples": n, "rings_deg": list(RINGS),
                         "sampled_fraction": np.round(frac, 5).tolist(), "pdf_mass": np.round(expected, 5).tolist(),
                         "pdf_mass_total": round(float(expected.sum()), 4),
                         "excess_mass": round(float(np.clip(frac - expected, 0, None).sum()), 4),
                         "chi2_per_bin": round(float((z ** 2).mean()), 2), "max_abs_z": round(float(np.abs(z).max()), 1)})
            print({k: v for k, v in rows[-1].items() if k not in ("sampled_fraction", "pdf_mass", "rings_deg")},
                  flush=True)
    return rows


DENSER = {"default": {}, "2x": dict(cosine_grid=20, half_rings=40, half_phi=24, half_phi_min=10, light_density=1.5),
          "half 2x": dict(half_rings=40, half_phi=24, half_phi_min=10), "cosine 2x": dict(cosine_grid=20),
          "light 2x": dict(light_density=1.5),
          "11x": dict(cosine_grid=30, half_rings=80, half_phi=48, half_phi_min=20, light_density=2.0)}
"""Quadrature settings of ``--quadrature`` (:class:`brdfkit.render.scene.Quadrature` fields
over the reference scene's; ``11x``: about eleven times its nodes a point)."""


def _regions(px):
    """Masks of the sphere's rim (left, right, top, bottom) and centre, for region means."""
    n, m = _scene(px).pixel_normals()
    inner, nx, ny = m.all(2), n[..., 0, 0], n[..., 0, 1]
    rim = inner & (nx ** 2 + ny ** 2 > 0.75 ** 2)
    return {"left rim": rim & (nx < -0.3), "right rim": rim & (nx > 0.3), "top rim": rim & (ny > 0.3),
            "bottom rim": rim & (ny < -0.3), "centre": inner & ~(nx ** 2 + ny ** 2 > 0.75 ** 2)}


def quadrature(files, names, px, spp, emitter_spp):
    """brdfkit's render of each file at the quadratures of :data:`DENSER` against Mitsuba's
    path tracer (two seeds, ``spp``), and Mitsuba's render by light sampling alone (two seeds,
    ``emitter_spp``: it never samples the BSDF) against both, per pixel and by region means."""
    import numpy as np

    from brdfkit.files.brdf_file import load_brdf
    from brdfkit.render.quadrature import render
    from brdfkit.testing.mitsuba_measured import measured_render

    mask, regions = inner_mask(px), _regions(px)
    rows = []
    for name in names:
        path = files[name]
        mi = {f"path seed {s}": measured_render(path, resolution=px, spp=spp, seed=s, timeout=14400) for s in (0, 1)}
        mi.update({f"emitter seed {s}": measured_render(path, resolution=px, spp=emitter_spp, seed=s, timeout=14400,
                                                        integrator="emitter") for s in (0, 1)})
        row = {"material": name, "px": px, "spp": spp, "emitter_spp": emitter_spp,
               "psnr_path_seed_0_vs_1": _psnr(mi["path seed 1"], mi["path seed 0"], mask),
               "psnr_emitter_seed_0_vs_1": _psnr(mi["emitter seed 1"], mi["emitter seed 0"], mask),
               "psnr_emitter_vs_path": _psnr(mi["emitter seed 0"], mi["path seed 0"], mask), "quadratures": {}}
        brdf, images = load_brdf(path), dict(mi)
        for label, kw in DENSER.items():
            q = dataclasses.replace(_scene(px).quadrature, **kw)
            t0 = time.perf_counter()
            images[f"brdfkit {label}"], _ = render(brdf, dataclasses.replace(_scene(px), quadrature=q))
            row["quadratures"][label] = {"settings": kw, "seconds": round(time.perf_counter() - t0, 1),
                                         **{f"psnr_vs_path_seed_{s}": _psnr(images[f"brdfkit {label}"],
                                                                            mi[f"path seed {s}"], mask) for s in (0, 1)}}
            print(name, label, row["quadratures"][label], flush=True)
        row["region_means_green"] = {k: {r: round(float(np.nan_to_num(img)[m][:, 1].mean()), 5)
                                         for r, m in regions.items()} for k, img in images.items()}
        rows.append(row)
    return rows


def mitsuba(files, names, px, spp, seeds, control, folder, integrator="path"):
    from brdfkit.testing.mitsuba_measured import measured_render

    mask = inner_mask(px)
    rows = []
    todo = [(n, files[n]) for n in names]
    if control:
        from brdfkit.io.merl import read_merl
        from brdfkit.io.rgl_bsdf import write_bsdf

        written = os.path.join(folder, "control.bsdf")
        write_bsdf(written, read_merl(control))
        todo.append((f"control: {os.path.basename(control)} written by brdfkit", written))
    for k, (name, path) in enumerate(todo):  # the control last
        t0 = time.perf_counter()
        ref = measured_render(path, resolution=px, spp=spp, seed=0, timeout=14400, integrator=integrator)
        row = {"material": name, "px": px, "spp": spp, "integrator": integrator,
               "mitsuba_s": round(time.perf_counter() - t0, 1),
               "load": load_average(), "mitsuba_nonfinite_pixels": _nonfinite(ref, mask)}
        direct, images, seconds = _renders(path, px, ("least-squares", "grazing"))
        row.update(mean_mitsuba=_mean(ref, mask), mean_direct=_mean(direct, mask),
                   psnr_direct=_psnr(direct, ref, mask),
                   psnr_table_least_squares=_psnr(images["least-squares"], ref, mask),
                   psnr_table_grazing=_psnr(images["grazing"], ref, mask), direct_render_s=seconds)
        if seeds > 1 and k < len(names):
            other = measured_render(path, resolution=px, spp=spp, seed=1, timeout=14400, integrator=integrator)
            row["psnr_mitsuba_seed_0_vs_1"] = _psnr(other, ref, mask)
            row["mitsuba_nonfinite_pixels_seed_1"] = _nonfinite(other, mask)
            row["psnr_direct_vs_seed_1"] = _psnr(direct, other, mask)
        rows.append(row)
        print(row, flush=True)
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--load", action="store_true", help="read every file; its non-reciprocity")
    ap.add_argument("--tables", action="store_true", help="the loss of a MERL table, per rule, on every file")
    ap.add_argument("--mitsuba", nargs="*", default=None, metavar="NAME", help="Mitsuba's render of these files")
    ap.add_argument("--seeds", type=int, default=1, help="2: a second Mitsuba render of each name (noise floor)")
    ap.add_argument("--control", default=None, metavar="TABLE", help="a MERL table written as .bsdf: the control")
    ap.add_argument("--integrator", choices=("path", "emitter"), default="path",
                    help="Mitsuba's: the path tracer (light and BSDF sampling, MIS), or light sampling alone "
                         "(emitter: the BSDF evaluated, never sampled)")
    ap.add_argument("--sampling", nargs="*", default=None, metavar="NAME",
                    help="Mitsuba's BSDF samples of these files against its own pdf (rings about the mirror direction)")
    ap.add_argument("--quadrature", nargs="*", default=None, metavar="NAME",
                    help="brdfkit's render of these files at denser quadratures against Mitsuba's path tracer and "
                         "its render by light sampling alone")
    ap.add_argument("--emitter-spp", type=int, default=16384, help="samples a pixel of the light-sampling renders")
    ap.add_argument("--px", type=int, default=64)
    ap.add_argument("--spp", type=int, default=16384)
    args = record_options(ap).parse_args(argv)
    set_threads(args.threads)
    files = _files()
    missing = [n for n in (args.mitsuba or []) + (args.sampling or []) + (args.quadrature or []) if n not in files]
    if missing:
        sys.exit(f"rgl_real.py: error: not in $BRDFKIT_REAL_DATA/rgl: {', '.join(missing)}")
    argv_shown = [os.path.basename(a) if os.path.isabs(a) else a for a in sys.argv[1:]]
    record = {"command": " ".join(["BRDFKIT_REAL_DATA=DATA python benchmarks/studies/rgl_real.py", *argv_shown]),
              "files": sorted(files), "px": args.px, "supersample": SUPERSAMPLE,
              "mask": "pixels whose 16 sample points all lie on the sphere"}
    load0, t0 = load_average(), time.time()

    def save():  # after each job: a crash late in a long run keeps what was measured
        write_record(record, args.json, load0, t0)

    with tempfile.TemporaryDirectory(prefix="rgl-real-") as folder:
        if args.mitsuba is not None:
            record["mitsuba"] = {"rows": mitsuba(files, args.mitsuba, args.px, args.spp, args.seeds, args.control,
                                                 folder, args.integrator)}
            save()
        if args.sampling is not None:
            record["sampling"] = {"rows": sampling(files, args.sampling)}
            save()
        if args.quadrature is not None:
            record["quadrature"] = {"rows": quadrature(files, args.quadrature, args.px, args.spp, args.emitter_spp)}
            save()
        if args.load:
            record["load"] = {"rows": load(files)}
            save()
        if args.tables:
            record["tables"] = {"rows": tables(files, args.px)}
    save()


if __name__ == "__main__":
    main()
