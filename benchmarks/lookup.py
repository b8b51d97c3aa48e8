#!/usr/bin/env python3
"""Per-pair cost of a table render's BRDF evaluations, against the same code at another git
revision, in one process: the trilinear lookup (:class:`brdfkit.geometry.trilinear.TrilinearTable`)
and the whole :meth:`brdfkit.render.renderable.TableBRDF.eval_dirs` (directions -> Rusinkiewicz
angles -> lookup; issue 14 item 1, ``docs/notes/performance.md``).

The direction pairs are those the quadrature evaluates in the reference scene at
``--resolution``, in its blocks and column-major as it hands them over (every
``--stride``-th block, at most ``--max-pairs``), the table the synthetic ``stiff-white``
(``--brdf``: a MERL file). The other revision's ``brdfkit/geometry/grid.py`` (and
``brdfkit/geometry/trilinear.py`` where it has one; the lookup moved there from ``geometry.py``) is
loaded from git as a package of its own, and its ``eval_dirs`` is ``TableBRDF.eval_dirs``
as it was up to this lookup's change
(``half_diff_from_io``, the lookup, ``torch.where`` over the horizon). Both sides are timed
in interleaved rounds, best of ``--repeat`` (process CPU time; another job on the machine
slows both alike), and their results compared bit for bit (exit status 1 if they differ).

Example (the figures of docs/notes/performance.md, "Table lookup")::

    python benchmarks/lookup.py --against c198071 --resolution 256 --threads 1 --repeat 7
"""

from __future__ import annotations

import importlib
import os
import subprocess
import sys
import tempfile
import time
import types

import common


def main(argv=None) -> int:
    ap = common.timing_parser(__doc__, repeat=5)
    ap.add_argument("--against", required=True, help="git revision of the code to compare with")
    ap.add_argument("--brdf", default=None, help="a MERL .binary instead of the synthetic stiff-white table")
    ap.add_argument("--resolution", type=int, default=256)
    ap.add_argument("--stride", type=int, default=4, help="keep every STRIDE-th block of pairs")
    ap.add_argument("--max-pairs", type=int, default=3_000_000)
    args = ap.parse_args(argv)
    common.set_threads(args.threads)
    import torch

    from brdfkit import geometry
    from brdfkit.materials import synthetic
    from brdfkit.geometry import trilinear
    from brdfkit.io.merl import read_merl
    from brdfkit.render.renderable import TableBRDF

    table = read_merl(args.brdf) if args.brdf else synthetic.table(synthetic.STIFF[2])
    wi, wo = _render_pairs(args.resolution, args.stride, args.max_pairs)
    n = sum(w.shape[0] for w in wi)
    with tempfile.TemporaryDirectory() as tmp:
        old = _revision_lookup(args.against, tmp)
        t32 = torch.as_tensor(table, dtype=torch.float32)
        luts = {"old": old.TrilinearTable(t32), "new": trilinear.TrilinearTable(t32)}
        new_brdf = TableBRDF(table, device="cpu")
        new_brdf.PREPARE_AFTER = 0
        angles = [geometry.half_diff_from_io(a, b) for a, b in zip(wi, wo)]

        def lookup(mod, lut):
            return lambda: [mod.lookup_trilinear(lut, th, td, pd, fill=0.0) for th, _, td, pd in angles]

        def old_eval():
            out = []
            for a, b in zip(wi, wo):
                th, _, td, pd = old.half_diff_from_io(a, b)
                rho = old.lookup_trilinear(luts["old"], th, td, pd, fill=0.0)
                above = (a[:, 2] > 0) & (b[:, 2] > 0)
                out.append(torch.where(above[:, None], rho, torch.zeros_like(rho)))
            return out

        def new_eval():
            return [new_brdf.eval_dirs(a, b) for a, b in zip(wi, wo)]

        fns = {"lookup_old": lookup(old, luts["old"]), "lookup_new": lookup(trilinear, luts["new"]),
               "eval_dirs_old": old_eval, "eval_dirs_new": new_eval}
        same = all(torch.equal(x, y) for k in ("lookup", "eval_dirs")
                   for x, y in zip(fns[k + "_old"](), fns[k + "_new"]()))
        best = {k: float("inf") for k in fns}
        for _ in range(args.repeat):
            for k, fn in fns.items():
                t = time.process_time()
                fn()
                best[k] = min(best[k], time.process_time() - t)
    ns = {k: 1e9 * v / n for k, v in best.items()}
    rows = [[what, f"{ns[what + '_old']:.1f}", f"{ns[what + '_new']:.1f}",
             f"{ns[what + '_old'] / ns[what + '_new']:.2f}x", f"{ns[what + '_new'] * 11_791_397 / 1e9:.2f}"]
            for what in ("lookup", "eval_dirs")]
    data = {"machine": common.machine(), "against": args.against, "resolution": args.resolution, "pairs": n,
            "bit_identical": same, "ns_per_pair": ns, "torch_threads": args.threads}
    common.report("lookup", f"Table BRDF evaluations of a {args.resolution} px render ({n:,} pairs), "
                            f"{args.threads} thread(s), best of {args.repeat}; bit-identical: {same}",
                  ["what", f"ns / pair at {args.against}", "ns / pair now", "speed-up",
                   "now, s for 11,791,397 pairs (256 px)"], rows, data, args.json)
    return 0 if same else 1


def _render_pairs(resolution, stride, max_pairs):
    """The direction pairs the quadrature hands a BRDF in the reference scene, block by
    block as it hands them (column-major ``(M, 3)``): every ``stride``-th block, up to
    ``max_pairs``."""
    import torch

    from brdfkit.render import quadrature
    from brdfkit.render.scene import Scene

    class Recorder:
        device = torch.device("cpu")
        name = "recorder"

        def __init__(self):
            self.wi, self.wo, self.n, self.blocks = [], [], 0, 0

        def eval_dirs(self, wi, wo):
            if self.blocks % stride == 0 and self.n < max_pairs:
                self.wi.append(wi.clone())
                self.wo.append(wo.clone())
                self.n += wi.shape[0]
            self.blocks += 1
            return torch.zeros(wi.shape[0], 3)

    rec = Recorder()
    quadrature.render(rec, Scene(resolution=resolution))
    quadrature.clear_cache()
    return rec.wi, rec.wo


def _revision_lookup(rev: str, folder: str):
    """The lookup of git revision ``rev``: its ``lookup_trilinear``, ``TrilinearTable`` and
    ``half_diff_from_io``, from its ``brdfkit/geometry/grid.py`` and ``brdfkit/geometry/trilinear.py``
    imported as the package ``brdfkit_<rev>`` from files written into ``folder`` (each name
    from ``trilinear`` where the revision has it there, else from ``geometry``)."""
    package = "brdfkit_" + "".join(c if c.isalnum() else "_" for c in rev)
    os.makedirs(os.path.join(folder, package))
    open(os.path.join(folder, package, "__init__.py"), "w").close()
    for name in ("geometry.py", "trilinear.py"):
        text = subprocess.run(["git", "show", f"{rev}:brdfkit/{name}"], cwd=common.REPO, capture_output=True,
                              text=True)
        if text.returncode == 0:
            with open(os.path.join(folder, package, name), "w") as f:
                f.write(text.stdout)
        elif name == "geometry.py":
            raise SystemExit(f"lookup.py: git show {rev}:brdfkit/geometry/grid.py failed: {text.stderr.strip()}")
    sys.path.insert(0, folder)
    modules = [importlib.import_module(package + ".geometry")]
    if os.path.exists(os.path.join(folder, package, "trilinear.py")):
        modules.insert(0, importlib.import_module(package + ".trilinear"))
    return types.SimpleNamespace(**{name: next(getattr(m, name) for m in modules if hasattr(m, name))
                                    for name in ("lookup_trilinear", "TrilinearTable", "half_diff_from_io")})


if __name__ == "__main__":
    sys.exit(main())
