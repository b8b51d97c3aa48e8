"""The page of ``brdfkit view``: one self-contained HTML file (no network; it works from
``file://``) that renders its materials live in WebGL2.

It holds, as JSON in the page: the reference scene's quadrature
(:func:`brdfkit.view.quadrature_data.scene_quadrature`) and environment, each material's
table as a float16 3D texture (:mod:`brdfkit.view.textures`) or, live, its numbers and
their basis and network (:mod:`brdfkit.view.live`), and the sample files' points; and
the package's assets (``brdfkit/view/assets``): the HTML, the JavaScript and the GLSL.
The page's size is about 8.75 MB a table written with ``compress=False`` (11.7 MB of
base64), less with gzip (which the browser's ``DecompressionStream`` undoes).

``#still=N&size=S`` (``N`` from 1, ``reference`` for 1) shows material ``N`` alone in
the reference scene at ``S`` pixels, without controls, and sets ``document.title`` to
``ready`` once drawn: the view a test or a script screenshots
(:mod:`brdfkit.view.browser`). ``&light=directional&dir=x,y,z``, ``&exposure=EV`` and
``&view=difference`` (Delta E 2000 against material 1, ``&scale=top``) set the rest.
"""

from __future__ import annotations

import functools
import json
import os
from importlib import resources

import numpy as np

from brdfkit.view.textures import blob, encode_planes, table_texture

__all__ = ["ASSETS", "SCRIPTS", "SHADERS", "asset", "page_data", "page_html", "write_page", "write_inputs"]

SCRIPTS = ("blobs.js", "gl.js", "live.js", "plots.js", "viewer.js")
"""The page's JavaScript, in order."""
SHADERS = {"eval": "brdfkit_eval.glsl", "quadrature": "quadrature.glsl", "render": "render.frag",
           "probe": "probe.frag", "display": "display.frag", "decode": "brdfkit_decode.glsl",
           "bake": "brdfkit_bake.frag"}
"""The page's GLSL sources by the name ``viewer.js`` knows them by."""
ASSETS = ("page.html", *SCRIPTS, *SHADERS.values())
LOBE = {"decades": 6.0, "sample_tolerance": 2.5}
"""The lobe plot's settings: ``brdfkit plot``'s decades, and how far (degrees) a sample
may lie from the plotted plane and ``theta_i`` to show as a point."""


def asset(name: str) -> str:
    """The text of one of the package's page assets (:data:`ASSETS`)."""
    return resources.files("brdfkit.view").joinpath("assets", name).read_text(encoding="utf-8")


@functools.lru_cache(maxsize=1)
def _quadrature() -> dict:
    """The reference scene's quadrature data, computed once per process (about a second)."""
    from brdfkit.view.quadrature_data import scene_quadrature

    return scene_quadrature()


def _scene_record(compress: bool) -> dict:
    from brdfkit.render.envmap import SUN_UV, uv_to_direction
    from brdfkit.render.scene import REFERENCE

    q = _quadrature()
    env = np.ascontiguousarray(q["env"], np.float32)
    return {"nodes": blob(np.ascontiguousarray(q["nodes"]).tobytes(), compress), "node_width": q["nodes"].shape[1],
            "counts": list(q["counts"]), "rects": [list(r) for r in q["rects"]], "constants": q["constants"],
            "env": blob(env.tobytes(), compress), "env_size": [env.shape[1], env.shape[0]],
            "view_half_width": q["view_half_width"], "resolution": REFERENCE.resolution,
            "sun": [float(x) for x in uv_to_direction(*SUN_UV)]}


def _live_records(inputs, compress: bool) -> tuple[dict | None, dict]:
    """``({"bases", "nets"}, {id(input): (basis index, net index)})`` of the live inputs:
    one record per basis (with the most components any of its materials uses) and per
    network."""
    from brdfkit.view.live import basis_data, net_data

    live = [i for i in inputs if i.kind == "live"]
    if not live:
        return None, {}
    bases, nets, where = {}, {}, {}
    for i in live:
        b = i.live["basis"]
        entry = bases.setdefault(id(b), [b, 0])
        entry[1] = max(entry[1], i.live["k"])
        if i.live["net"] is not None:
            nets.setdefault(id(i.live["net"][1]), i.live["net"])
    order_b, order_n = list(bases), list(nets)
    for i in live:
        net = i.live["net"]
        where[id(i)] = (order_b.index(id(i.live["basis"])), None if net is None else order_n.index(id(net[1])))
    return ({"bases": [basis_data(b, k, compress) for b, k in bases.values()],
             "nets": [net_data(cfg, state, compress) for cfg, state in nets.values()]}, where)


def page_data(inputs, compress: bool = True) -> dict:
    """The page's data (JSON-ready) for inputs read by :func:`brdfkit.view.inputs.read_inputs`."""
    from importlib.metadata import version

    from brdfkit.view.inputs import sample_rows

    live, where = _live_records(inputs, compress)
    materials, samples = [], []
    for i in inputs:
        if i.kind == "samples":
            rows = sample_rows(i.samples)
            samples.append({"label": i.label, "count": int(rows.shape[0]), "points": blob(rows.tobytes(), compress)})
        elif i.kind == "live":
            b, n = where[id(i)]
            materials.append({"label": i.label, "kind": "live", "embedding": i.live["kind"], "k": i.live["k"],
                              "coefficients": i.live["coefficients"], "gain": i.live["gain"], "basis": b, "net": n})
        else:
            half, scale = table_texture(i.table, i.path)
            materials.append({"label": i.label, "kind": "table", "scale": 1.0 / scale,
                              "table": blob(encode_planes(half), compress, planes=True)})
    return {"version": version("brdfkit"), "scene": _scene_record(compress), "materials": materials, "samples": samples,
            "live": live, "lobe": LOBE}


def _json(value) -> str:
    """JSON safe inside a ``<script>`` element (no ``</`` in it)."""
    return json.dumps(value, separators=(",", ":"), sort_keys=True).replace("</", "<\\/")


def page_html(data: dict, shaders: dict | None = None) -> str:
    """The page's HTML for its :func:`page_data`; ``shaders``: GLSL sources by name to use
    instead of the package's (``brdfkit export`` writes its page with its own files)."""
    from html import escape

    sources = {name: asset(f) for name, f in SHADERS.items()}
    sources.update(shaders or {})
    labels = ", ".join(m["label"] for m in data["materials"])
    script = "\n".join(asset(f) for f in SCRIPTS)
    if "</script" in script.lower():
        raise ValueError("a page script holds '</script'")
    return (asset("page.html").replace("{{VERSION}}", escape(data["version"]))
            .replace("{{TITLE}}", escape(f"brdfkit view: {labels}"))
            .replace("{{SHADERS}}", _json(sources)).replace("{{SCRIPT}}", script)
            .replace("{{DATA}}", _json(data)))


def write_page(paths, output, *, model_path=None, live: bool = False, compress: bool = True,
               progress=None, shaders: dict | None = None) -> dict:
    """Read ``paths`` and write their page to ``output`` (atomically, never over an input).

    Parameters
    ----------
    paths
        BRDF files and sample files (:func:`brdfkit.view.inputs.read_inputs`).
    output
        The ``.html`` file.
    model_path
        The decoder of ``.emb`` inputs (default: the built-in part each names).
    live
        Basis and residual embeddings decoded by the page's shader from their numbers.
    compress
        gzip the page's data (the browser's ``DecompressionStream`` undoes it); ``False``
        for a browser without it (a bigger page).
    progress
        Optional ``progress(message)``.
    shaders
        GLSL sources by name instead of the package's (:func:`page_html`).

    Returns
    -------
    dict
        ``{"output", "bytes", "materials": [(label, kind)], "samples": [label]}``.
    """
    from brdfkit.atomic import refuse_overwrite_of_inputs
    from brdfkit.errors import InputError
    from brdfkit.view.inputs import read_inputs

    output = os.fspath(output)
    if not output.lower().endswith((".html", ".htm")):
        raise InputError(f"{output}: the page must be an .html file")
    refuse_overwrite_of_inputs(output, [*map(os.fspath, paths), model_path])
    return write_inputs(read_inputs(paths, model_path, live=live, progress=progress), output, compress=compress,
                        shaders=shaders)


def write_inputs(inputs, output, *, compress: bool = True, shaders: dict | None = None) -> dict:
    """Write the page of inputs already read (:class:`brdfkit.view.inputs.PageInput`: a
    table in memory needs no file) to ``output``, atomically; returns what
    :func:`write_page` returns."""
    from brdfkit.atomic import atomic_open

    data = page_html(page_data(inputs, compress), shaders).encode("utf-8")
    with atomic_open(output, "wb") as f:
        f.write(data)
    return {"output": os.fspath(output), "bytes": len(data),
            "materials": [(i.label, i.kind) for i in inputs if i.kind != "samples"],
            "samples": [i.label for i in inputs if i.kind == "samples"]}
