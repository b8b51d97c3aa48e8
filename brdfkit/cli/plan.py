"""``brdfkit plan``: choose N measurement directions for a reconstruction."""

from __future__ import annotations

import click

_DESIGNS = ("nielsen", "render", "uniform")  # brdfkit.acquisition.designs.DESIGNS, not imported here: --help stays light


def _given(name: str) -> bool:
    from click.core import ParameterSource

    return click.get_current_context().get_parameter_source(name) is not ParameterSource.DEFAULT


@click.command("plan")
@click.option("-n", "--count", "n", type=click.IntRange(min=1), required=True, help="Number of directions.")
@click.option("-m", "--model", "model", type=click.Path(dir_okay=False), default=None, metavar="NAME|FILE",
              help="The PCA basis to plan for: a built-in with a learnt prior (`brdfkit models`; its basis), a "
                   "learnt-prior file or a basis file from `brdfkit fit --method basis`; default: the default "
                   "built-in's (none for --design uniform).")
@click.option("--design", type=click.Choice(_DESIGNS), default="render", show_default=True,
              help="nielsen: minimum condition number of the basis rows (Nielsen et al. 2015); render: minimum "
                   "expected render error of the fit under the basis's prior (docs/planning.md); uniform: uniform "
                   "over the Rusinkiewicz angles, as `brdfkit sample -n` draws.")
@click.option("--seed", type=int, default=0, show_default=True, help="Seed of everything random in the design.")
@click.option("--evaluations", type=click.IntRange(min=1), default=None,
              help="nielsen: cells evaluated per added direction [default: 2000].")
@click.option("--refine/--no-refine", default=None,
              help="nielsen: move the chosen cells to better grid neighbours at the end [default: refine].")
@click.option("--draws", type=click.IntRange(min=0), default=None,
              help="render: materials drawn from the basis's prior (with --given: from the fit's posterior around "
                   "its estimate) to average the render error over [default: 16].")
@click.option("--candidates", type=click.IntRange(min=1), default=None,
              help="render: cells considered, drawn at random from the basis's [default: 100000].")
@click.option("--within", type=click.Path(dir_okay=False), default=None, metavar="SAMPLES",
              help="Choose among the directions of this sample file (an instrument's measurements or reachable "
                   "configurations: .csv or pbrt-v2 .brdf), one per cell of the MERL grid, at their own angles.")
@click.option("--given", type=click.Path(dir_okay=False), default=None, metavar="SAMPLES",
              help="The samples of this material measured so far (any sample file, as --within): choose the next N "
                   "directions for it, from the fit's posterior after them and at its estimate, never in a cell "
                   "measured (render design; docs/planning.md, \"Measuring in rounds\").")
@click.option("-o", "--output", type=click.Path(dir_okay=False), required=True, help="Output directions CSV.")
def command(n, model, design, seed, evaluations, refine, draws, candidates, within, given, output):
    """Write N measurement directions chosen for the reconstruction with a PCA basis.

    The CSV (docs/formats.md, "Directions CSV") gives each direction pair as the
    Rusinkiewicz angles theta_h,theta_d,phi_d (radians) and as the unit vectors
    wi_x..wo_z of the local frame (z the normal): what the light source and the detector
    are set to. Measure there (or `brdfkit sample TABLE --at` it), then `brdfkit sparse`.
    In rounds: --given the samples so far chooses the next N for this material.
    See docs/planning.md.
    """
    from brdfkit.atomic import refuse_overwrite_of_inputs
    from brdfkit.console import console
    from brdfkit.errors import InputError
    from brdfkit.io.directions import write_directions
    from brdfkit.io.sample_files import read_sample_file
    from brdfkit.acquisition.planning import plan_directions

    refuse_overwrite_of_inputs(output, [p for p in (model, within, given) if p])
    applies = {"nielsen": ("evaluations", "refine"), "render": ("draws", "candidates")}
    values = {"evaluations": evaluations, "refine": refine, "draws": draws, "candidates": candidates}
    options = {k: v for k, v in values.items() if _given(k)}
    wrong = [k for k in options if k not in applies.get(design, ())]
    if wrong:
        raise InputError(f"{' and '.join('--' + k for k in wrong)} do not apply to --design {design}")
    samples = read_sample_file(within) if within else None
    so_far = read_sample_file(given) if given else None
    plan = plan_directions(model, n, design=design, seed=seed, within=samples, given=so_far, **options)
    write_directions(output, plan.directions, comments=[
        f"brdfkit plan: {plan.describe()}" + (f"; among the {len(samples)} directions of {within}" if within else ""),
        "theta_h,theta_d,phi_d: Rusinkiewicz angles in radians; wi, wo: unit vectors, z the surface normal, "
        "phi_h = 0 (any rotation about the normal measures the same)"])
    console().print(f"wrote {len(plan)} directions to {output} ({plan.describe()})")
