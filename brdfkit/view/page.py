"""The page of ``brdfkit view``: one self-contained HTML file (no network; it works from
``file://``) that renders its materials live in WebGL2.

It holds, as JSON in the page: the reference scene's quadrature
(:func:`brdfkit.view.quadrature_data.scene_quadrature`) and environment, each material's
table as a float16 3D texture (:mod:`brdfkit.view.textures`) or, live, its basis and the
defines and uniforms its decoder takes (:mod:`brdfkit.view.live`), the sample files'
points, and every constant the page's scripts and shaders use that brdfkit defines (the
display encoding, the colour maps, the lobe plot's samples); and the package's assets
(``brdfkit/view/assets``): the HTML, the JavaScript and the GLSL, each fragment shader
assembled from the files it requires (:func:`glsl_program`).
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
import re
from importlib import resources

import numpy as np

from brdfkit.view.textures import blob, encode_planes, table_texture

__all__ = ["ASSETS", "SCRIPTS", "SHADERS", "PROGRAMS", "GLSL_HEADER", "LOBE", "asset", "glsl_files", "glsl_program",
           "page_data", "page_html", "write_page", "write_inputs"]

LOBE = {"decades": 6.0, "sample_tolerance": 2.5}
"""The lobe plot's settings: ``brdfkit plot``'s decades, and how far (degrees) a sample
may lie from the plotted plane and ``theta_i`` to show as a point."""

SCRIPTS = ("blobs.js", "gl.js", "live.js", "plots.js", "viewer.js")
"""The page's JavaScript, in order."""
PROGRAMS = {"render": "render.frag", "probe": "probe.frag", "display": "display.frag", "bake": "brdfkit_bake.frag"}
"""The page's fragment shaders by the name ``viewer.js`` knows them by; each with the GLSL
files it requires (:func:`glsl_program`)."""
SHADERS = ("brdfkit_grid.glsl", "brdfkit_eval.glsl", "brdfkit_decode.glsl", "brdfkit_bake.frag", "brdfkit_frame.glsl",
           "quadrature.glsl", "render.frag", "probe.frag", "display.frag")
"""The package's GLSL files."""
GLSL_HEADER = ("#version 300 es\nprecision highp float;\nprecision highp int;\nprecision highp sampler2D;\n"
               "precision highp sampler3D;\n")
"""What every fragment shader of the page starts with, before its defines (GLSL ES 3.00:
WebGL2)."""
ASSETS = ("page.html", *SCRIPTS, *SHADERS)
_REQUIRE = re.compile(r"^#pragma brdfkit require\(([\w.]+)\)[ \t]*$", re.M)


def asset(name: str) -> str:
    """The text of one of the package's page assets (:data:`ASSETS`)."""
    return resources.files("brdfkit.view").joinpath("assets", name).read_text(encoding="utf-8")


def glsl_files(name: str, sources: dict | None = None) -> list[str]:
    """The GLSL files a program's file ``name`` needs, in the order they go, each once, and
    ``name`` last: a file says what it needs itself, with a line ``#pragma brdfkit
    require(FILE)`` (GLSL ignores a pragma it does not know). ``sources``: text by file
    name instead of the package's.

    Examples
    --------
    >>> glsl_files("brdfkit_bake.frag")
    ['brdfkit_grid.glsl', 'brdfkit_decode.glsl', 'brdfkit_bake.frag']
    """
    order: list[str] = []

    def visit(f, path):
        if f in path:
            raise ValueError(f"GLSL files require each other: {' -> '.join(path + (f,))}")
        if f not in order:
            for needed in _REQUIRE.findall((sources or {}).get(f) or asset(f)):
                visit(needed, path + (f,))
            order.append(f)

    visit(name, ())
    return order


def glsl_program(name: str, sources: dict | None = None) -> str:
    """The source of the fragment shader ``name`` (a file of :data:`PROGRAMS`): the files it
    needs (:func:`glsl_files`) joined, without their ``require`` lines; what goes after
    :data:`GLSL_HEADER` and the defines."""
    text = [(sources or {}).get(f) or asset(f) for f in glsl_files(name, sources)]
    return "\n".join(_REQUIRE.sub("", t) for t in text)


@functools.lru_cache(maxsize=1)
def _quadrature() -> dict:
    """The reference scene's quadrature data, computed once per process (about a second)."""
    from brdfkit.view.quadrature_data import scene_quadrature

    return scene_quadrature()


def _scene_record(compress: bool) -> dict:
    from brdfkit.render.envmap import SUN_UV, uv_to_direction
    from brdfkit.render.scene import REFERENCE
    from brdfkit.view.quadrature_data import MAX_RECTS

    q = _quadrature()
    env = np.ascontiguousarray(q["env"], np.float32)
    return {"nodes": blob(np.ascontiguousarray(q["nodes"]).tobytes(), compress), "node_width": q["nodes"].shape[1],
            "uniforms": q["uniforms"], "defines": {"Q_MAX_RECTS": MAX_RECTS},
            "env": blob(env.tobytes(), compress), "env_size": [env.shape[1], env.shape[0]],
            "resolution": REFERENCE.resolution, "sun": [float(x) for x in uv_to_direction(*SUN_UV)]}


def _display_record() -> dict:
    """What ``display.frag`` and ``plots.js`` take from brdfkit: the display encoding's
    exposure (:mod:`brdfkit.render.display`), colour-science's sRGB -> XYZ matrix and D65
    white (as :func:`brdfkit.evaluation.metrics.delta_e_2000_map` converts), matplotlib's
    inferno (``brdfkit compare``'s Delta E colours: 256 entries, 8-bit) and the line
    colours of ``brdfkit plot``."""
    import colour
    import matplotlib

    from brdfkit.figures.brdf_plot import COLOURS
    from brdfkit.render.display import EXPOSURE

    srgb = colour.RGB_COLOURSPACES["sRGB"]
    white = colour.xy_to_XYZ(colour.CCS_ILLUMINANTS["CIE 1931 2 Degree Standard Observer"]["D65"])
    lut = matplotlib.colormaps["inferno"](np.arange(256), bytes=True)
    return {"exposure": float(EXPOSURE), "inferno": lut.reshape(-1).tolist(), "lines": list(COLOURS),
            "uniforms": {"u_rgb_to_xyz": np.asarray(srgb.matrix_RGB_to_XYZ, np.float64).T.reshape(-1).tolist(),
                         "u_white": [float(x) for x in white]}}


def _lobe_record() -> dict:
    """The lobe plot's settings: ``brdfkit plot``'s ``theta_o`` samples (degrees) and
    luminance weights, its decades, and how far (degrees) a sample may lie from the plotted
    plane and ``theta_i`` to show as a point."""
    from brdfkit.figures.brdf_plot import LUMINANCE, THETA_O_DEG

    return {**LOBE, "theta_o": [float(x) for x in THETA_O_DEG], "luminance": [float(x) for x in LUMINANCE],
            "uniforms": {"u_theta_o": [float(THETA_O_DEG[0]), float(THETA_O_DEG[1] - THETA_O_DEG[0])]}}


def _live_records(inputs, compress: bool) -> tuple[list | None, dict]:
    """``(bases, {id(input): basis index})`` of the live inputs: one record per basis (with
    the most components any of its materials uses)."""
    from brdfkit.view.live import basis_data

    live = [i for i in inputs if i.kind == "live"]
    if not live:
        return None, {}
    bases = {}
    for i in live:
        b = i.live["basis"]
        entry = bases.setdefault(id(b), [b, 0])
        entry[1] = max(entry[1], i.live["k"])
    order = list(bases)
    return ([basis_data(b, k, compress) for b, k in bases.values()],
            {id(i): order.index(id(i.live["basis"])) for i in live})


def page_data(inputs, compress: bool = True) -> dict:
    """The page's data (JSON-ready) for inputs read by :func:`brdfkit.view.inputs.read_inputs`."""
    from importlib.metadata import version

    from brdfkit.view.inputs import sample_rows
    from brdfkit.view.live import material_uniforms

    bases, where = _live_records(inputs, compress)
    materials, samples = [], []
    for i in inputs:
        if i.kind == "samples":
            rows = sample_rows(i.samples)
            samples.append({"label": i.label, "count": int(rows.shape[0]), "points": blob(rows.tobytes(), compress)})
        elif i.kind == "live":
            materials.append({"label": i.label, "kind": "live", "embedding": i.live["kind"], "k": i.live["k"],
                              "basis": where[id(i)], **material_uniforms(i.live)})
        else:
            half, scale = table_texture(i.table, i.path)
            materials.append({"label": i.label, "kind": "table", "scale": 1.0 / scale,
                              "table": blob(encode_planes(half), compress, planes=True)})
    return {"version": version("brdfkit"), "scene": _scene_record(compress), "materials": materials, "samples": samples,
            "bases": bases, "display": _display_record(), "lobe": _lobe_record()}


def _json(value) -> str:
    """JSON safe inside a ``<script>`` element (no ``</`` in it)."""
    return json.dumps(value, separators=(",", ":"), sort_keys=True).replace("</", "<\\/")


def page_html(data: dict, shaders: dict | None = None) -> str:
    """The page's HTML for its :func:`page_data`; ``shaders``: GLSL text by file name to use
    instead of the package's (``brdfkit export`` writes its page with its own files)."""
    from html import escape

    programs = {name: glsl_program(f, shaders) for name, f in PROGRAMS.items()}
    labels = ", ".join(m["label"] for m in data["materials"])
    script = "\n".join(asset(f) for f in SCRIPTS)
    if "</script" in script.lower():
        raise ValueError("a page script holds '</script'")
    return (asset("page.html").replace("{{VERSION}}", escape(data["version"]))
            .replace("{{TITLE}}", escape(f"brdfkit view: {labels}"))
            .replace("{{SHADERS}}", _json({"header": GLSL_HEADER, "programs": programs})).replace("{{SCRIPT}}", script)
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
        GLSL text by file name instead of the package's (:func:`page_html`).

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
