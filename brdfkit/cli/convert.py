"""``brdfkit convert``: BRDF files between MERL ``.binary``, RGL ``.bsdf`` and ``.emb``."""

from __future__ import annotations

import click

from brdfkit.cli.common import model_option

# Defaults of brdfkit.io.rgl.fit.FitSettings, repeated here so that --help imports nothing
# (tests/test_rgl_bsdf.py checks that they agree).
RESOLUTION, THETA_I = 64, 48
RULES = ("least-squares", "mean", "grazing", "steep")  # brdfkit.io.rgl_bsdf.RULES, the default first


def _given(name: str) -> bool:
    from click.core import ParameterSource

    return click.get_current_context().get_parameter_source(name) is not ParameterSource.DEFAULT


@click.command("convert")
@click.argument("source", type=click.Path(dir_okay=False), metavar="IN")
@model_option
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False), metavar="OUT",
              help="Output: a MERL table (.binary) or an RGL file (.bsdf) for Mitsuba 3 / pbrt-v4.")
@click.option("--resolution", type=click.IntRange(min=2, max=1024), default=RESOLUTION, show_default=True,
              help=".bsdf: N, the N x N sample-space grid per incident elevation (size grows as N^2; "
                   "docs/rgl-bsdf.md).")
@click.option("--theta-i", "theta_i", type=click.IntRange(min=2, max=1024), default=THETA_I, show_default=True,
              help=".bsdf: number of incident elevations, 0 to 89 degrees.")
@click.option("--spectral", is_flag=True,
              help=".bsdf: write spectra (pbrt-v4, Mitsuba's spectral variants; Mallett and Yuksel 2019) "
                   "instead of RGB (Mitsuba's RGB variants).")
@click.option("--description", default=None, help=".bsdf: the file's description (default: its source).")
@click.option("--reciprocity", type=click.Choice(RULES), default=RULES[0], show_default=True,
              help="A .bsdf input: how its two conditionings (on either direction of a pair; a "
                   "measurement is not reciprocal) become the one value a table holds per reciprocal pair: "
                   "their mean weighted by the squared cosine each was divided by (nearest to the renders in "
                   "the mean square), their plain mean, or the one conditioned on the more grazing or the "
                   "steeper direction (docs/rgl-bsdf.md measures them).")
def command(source, model_path, output, resolution, theta_i, spectral, description, reciprocity):
    """Convert the BRDF file IN into OUT: a MERL .binary table or an RGL .bsdf file.

    IN is a MERL .binary table, an RGL .bsdf file (isotropic, RGB: evaluated at the MERL
    grid's directions, made reciprocal by --reciprocity; its non-reciprocity is printed)
    or an embedding .emb (decoded with -m MODEL, default the built-in it names). A
    .bsdf is written in the adaptive parameterization of Dupuy and Jakob 2018, as
    Mitsuba 3's `measured` BSDF and pbrt-v4's `measured` material read it
    (docs/rgl-bsdf.md).
    """
    import os

    from brdfkit.files.brdf_file import OUTPUT_TYPES, EmbeddingDecoders, convert
    from brdfkit.console import console
    from brdfkit.errors import InputError

    bsdf_options = [f"--{n.replace('_', '-')}" for n in ("resolution", "theta_i", "spectral", "description")
                    if _given(n)]
    settings = None
    if OUTPUT_TYPES.get(os.path.splitext(output)[1].lower()) == "merl" and bsdf_options:
        raise InputError(f"{output}: options of an RGL .bsdf output ({', '.join(bsdf_options)}) given for a "
                         f"MERL table")
    if OUTPUT_TYPES.get(os.path.splitext(output)[1].lower()) == "rgl":
        from brdfkit.io.rgl.fit import FitSettings

        settings = FitSettings(resolution=resolution, theta_i=theta_i)
    report = convert(source, output, models=EmbeddingDecoders(model_path), settings=settings, spectral=spectral,
                     description=description, reciprocity=reciprocity)
    if "non_reciprocity" in report:
        console().print(f"{source}: non-reciprocity {report['non_reciprocity']:.4f} (log RMS between the file "
                        f"conditioned on either direction, over the MERL grid); made reciprocal by the "
                        f"{reciprocity} rule (--reciprocity)", soft_wrap=True)
    what = "MERL table" if report["output_type"] == "merl" else \
        f"RGL .bsdf, {'spectral' if spectral else 'RGB'}, {resolution} x {resolution} x {theta_i} theta_i"
    console().print(f"wrote {output} ({what}, {report['bytes'] / 1e6:.2f} MB) from {source}: read "
                    f"{report['read_s']:.1f} s, written {report['write_s']:.1f} s", soft_wrap=True)
