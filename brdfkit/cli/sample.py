"""``brdfkit sample``: measure a dense MERL table, at random or at given directions."""

from __future__ import annotations

import click

from brdfkit.atomic import refuse_overwrite_of_inputs
from brdfkit.console import console
from brdfkit.errors import InputError


def _table(path: str):
    """The dense table of a BRDF file through the one loader (:func:`brdfkit.files.brdf_file.read_table`:
    ``.binary``, ``.bsdf``, ``.emb``); a file of any other name is read as a MERL table,
    whose reader says what it is not."""
    import os

    from brdfkit.files.brdf_file import FILE_TYPES, read_table
    from brdfkit.io.merl import read_merl

    return read_table(path) if os.path.splitext(path)[1].lower() in FILE_TYPES else read_merl(path)


def _given(name: str) -> bool:
    from click.core import ParameterSource

    return click.get_current_context().get_parameter_source(name) is not ParameterSource.DEFAULT


@click.command("sample")
@click.argument("brdf", type=click.Path(dir_okay=True))
@click.option("-n", "--count", "n", type=click.IntRange(min=1), default=None,
              help="Number of random samples (or give --at).")
@click.option("--at", "at", type=click.Path(dir_okay=False), default=None,
              help="Directions CSV (e.g. from `brdfkit plan`): measure the table at these directions "
                   "instead of drawing at random (docs/formats.md).")
@click.option("--seed", type=int, default=0, show_default=True, help="Random seed (with -n).")
@click.option("--distribution", type=click.Choice(["angles", "cells"]), default="angles", show_default=True,
              help="With -n: uniform over Rusinkiewicz angles, or over measured cells.")
@click.option("--given", "given", type=click.Path(dir_okay=False), default=None, metavar="SAMPLES",
              help="With --at: the samples measured so far (any sample file), written first: the output holds them "
                   "and this round's (measuring in rounds, docs/planning.md).")
@click.option("-o", "--output", type=click.Path(dir_okay=False), required=True, help="Output CSV.")
def command(brdf, n, at, seed, distribution, given, output):
    """Measure the BRDF (a MERL .binary table, an RGL .bsdf file at the MERL grid, or an
    .emb decoded by its built-in model) into a CSV sample set: N random measurements (-n),
    or one at each direction of a directions CSV (--at).

    With -n only measured cells are drawn, each with its cell's angles and value. With
    --at each direction gets the table's trilinear interpolation there (a cell's own
    value at its own angles); --given SO_FAR writes those samples first, then these (a
    round of `brdfkit plan --given`). The CSV has columns theta_h,theta_d,phi_d,r,g,b
    (radians, BRDF in 1/sr); see docs/formats.md.
    """
    import os

    from brdfkit.io.samples import write_samples
    from brdfkit.acquisition.sampling import draw_samples, join_samples, measure_samples

    if (n is None) == (at is None):
        raise InputError("give either -n N (random samples) or --at DIRECTIONS.csv, not " +
                         ("both" if n is not None else "neither"))
    if at is not None:
        extra = [f"--{o}" for o in ("seed", "distribution") if _given(o)]
        if extra:
            raise InputError(f"{' and '.join(extra)} apply to random samples (-n), not to --at")
    elif given is not None:
        raise InputError("--given applies to --at (a round measured at planned directions), not to -n")
    refuse_overwrite_of_inputs(output, [brdf] + [p for p in (at, given) if p])
    name = os.path.basename(brdf)
    if at is not None:
        from brdfkit.io.directions import read_directions
        from brdfkit.io.sample_files import read_sample_file

        directions = read_directions(at)  # before the table: a bad file is refused at once
        so_far = read_sample_file(given) if given else None
        samples = measure_samples(_table(brdf), directions, source=name)
        count, how = len(samples), f" at the directions of {at}"
        if so_far is not None:
            how += f" after the {len(so_far)} samples of {given}"
            samples = join_samples(so_far, samples, source=name)
    else:
        samples = draw_samples(_table(brdf), n, seed, distribution, source=name)
        count, how = len(samples), ""
    write_samples(output, samples)
    console().print(f"wrote {count} samples of {brdf}{how} to {output}")
