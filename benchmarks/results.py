"""Regenerate ``docs/notes/results.md`` by one command: run the two benchmarks, write the page.

    python benchmarks/results.py --proxies PROXIES --runs RUNS [--jobs 2] [--skip-run]
                                 [--out docs/notes/results.md] [--test-list ../shared/data/merl-test.txt]

Run from the repository root. ``PROXIES`` holds ``merl/`` and ``rgl/`` folders of proxy
tables (``python ../shared/tools/nbrdf_to_merl.py merl|rgl DIR``, ``docs/data.md``);
``RUNS`` receives the PCA bases, the two bench folders and the shared render cache.
Unless ``--skip-run``, it runs, printing each command first (the compressions first: the
suite's renders make the sparse benchmark the long one, about three hours with two
jobs):

1. ``RUNS/ipca80.safetensors`` (when missing): ``brdfkit fit --method basis`` on the 80
   MERL training materials, the materials ``merl80-l40`` was trained on;
2. the sparse benchmark (``prior``, ``ipca``, ``nbrdf``, ``hypernet``; 3 draws; 64 px)
   with uniform samples at N = 40, 160, 400, 2000, 4000 (issue 22's) into
   ``RUNS/bench-uniform``, with samples at the ``render`` design's directions (``brdfkit
   plan``) at N = 20, 40 into ``RUNS/bench-planned``, and the two merged into
   ``RUNS/bench-sparse``;
3. ``RUNS/all151``, a folder of links to every MERL and RGL proxy (refused when a name
   is in both), and ``RUNS/ipca151-13.safetensors`` (when missing), a 13-component basis
   fitted on it;
4. the compression benchmark of ``merl-rgl-l40`` (its default ``encode``, a basis
   embedding of 39 numbers, and ``merl-rgl-l40:hypernet``, the hypernetwork's 40-D
   latent), ``merl-rgl-l7`` and that basis's leading 13, 8 and 2 components (PCA-13
   beside 40-D, IPCA-8, PCA-2 beside 7-D: the same count of numbers) on all 151 tables
   into ``RUNS/bench-compression``;
5. ``RUNS/ipca80-13.safetensors`` (when missing) on the 80 training materials, and the
   compression of the 20 test materials, which no model here was trained on, by
   ``merl80-l40`` (basis embedding and latent) against its PCA-13 and IPCA-8 into
   ``RUNS/bench-unseen``.

Every bench renders in the scene suite (``--scenes all``, ``docs/render.md``) at 64 px
(six scenes cost six renders a reconstruction: at 128 px the run took about nine hours on
the 2-core machine): the figures are means over the six scenes, with each scene's in a
table beside them.

Every bench runs with ``--resume``: after an interruption the same command goes on
where it stopped (a finished bench is not run again; measure afresh in an empty RUNS).

Then (or straight away with ``--skip-run``) it reads the two ``bench.json``, writes the
page (atomically) and copies the bench figures beside it (``images/bench-*.png``), and
prints issue 22's done-when check. Every figure on the page is computed from the records
(``results_page.py``). Bad input: one line, exit code 2; a failed command: its exit code.
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import shutil
import subprocess
import sys

import results_page as page
from brdfkit.atomic import atomic_open, atomic_path
from brdfkit.errors import InputError

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
FIGURES = (("sparse", "error_vs_cpu_time.png", "bench-error-vs-cpu-time.png"),
           ("sparse", "error_vs_time.png", "bench-error-vs-time.png"),
           ("sparse", "error_vs_n.png", "bench-error-vs-n.png"),
           ("compression", "compression.png", "bench-compression.png"))


def plan(proxies: str, runs: str, test_list: str, jobs: int) -> dict:
    """The commands, as argument lists starting with ``brdfkit`` (what is printed and put
    on the page), and the files the fits make."""
    j = lambda *p: os.path.join(*p)  # noqa: E731
    sparse = ["brdfkit", "bench", "--data", j(proxies, "merl"), "--test-list", test_list, "-m", "merl80-l40",
              "--ipca", j(runs, "ipca80.safetensors"), "--model-file", "prior=merl80-l40",
              "--methods", "prior,ipca,nbrdf,hypernet", "--seeds", "3"]
    common = ["--scenes", "all", "--resolution", "64", "--jobs", str(jobs), "--threads", "1", "--device", "cpu",
              "--cache", j(runs, "bench-cache"), "--resume"]
    return {
        "ipca80": j(runs, "ipca80.safetensors"), "ipca151": j(runs, "ipca151-13.safetensors"),
        "ipca80k": j(runs, "ipca80-13.safetensors"),
        "all151": j(runs, "all151"),
        "fit80": ["brdfkit", "fit", "--method", "basis", j(proxies, "merl"), "--exclude-list", test_list,
                  "-o", j(runs, "ipca80.safetensors")],
        "planned": [*sparse, "--n", "20,40", "--sampling", "planned", "--plan-model", "merl80-l40",
                    "--plan-design", "render", *common, "-o", j(runs, "bench-planned")],
        "uniform": [*sparse, "--n", "40,160,400,2000,4000", *common, "-o", j(runs, "bench-uniform")],
        "sparse": ["brdfkit", "bench", "--merge", j(runs, "bench-uniform"), "--merge", j(runs, "bench-planned"),
                   "-o", j(runs, "bench-sparse")],
        "fit151": ["brdfkit", "fit", "--method", "basis", j(runs, "all151"), "--components", "13",
                   "-o", j(runs, "ipca151-13.safetensors")],
        "compression": ["brdfkit", "bench", "--compression-models",
                        "merl-rgl-l40,merl-rgl-l40:hypernet,merl-rgl-l7,basis-8,basis-2",
                        "--compression-data", j(runs, "all151"), "--ipca", j(runs, "ipca151-13.safetensors"),
                        *common, "-o", j(runs, "bench-compression")],
        "fit80k": ["brdfkit", "fit", "--method", "basis", j(proxies, "merl"), "--exclude-list", test_list,
                   "--components", "13", "-o", j(runs, "ipca80-13.safetensors")],
        "unseen": ["brdfkit", "bench", "--compression-models", "merl80-l40,merl80-l40:hypernet,basis-8",
                   "--compression-data", j(runs, "test20"), "--ipca", j(runs, "ipca80-13.safetensors"),
                   *common, "-o", j(runs, "bench-unseen")],
    }


def _brdfkit() -> list[str]:
    script = os.path.join(os.path.dirname(sys.executable), "brdfkit")
    if os.path.exists(script):
        return [script]
    return [sys.executable, "-c", "import sys; from brdfkit.cli import main; main(sys.argv[1:])"]


def run(argv: list[str]) -> None:
    print("$ " + shlex.join(argv), flush=True)
    code = subprocess.run(_brdfkit() + argv[1:]).returncode
    if code:
        print(f"results.py: error: the command above failed (exit code {code})", file=sys.stderr)
        sys.exit(code)


def link_all(proxies: str, folder: str) -> int:
    """Make ``folder`` a folder of links to every ``PROXIES/merl`` and ``PROXIES/rgl``
    table (links it made before are updated, stale ones removed); returns their count."""
    sources: dict = {}
    for sub in ("merl", "rgl"):
        d = os.path.join(proxies, sub)
        if not os.path.isdir(d):
            raise InputError(f"{d}: not a folder (PROXIES must hold merl/ and rgl/)")
        for f in sorted(os.listdir(d)):
            if not f.endswith(".binary"):
                continue
            clash = [k for k in sources if k.lower() == f.lower()]
            if clash:
                raise InputError(f"{f}: a material of that name is in both {sources[clash[0]]} and {d}; "
                                 f"rename one (the compression folder holds both)")
            sources[f] = os.path.abspath(os.path.join(d, f))
    os.makedirs(folder, exist_ok=True)
    for f in os.listdir(folder):
        p = os.path.join(folder, f)
        if f.endswith(".binary") and not os.path.islink(p):
            raise InputError(f"{p}: not a link; {folder} must hold only links this script makes")
        if f.endswith(".binary") and os.readlink(p) != sources.get(f):
            os.unlink(p)
    for f, src in sources.items():
        if not os.path.lexists(os.path.join(folder, f)):
            os.symlink(src, os.path.join(folder, f))
    return len(sources)


def link_test(proxies: str, test_list: str, folder: str) -> int:
    """Make ``folder`` a folder of links to the test materials' ``PROXIES/merl`` tables
    (the compression of materials no model here was trained on; a test material without a
    table is left out, as the sparse bench leaves it out); returns their count."""
    from brdfkit.io.folders import read_exclude_list

    os.makedirs(folder, exist_ok=True)
    names = read_exclude_list(test_list)
    names = [n for n in names if os.path.isfile(os.path.join(proxies, "merl", n + ".binary"))]
    for name in names:
        src = os.path.abspath(os.path.join(proxies, "merl", name + ".binary"))
        link = os.path.join(folder, name + ".binary")
        if os.path.lexists(link) and os.readlink(link) != src:
            os.unlink(link)
        if not os.path.lexists(link):
            os.symlink(src, link)
    return len(names)


def read_bench(folder: str) -> dict:
    path = os.path.join(folder, "bench.json")
    if not os.path.isfile(path):
        raise InputError(f"{path}: missing (run without --skip-run, or give the RUNS the benchmarks wrote)")
    try:
        with open(path, encoding="utf-8") as f:
            doc = json.load(f)
    except (OSError, UnicodeDecodeError, ValueError) as e:
        raise InputError(f"{path}: not readable as a bench result ({e})") from None
    if not isinstance(doc, dict) or doc.get("format") != "brdfkit-bench" or "records" not in doc:
        raise InputError(f"{path}: not a brdfkit bench result")
    return doc


def builtin_entry(path):
    """The manifest entry whose hypernetwork or learnt prior is ``path`` (or ``None``)."""
    from brdfkit.models.builtin import read_manifest

    if not path or not os.path.isfile(path):
        return None
    man, name, digest = read_manifest(), os.path.basename(path), None
    for m in man.bundles:
        files = [p.path for part, p in m.parts.items() if part in ("network", "prior")]
        # the same bytes, wherever the run found them (a checkout of the same commit)
        for f in (f for f in files if os.path.basename(f) == name):
            digest = digest or _digest(path)
            if _digest(f) == digest:
                return m
    return None


def _digest(path) -> str:
    import hashlib

    with open(path, "rb") as f:
        return hashlib.file_digest(f, "sha256").hexdigest()


def training_materials(path):
    """The training materials a model file's header names (a learnt prior, a PCA basis,
    a hypernetwork), or ``None``; the header only, no tensor is read."""
    meta = _header(path)
    try:
        names = json.loads(meta["materials"]) if "materials" in meta else \
            json.loads(meta.get("meta", "{}")).get("materials")
    except Exception:  # unreadable or another format: the page says "unknown"
        return None
    return set(names) if isinstance(names, list) else None


def same_materials_line(sparse: dict) -> str:
    """Whether the learnt prior and the IPCA basis of the sparse run were fitted on the
    same materials, and none of the test materials, from their files' headers."""
    cfg = sparse["config"]
    prior, ipca = (training_materials(p) if p and os.path.isfile(p) else None
                   for p in (_prior_file((cfg.get("models") or {}).get("prior")), cfg.get("ipca")))
    if prior is None or ipca is None:
        return "Training materials of the learnt prior and the IPCA basis: unknown (files not readable here)."
    test = set(sparse["materials"]["sparse"])
    return (f"Training materials (from the model files): the learnt prior {len(prior)}, the IPCA basis "
            f"{len(ipca)}; the same set: {'yes' if prior == ipca else 'no'}; test materials among them: "
            f"{len(test & (prior | ipca))}.")


def _prior_file(spec):
    """The learnt-prior file a bench's ``prior`` model names: a file as given, a built-in's
    name resolved (``--model-file prior=merl80-l40``); ``None`` if neither."""
    from brdfkit.errors import BrdfkitError
    from brdfkit.models.builtin import resolve_prior

    if not spec or os.path.isfile(spec):
        return spec
    try:
        return resolve_prior(spec)
    except BrdfkitError:
        return None


def _header(path) -> dict:
    from safetensors import safe_open

    try:
        with safe_open(path, "np") as f:
            return f.metadata() or {}
    except Exception:  # unreadable or another format: the page says "n/a"
        return {}


def _trained(path, prior: bool = False) -> str:
    """Which model a file is and how long it trained: a hypernetwork's figures from the
    manifest, a learnt prior's from its own header (it trains separately)."""
    m = builtin_entry(path)
    if m is None:
        return f"model file `{os.path.basename(path or '?')}` (not a built-in)"
    steps, secs = m.steps, m.train_seconds
    if prior:
        meta = _header(path)
        try:
            steps, secs = int(meta["steps"]), float(meta["wall_time_s"])
        except (KeyError, ValueError):
            steps = secs = None
    took = f"{steps:,} steps in {secs / 60:.0f} min" if steps and secs else "n/a"
    return f"built-in `{m.name}`, trained on {m.materials_list or m.materials}: CPU, {took}"


def _pca_spec(spec) -> bool:
    """``basis-K`` (``pca-K`` in earlier runs): the leading components of the ``--ipca``
    basis, not a model file."""
    head, _, k = str(spec).partition("-")
    return head in ("basis", "pca") and k.isdigit()


def differs_table(sparse: dict, comp: dict) -> list[str]:
    cfg, env, ccfg = sparse["config"], sparse["environment"], comp["config"]
    seeds = sorted({r.get("seed") for r in sparse["records"] if r["kind"] == "sparse"})
    ipca = [r["method"] for r in comp["records"] if r["kind"] == "compression" and r["method"].startswith("ipca")]
    rows = [
        ("data", "the measured MERL tables (with measurement noise)",
         "**NBRDF proxies**: the published NBRDF networks (Sztrajman et al. 2021) evaluated on the MERL grid "
         "(`python ../shared/tools/nbrdf_to_merl.py merl|rgl DIR`, `docs/data.md`); smooth, no noise, "
         "slightly softened specular peaks"),
        ("split", "80 MERL train / 20 test", "the same 20 test materials (`merl-test.txt`); the hypernetwork, "
         "the learnt prior, its basis and the IPCA baseline all fitted on the other 80"),
        ("hypernetwork (sparse)", "GPU, to convergence", _trained(cfg.get("model"))),
        ("learnt prior (`prior`)", "none: brdfkit's own method",
         _trained((cfg.get("models") or {}).get("prior"), prior=True) + "; **not the paper's architecture** "
         "([generalisation.md](generalisation.md), [models.md](../models.md))"),
        ("compression models", "7-D and 40-D trained for compression on MERL (and a MERL + RGL variant)",
         "; ".join(_trained(p) for p in ccfg.get("compression_models") or () if not _pca_spec(p)) or "none"),
        ("IPCA in compression", "protocol not stated",
         (f"{ipca[0]} fitted on all the compressed tables; PCA-K is its K leading components (PCA-13 beside "
          f"40-D, IPCA-8, PCA-2 beside 7-D: the same count of numbers)" if ipca else "none")),
        ("scene for PSNR / Delta E / SSIM", "the paper's renders",
         f"our scene suite ([render.md](../render.md)): a sphere under {len(cfg.get('scenes') or ['reference'])} "
         f"procedural HDR environment(s) ({', '.join(cfg.get('scenes') or ['reference'])}), the figures their "
         f"mean, deterministic quadrature renderer, **{cfg['resolution']} x {cfg['resolution']} pixels**, whole "
         f"image"),
        ("draws", "not stated", f"{page.plural(len(seeds), 'draw')} of N samples per material (seeds "
         f"{', '.join(map(str, seeds))}), uniform over the Rusinkiewicz angles (at N = 10, 20, 40 also at "
         f"planned directions, `(planned)`), the same samples for every method"),
        ("NBRDF baseline", "fitted to measured samples", "fitted to samples of tables **made by NBRDF networks "
         "of the same architecture**: the proxies lie in the baseline's own function class, which favours it"),
        ("timing", "GPU", f"CPU ({env.get('cpus')} cores, {env.get('machine')}), {env.get('threads')} torch "
         f"thread(s) per process, {cfg.get('jobs')} process(es), on a machine shared with other work: wall "
         f"times are inflated; CPU times are given beside them"),
    ]
    return ["| | paper | here |", "| --- | --- | --- |"] + [f"| {a} | {b} | {c} |" for a, b, c in rows]


def compose(sparse: dict, comp: dict, proxies: str, cmds: dict, one: str, figures: set, unseen=None) -> str:
    dates = sorted({s[:10] for d in (sparse, comp) for s in [d["started"], *d.get("merged_from", [])]})
    check = page.done_when(sparse)
    sparse = page.with_sampling_labels(sparse)
    lines = ["# Results: the paper's experiments on the NBRDF proxies", "",
             f"Generated by `{one}` ([How to regenerate](#how-to-regenerate-every-number)) from the two "
             f"`bench.json` files it names; do not edit by hand. Measured with `brdfkit bench` "
             f"([bench.md](../bench.md)) on {' and '.join(dates)}. **Read the caveats first**: these are not the "
             f"paper's conditions. The built-in models were trained on a CPU for minutes, not on a GPU to "
             f"convergence, the tables are proxies, and the scene is ours. The raw records (every material, N, "
             f"draw and method) are in the `bench.json` files.", "",
             "## What differs from the paper (Gokbudak et al. 2024)", "", *differs_table(sparse, comp), "",
             "## Issue 22's done-when check", "",
             "With `merl80-l40` and IPCA-8 fitted on the same 80 materials, on the 20 test materials, draws 0, 1, "
             "2: does the default (`prior`) reach IPCA's PSNR at N = 40 and IPCA's + 1 dB from N = 160 on, "
             "with at most 0.8 of IPCA's BRDF log RMSE at every N; and does it reach from 20 planned "
             "directions the PSNR it reaches from 40 uniform samples? From the records (means over the "
             "material and draw pairs both sides finished):", "",
             *[f"* {line}" for line in page.done_lines(check)], "", same_materials_line(sparse), "",
             "## Methods", "", *[f"* {page.METHOD_TEXT[m]}" for m in page.methods_of(sparse)
                                 if m in page.METHOD_TEXT],
             *([f"* {page.PLANNED_TEXT}"] if any(m.endswith("(planned)") for m in page.methods_of(sparse))
               else []), f"* {page.COMPRESSION_TEXT}", "",
             *page.sparse_section(sparse)]
    if "bench-error-vs-cpu-time.png" in figures:
        lines += ["![error against CPU time](images/bench-error-vs-cpu-time.png)", "",
                  "Error against CPU time per reconstruction (one thread; each method a curve through its N, "
                  "error bars = spread over draws). The same against wall time: "
                  "[bench-error-vs-time.png](images/bench-error-vs-time.png); against N: "
                  "[bench-error-vs-n.png](images/bench-error-vs-n.png).", ""]
    hyp = builtin_entry(sparse["config"].get("model"))
    lines += [*page.sparse_findings(sparse),
              *page.paper_section(sparse, hyp.name if hyp else os.path.basename(sparse["config"].get("model") or "?")),
              *page.compression_section(comp, proxies, figure="bench-compression.png" in figures),
              *(page.compression_section(unseen, proxies, figure=False, title="Compression of unseen materials",
                                         intro="The test materials, which `merl80-l40` and the PCA bases were "
                                               "fitted without (all on the other 80 MERL materials).")
                if unseen else ["## Compression of unseen materials", "", "Not run (no `bench-unseen`).", ""]),
              *regenerate(sparse, comp, cmds, one, proxies)]
    return "\n".join(lines).rstrip() + "\n"


def regenerate(sparse, comp, cmds, one, proxies) -> list[str]:
    from brdfkit.models.builtin import read_manifest

    lines = ["## How to regenerate every number", "",
             "From the repository root (`../shared` beside it), with the proxies made first (`docs/data.md`):",
             "", "```sh", f"python ../shared/tools/nbrdf_to_merl.py merl {os.path.join(proxies, 'merl')}",
             f"python ../shared/tools/nbrdf_to_merl.py rgl {os.path.join(proxies, 'rgl')}", one, "```", "",
             "The last line runs, printing each (a fit only when its output is missing):", "", "```sh",
             shlex.join(cmds["fit80"]), shlex.join(cmds["planned"]), shlex.join(cmds["uniform"]),
             shlex.join(cmds["sparse"]),
             f"# {cmds['all151']}: links to every {proxies}/merl and {proxies}/rgl table (no name in both)",
             shlex.join(cmds["fit151"]), shlex.join(cmds["compression"]),
             f"# {os.path.dirname(cmds['all151'])}/test20: links to the test materials of {proxies}/merl",
             shlex.join(cmds["fit80k"]), shlex.join(cmds["unseen"]), "```", ""]
    for key, doc in (("sparse", sparse), ("compression", comp)):
        recorded = doc["config"].get("command") or ""
        if recorded and recorded != shlex.join(cmds[key]):
            lines += [f"The {key} `bench.json` records another command (these figures are that run's):", "",
                      "```sh", recorded, "```", ""]
    used = {m.name: m for m in read_manifest().bundles}
    names = [n for n in ("merl80-l40", "merl-rgl-l40", "merl-rgl-l7") if n in used and used[n].command]
    if names:
        lines += ["The built-in models were trained by (manifest, [models.md](../models.md)):", "", "```sh"]
        lines += [f"# {n}\n" + used[n].command.replace("; ", "\n") for n in names] + ["```", ""]
    lines += ["The figures `images/bench-*.png` are the runs' `error_vs_cpu_time.png`, `error_vs_time.png`, "
              "`error_vs_n.png` and `compression.png`, copied.", ""]
    return lines


def copy_figures(runs_dirs: dict, images: str) -> set:
    os.makedirs(images, exist_ok=True)
    copied = set()
    for kind, src, dst in FIGURES:
        path = os.path.join(runs_dirs[kind], src)
        if os.path.isfile(path):
            with atomic_path(os.path.join(images, dst)) as tmp:
                shutil.copyfile(path, tmp)
            copied.add(dst)
    return copied


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="results.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("--proxies", required=True, help="folder with merl/ and rgl/ proxy tables")
    ap.add_argument("--runs", required=True, help="folder for the bases, bench outputs and render cache")
    ap.add_argument("--skip-run", action="store_true", help="only read RUNS/bench-*/bench.json and write the page")
    ap.add_argument("--jobs", type=int, default=2, help="bench worker processes (default 2)")
    ap.add_argument("--test-list", default="../shared/data/merl-test.txt", help="the 20 test materials")
    ap.add_argument("--out", default=os.path.join("docs", "notes", "results.md"),
                    help="the page (figures go into images/ beside it); default docs/notes/results.md")
    args = ap.parse_args(argv)
    cmds = plan(args.proxies, args.runs, args.test_list, args.jobs)
    one = shlex.join(["python", "benchmarks/results.py", "--proxies", args.proxies, "--runs", args.runs,
                      "--jobs", str(args.jobs)])
    dirs = {"sparse": os.path.join(args.runs, "bench-sparse"),
            "compression": os.path.join(args.runs, "bench-compression"),
            "unseen": os.path.join(args.runs, "bench-unseen")}
    try:
        if args.jobs < 1:
            raise InputError(f"--jobs must be at least 1, got {args.jobs}")
        if not args.skip_run:
            for p in (os.path.join(args.proxies, "merl"), os.path.join(args.proxies, "rgl")):
                if not os.path.isdir(p):
                    raise InputError(f"{p}: not a folder (PROXIES must hold merl/ and rgl/)")
            if not os.path.isfile(args.test_list):
                raise InputError(f"{args.test_list}: no such file (the test materials' list)")
            os.makedirs(args.runs, exist_ok=True)
            print(f"# {cmds['all151']}: {link_all(args.proxies, cmds['all151'])} links", flush=True)
            if not os.path.exists(cmds["ipca151"]):
                run(cmds["fit151"])
            run(cmds["compression"])
            print(f"# {os.path.join(args.runs, 'test20')}: "
                  f"{link_test(args.proxies, args.test_list, os.path.join(args.runs, 'test20'))} links", flush=True)
            if not os.path.exists(cmds["ipca80k"]):
                run(cmds["fit80k"])
            run(cmds["unseen"])
            if not os.path.exists(cmds["ipca80"]):
                run(cmds["fit80"])
            for key in ("planned", "uniform", "sparse"):
                run(cmds[key])
        sparse, comp = read_bench(dirs["sparse"]), read_bench(dirs["compression"])
        unseen = read_bench(dirs["unseen"]) if os.path.isdir(dirs["unseen"]) else None
        out_dir = os.path.dirname(os.path.abspath(args.out))
        if not os.path.isdir(out_dir):
            raise InputError(f"{args.out}: folder {out_dir} does not exist")
        figures = copy_figures(dirs, os.path.join(out_dir, "images"))
        text = compose(sparse, comp, args.proxies, cmds, one, figures, unseen)
        with atomic_open(args.out, "w", encoding="utf-8") as f:
            f.write(text)
    except InputError as e:
        print(f"results.py: error: {e}", file=sys.stderr)
        return 2
    print(f"wrote {args.out} and {len(figures)} figure(s)")
    print("Issue 22 done-when check (prior against ipca, same 80 training materials; planned against uniform):")
    for line in page.done_lines(page.done_when(sparse)) + [same_materials_line(sparse)]:
        print("  " + line)
    return 0


if __name__ == "__main__":
    sys.exit(main())
