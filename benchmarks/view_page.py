"""The page of ``brdfkit view`` measured in headless Chromium: its screenshots against
``brdfkit render``'s PNGs, its sizes, and how long a still takes (the figures of
``docs/view.md``).

Three materials brdfkit ships (teflon, blue-metallic-paint, chrome-steel: diffuse, glossy,
metallic), each embedded in ``merl80-l40``'s basis by the least-squares projection (13
components), the metallic one as a residual embedding with its correction. For each:

* ``table``: the page in table mode (the embedding decoded by brdfkit) at
  ``#still=N&size=PX`` against ``brdfkit render EMB --png`` at ``PX`` (PSNR of the 8-bit
  images, peak 255, the whole image);
* ``live``: the page with ``--live`` (the shader decodes the embedding) against table mode;
* the page's size per table, gzip'd and not, and the seconds each still took to draw.

``python benchmarks/view_page.py --px 256 --json benchmarks/results/DATE-view-page.json``
(needs Chromium, ``apt-get install chromium``, and the built-in models). Seconds are wall
time on whatever machine runs it, with its load average beside them.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import load_average, record_options, set_threads, write_record  # noqa: E402

MATERIALS = (("teflon", "diffuse", "basis"), ("blue-metallic-paint", "glossy", "basis"),
             ("chrome-steel", "metallic", "residual"))


def _psnr8(a, b) -> float:
    import numpy as np

    mse = float(np.mean((np.asarray(a, np.float64) - np.asarray(b, np.float64)) ** 2))
    return math.inf if mse == 0 else round(10 * math.log10(255.0 ** 2 / mse), 2)


def _embedding(table, kind: str, k: int = 13):
    """The least-squares projection of ``table`` onto ``merl80-l40``'s basis, as a
    ``kind`` embedding (a residual's with its correction)."""
    import numpy as np

    from brdfkit.embeddings.decoders import load_decoder
    from brdfkit.io.embedding import Embedding
    from brdfkit.models.builtin import resolve_part

    dec = load_decoder(kind, resolve_part("merl80-l40", kind))
    basis = dec.obj.basis if kind == "residual" else dec.obj
    c = basis.leading(k).project(table).astype(np.float32).reshape(-1)
    if kind == "basis":
        return Embedding(c, "basis", dec.digest, "view_page.py")
    return Embedding(c, "residual", dec.digest, "view_page.py",
                     parts={"basis": dec.obj.basis_digest, "residual": dec.digest}, options={"correction": 1.0})


def measure(folder: str, px: int) -> dict:
    import numpy as np

    from brdfkit.files.brdf_file import load_brdf
    from brdfkit.io.embedding import write_embedding
    from brdfkit.materials.nbrdf_networks import material_table
    from brdfkit.render.display import display_encode
    from brdfkit.render.quadrature import render_many
    from brdfkit.render.scene import reference_scene
    from brdfkit.view.browser import Browser, screenshot
    from brdfkit.view.page import write_page

    embs = []
    for name, _, kind in MATERIALS:
        embs.append(os.path.join(folder, f"{name}.emb"))
        write_embedding(embs[-1], _embedding(material_table(name), kind))
    t0 = time.perf_counter()
    renders = [np.round(display_encode(img) * 255).astype(np.uint8)
               for img, _ in render_many([load_brdf(p) for p in embs], reference_scene(px))]
    render_s = time.perf_counter() - t0
    pages = {"table": write_page(embs, os.path.join(folder, "table.html")),
             "raw": write_page(embs, os.path.join(folder, "raw.html"), compress=False),
             "live": write_page(embs, os.path.join(folder, "live.html"), live=True)}
    rows = []
    with Browser(px) as b:
        for i, (name, what, kind) in enumerate(MATERIALS):
            row = {"material": name, "stands_for": what, "embedding": kind}
            shots = {}
            for mode in ("table", "live"):
                t = time.perf_counter()
                shots[mode] = screenshot(pages[mode]["output"], f"still={i + 1}", px, browser=b, timeout=1800)
                row[f"{mode}_still_s"] = round(time.perf_counter() - t, 1)
            row["psnr_table_vs_render"] = _psnr8(shots["table"], renders[i])
            row["psnr_live_vs_table"] = _psnr8(shots["live"], shots["table"])
            rows.append(row)
            print(row, flush=True)
    return {"px": px, "rows": rows, "python_renders_s": round(render_s, 1),
            "page_bytes": {k: v["bytes"] for k, v in pages.items()}, "tables_in_page": len(MATERIALS)}


def main(argv=None):
    ap = record_options(argparse.ArgumentParser(description=__doc__.split("\n\n")[0]))
    ap.add_argument("--px", type=int, default=256, help="render and screenshot size, pixels")
    args = ap.parse_args(argv)
    set_threads(args.threads)
    load0, t0 = load_average(), time.time()
    with tempfile.TemporaryDirectory(prefix="view-page-") as folder:
        record = {"command": "python benchmarks/view_page.py " + " ".join(sys.argv[1:]), **measure(folder, args.px)}
    write_record(record, args.json, load0, t0)


if __name__ == "__main__":
    main()
