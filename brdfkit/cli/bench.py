"""``brdfkit bench``: error against run time of the reconstruction methods, and compression."""

from __future__ import annotations

import click

from brdfkit.errors import InputError
from brdfkit.cli.common import parse_option


def _int_list(value: str, name: str) -> tuple:
    try:
        out = tuple(int(v) for v in value.split(",") if v.strip())
    except ValueError:
        raise InputError(f"{name}: {value!r} is not a comma-separated list of integers") from None
    if not out or min(out) < 1:
        raise InputError(f"{name}: {value!r}: give positive integers, e.g. 40,160,400")
    return out


def _str_list(value: str | None) -> tuple:
    return tuple(v.strip() for v in (value or "").split(",") if v.strip())


@click.command("bench")
@click.option("--data", type=click.Path(file_okay=False), default=None,
              help="Folder of MERL tables for the sparse benchmark.")
@click.option("--test-list", type=click.Path(dir_okay=False), default=None,
              help="Test material names, one a line (e.g. merl-test.txt, the paper's 20 test materials: docs/data.md); default: all of --data.")
@click.option("-m", "--model", type=click.Path(dir_okay=False), default=None, metavar="NAME|FILE",
              help="Hypernetwork model (.safetensors, or a built-in name) for the method 'hypernet'; a built-in "
                   "with a learnt prior gives the method 'prior' its model too.")
@click.option("--ipca", type=click.Path(dir_okay=False), default=None, metavar="NAME|FILE",
              help="PCA basis (.safetensors from `brdfkit fit --method basis`, or a built-in name: its basis) "
                   "for 'ipca' and the compression reference.")
@click.option("--model-file", "model_files", multiple=True, metavar="METHOD=FILE",
              help="The model file (or built-in name) of any method that needs one (repeatable), e.g. "
                   "prior=merl80-l40; -m and --ipca are the same for hypernet and ipca.")
@click.option("--n", "n_list", default="40,160,400,2000,4000", show_default=True,
              help="Sample counts N, comma-separated.")
@click.option("--seeds", type=int, default=3, show_default=True,
              help="Draws of samples per material and N (mean and spread over them).")
@click.option("--first-seed", type=int, default=0, show_default=True,
              help="First seed (seeds FIRST .. FIRST+K-1): more draws later, then --merge.")
@click.option("--methods", default=None,
              help="Reconstruction methods, comma-separated [default: hypernet,ipca,nbrdf, led by prior "
                   "when -m names a built-in with a learnt prior (as `sparse --method auto` picks) or "
                   "--model-file prior= is given].")
@click.option("--sampling", "sampling", default="uniform", show_default=True,
              help="Samplings, comma-separated: uniform (random draws over the angles) and/or planned (the table "
                   "measured at `brdfkit plan` directions for --plan-model); every N and draw is run with each.")
@click.option("--plan-model", default=None, metavar="NAME|FILE",
              help="PCA basis planned samples are planned for (a built-in with a learnt prior, a basis or "
                   "learnt-prior file) [default: the --ipca basis].")
@click.option("--plan-design", default="render", show_default=True,
              help="Design of the planned samples (`brdfkit plan --design`).")
@click.option("--compression-models", default=None,
              help="What to test on encode -> decode, comma-separated: MODEL[:KIND[-SIZE]], a built-in's name or "
                   "a basis or hypernetwork file, encoded as `brdfkit encode -m MODEL --kind KIND --size SIZE` does "
                   "(e.g. merl80-l40, merl80-l40:basis-21, merl80-l40:hypernet, merl-rgl-l7); basis-K (pca-K before): "
                   "the projection on the K leading components of --ipca (3 K numbers: basis-13 beside "
                   "merl80-l40:basis-39).")
@click.option("--compression-data", type=click.Path(file_okay=False), default=None,
              help="Folder of MERL tables for the compression benchmark.")
@click.option("--scenes", default="reference", show_default=True, metavar="all|A,B",
              help="Scenes of the suite the renders are scored in (docs/render.md); with several, PSNR, "
                   "Delta E and SSIM are their means, and each scene's is recorded.")
@click.option("--resolution", type=int, default=128, show_default=True,
              help="Reference-scene render size (pixels square) for PSNR, Delta E and SSIM.")
@click.option("--jobs", type=int, default=1, show_default=True,
              help="Worker processes (one material at a time each).")
@click.option("--threads", type=int, default=None,
              help="Torch threads per process [default: torch's choice, or CPUs / jobs].")
@click.option("--device", default=None, help="Torch device (default: CUDA when present, else CPU).")
@click.option("--nbrdf-steps", type=int, default=None, help="Most optimiser steps of the NBRDF baseline.")
@click.option("--ipca-lambda", type=float, default=None, help="Ridge weight of the PCA baseline.")
@click.option("-O", "--option", "method_options", multiple=True, metavar="METHOD.KEY=VALUE",
              help="An option of a method, e.g. nbrdf.lr=0.005 (repeatable; see docs/baselines.md).")
@click.option("--group-by-prefix", is_flag=True,
              help="Also summarise per family: the material name up to its first '-' (merl-*, rgl-*).")
@click.option("--cache", type=click.Path(file_okay=False), default=None,
              help="Folder of cached reference renders [default: OUTDIR/cache].")
@click.option("-o", "--output", type=click.Path(file_okay=False), required=True,
              help="Output folder: bench.json, bench.md, error_vs_n.png, error_vs_time.png, compression.png.")
@click.option("--merge", "merge", multiple=True, type=click.Path(), metavar="RUN",
              help="Instead of running: merge the bench.json of finished runs (folders or files, "
                   "repeat the option) into -o.")
@click.option("--allow-incomplete", is_flag=True,
              help="With --merge: also merge interrupted runs (the materials every run finished).")
@click.option("--replace", is_flag=True,
              help="With --merge: a method that a later run holds replaces its records in the earlier runs "
                   "(one method re-run after a change).")
@click.option("--resume", is_flag=True,
              help="Go on with the interrupted run in OUTPUT: keep its finished materials, run the others "
                   "(same options but --jobs).")
@click.option("-q", "--quiet", is_flag=True, help="No progress bar.")
def command(data, test_list, model, ipca, model_files, n_list, seeds, first_seed, methods, sampling, plan_model,
            plan_design, compression_models, compression_data, scenes,
            resolution, jobs, threads, device, nbrdf_steps, ipca_lambda, method_options, group_by_prefix, cache, merge, replace, output,
            allow_incomplete, resume, quiet):
    """Measure reconstruction error against run time (and compression error).

    For each test material of --data, each N, each seed and each --sampling, every method
    reconstructs the material from the same N samples; each reconstruction is timed and
    scored in BRDF space (log RMSE) and on reference-scene renders (PSNR, Delta E 2000,
    SSIM).
    See docs/bench.md.
    """
    import shlex
    import sys

    from brdfkit.bench import BenchConfig, merge_results, run_bench
    from brdfkit.console import console
    from brdfkit.render.scene_suite import scene_names

    if merge:
        if data or compression_models:
            raise InputError("--merge combines finished runs; give no --data or --compression-models with it")
        result = merge_results(merge, output, allow_incomplete=allow_incomplete, replace=replace)
        console().print(f"merged {len(merge)} runs: wrote {', '.join(result['outputs'])}")
        return

    options = {m: o for m, o in (("nbrdf", {"steps": nbrdf_steps}), ("ipca", {"lam": ipca_lambda}))
               if None not in o.values()}
    for item in method_options:
        key, value = parse_option(item)
        method, dot, name = key.partition(".")
        if not dot or not method or not name:
            raise InputError(f"-O {item!r}: expected METHOD.KEY=VALUE, e.g. nbrdf.lr=0.005")
        options.setdefault(method, {})[name] = value
    models = {}
    for item in model_files:
        name, sep, path = item.partition("=")
        if not sep or not name.strip() or not path:
            raise InputError(f"--model-file {item!r}: expected METHOD=FILE")
        models[name.strip()] = path
    cfg = BenchConfig(output=output, data=data, test_list=test_list, model=model, ipca=ipca, models=models,
                      n=_int_list(n_list, "--n"), seeds=seeds, first_seed=first_seed,
                      methods=None if methods is None else _str_list(methods),
                      sampling=_str_list(sampling), plan_model=plan_model, plan_design=plan_design,
                      compression_models=_str_list(compression_models), compression_data=compression_data,
                      scenes=tuple(scene_names(scenes)),
                      resolution=resolution, jobs=jobs, threads=threads, device=device,
                      options=options,
                      group_by_prefix=group_by_prefix,
                      cache=cache, command="brdfkit bench " + shlex.join(sys.argv[2:] if len(sys.argv) > 1
                                                                         and sys.argv[1] == "bench" else []))
    result = run_bench(cfg, progress=not quiet, resume=resume)
    failed = sum("error" in r for r in result["records"])
    out = console()
    out.print(f"wrote {', '.join(result['outputs'])}")
    if failed:
        out.print(f"[yellow]{failed} of {len(result['records'])} reconstruction(s) failed; "
                  f"see the Failures section of bench.md[/yellow]")
