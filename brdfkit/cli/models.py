"""``brdfkit models``: list the built-in pretrained models."""

from __future__ import annotations

import json
import os

import click


def _duration(seconds) -> str:
    if seconds is None:
        return "-"
    if seconds < 120:
        return f"{seconds:.0f} s"
    if seconds < 7200:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"


def _parts(m) -> str:
    """The bundle's parts, by name, a missing file marked."""
    return " ".join(name + ("" if os.path.isfile(p.path) else " (missing)") for name, p in m.parts.items())


def _table(columns):
    from rich import box
    from rich.table import Table

    tab = Table(box=box.SIMPLE_HEAD, padding=(0, 1), pad_edge=False, collapse_padding=True, show_edge=False)
    for col in columns:
        # Fold rather than cut with an ellipsis when a terminal is narrower still.
        tab.add_column(col, justify="left" if col == "name" else "right", overflow="fold")
    return tab


def _json(m, served: dict) -> dict:
    d = m.to_json()
    for p in d["parts"].values():
        p["installed"] = os.path.isfile(p["path"])
    if m.name in served:
        d["serves"] = served[m.name].to_json()
    return d


def _key(k: str):
    return (0, int(k), k) if str(k).isdigit() else (1, 0, str(k))


def _print_renders(out, installed) -> None:
    """The bundles' and their parts' validation figures as renders: PSNR dB / Delta E
    2000 per N (or ``encode``, ``encode-SIZE``), and how they were measured (which
    materials, held out or not)."""
    rows = [(m.name, m.renders) for m in installed if m.renders.get("psnr")]
    rows += [(f"{m.name} {name}", p.renders) for m in installed for name, p in m.parts.items()
             if p.renders.get("psnr")]
    if not rows:
        return
    keys = sorted({k for _, r in rows for k in r["psnr"]}, key=_key)
    out.print("\nValidation: renders, PSNR dB / Delta E 2000 (N: from N samples; encode-SIZE: encode + decode at "
              "SIZE numbers; -: not measured; which materials, below)")
    val = _table(("name", *(f"N={k}" if str(k).isdigit() else str(k) for k in keys)))
    for name, r in rows:
        p, e = r["psnr"], r.get("delta_e", {})
        val.add_row(name, *(f"{p[k]:.1f}/{e[k]:.2f}" if k in p and k in e else "-" for k in keys))
    out.print(val)
    for name, r in rows:
        out.print(f"{name}: {r.get('materials', 'held-out materials')}; scenes "
                  f"{', '.join(r.get('scenes', ['reference']))}; {r.get('resolution', '?')} px", soft_wrap=True)


@click.command("models")
@click.option("--json", "as_json", is_flag=True, help="Print the manifest's bundles as JSON on stdout.")
@click.option("--check", is_flag=True,
              help="Also load each part of each built-in and check it against the manifest.")
def command(as_json, check):
    """List the built-in models: the names `-m` takes, with how each was trained.

    A built-in model is a bundle of parts: its hypernetwork (network), PCA basis (basis),
    learnt prior (prior) and basis residual (residual); each job takes the part it needs.
    What each serves is listed as the jobs take it: the embedding kinds `encode --kind`
    makes and their sizes (`--size`; residual members: the networks a size among which
    encode chooses), and the methods `sparse --method` runs, auto's first. Validation figures are renders (PSNR and Delta E 2000) of reconstructions from N
    samples of held-out materials, or of encode + decode (the materials named, held out
    or not), then the BRDF log RMSE. A model with a learnt prior reconstructs sparse
    samples with it by default (`brdfkit sparse`, docs/models.md). The folder is the
    package's brdfkit/models, or $BRDFKIT_BUILTIN_MODELS when set.
    """
    from brdfkit.methods.service import installed_services
    from brdfkit.models.builtin import read_manifest

    man = read_manifest()
    installed = man.installed()
    served = {s.bundle: s for s in installed_services()}
    if check:
        for m in installed:
            _check(m)
    if as_json:
        click.echo(json.dumps({"folder": man.folder, "default": man.default,
                               "bundles": [_json(m, served) for m in man.bundles]}, indent=1))
        return
    if not installed:
        click.echo(f"no built-in models installed (in {man.folder}); pass -m MODEL.safetensors from `brdfkit fit`")
        return
    from rich.console import Console

    # Two narrow tables, not one wide one: each fits an 80-column terminal, and the
    # validation table grows by one 8-column N per figure without pushing the rest out.
    # Headings, notes and paths are plain lines: a table's title would wrap at its width.
    ns = sorted({n for m in installed for n in m.validation})
    out = Console(markup=False)  # a path or list name may hold "[...]"
    out.print(f"Built-in models in {man.folder}", soft_wrap=True)
    tab = _table(("name", "parts", "dim", "mats", "steps", "time"))
    for m in installed:
        tab.add_row(m.name + (" *" if m.default else ""), _parts(m), "-" if m.latent_dim is None else str(m.latent_dim),
                    "-" if m.materials is None else str(m.materials), "-" if m.steps is None else f"{m.steps:,}",
                    _duration(m.train_seconds))
    out.print(tab)
    out.print("*: the default. dim: its hypernetwork's latent.")
    _print_renders(out, installed)
    if ns:
        out.print("\nBRDF-space: log RMSE on held-out materials from N samples (-: not measured)")
        val = _table(("name", *(f"N={n}" for n in ns)))
        for m in installed:
            val.add_row(m.name, *("-" if m.validation.get(n) is None else f"{m.validation[n]:.3f}" for n in ns))
        out.print(val)
    _print_served(out, installed, served)
    out.print()
    for m in installed:
        lists = f"; materials: {m.materials_list}" if m.materials_list else ""
        for name, p in m.parts.items():
            out.print(f"{m.name} {name}: {p.path} (digest {p.digest[:12]}{lists})", soft_wrap=True)
    missing = [m.name for m in man.bundles if not m.installed]
    if missing:
        out.print(f"in the manifest but not installed: {', '.join(missing)}")
    if check:
        parts = sum(len(m.parts) for m in installed)
        out.print(f"checked: {len(installed)} model(s), {parts} part(s): each loads and matches the manifest")


def _print_served(out, installed, served) -> None:
    """What each built-in serves (:mod:`brdfkit.methods.service`): a line of embedding kinds
    and sizes, a line of sparse methods."""
    out.print("\nServes: encode --kind KIND --size N (the first kind and the * size by default;")
    out.print("members: networks a size, chosen per material); sparse --method (auto's first)")
    for m in installed:
        s = served[m.name]
        kinds = "; ".join(f"{k} {_sizes(sizes, s.default_sizes[k])}"
                          + (f" ({s.members[k]} members)" if s.members[k] > 1 else "") for k, sizes in s.kinds.items())
        out.print(f"{m.name} encode: {kinds or 'none'}", soft_wrap=True)
        out.print(f"{m.name} sparse: {', '.join(s.methods) or 'none'}", soft_wrap=True)


def _sizes(sizes, default) -> str:
    """Sizes for the listing, the default marked: ``9, 21, 39*`` or ``3, 6, ... 90 (39*)``."""
    if len(sizes) > 3:
        return f"{sizes[0]}, {sizes[1]}, ... {sizes[-1]} ({default}*)"
    return ", ".join(f"{x}*" if x == default else str(x) for x in sizes)


def _check(m) -> None:
    """Load each part of bundle ``m``: resolving checks a file's digest against the
    manifest, loading its weights against the digest it records (FormatError if not)."""
    from brdfkit.models.builtin import load_part

    for name in m.parts:
        load_part(m.name, name)
