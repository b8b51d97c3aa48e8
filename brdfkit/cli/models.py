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


def _prior_path(m) -> str:
    return os.path.join(os.path.dirname(m.path), m.prior)


def _prior_state(m) -> str:
    if not m.prior:
        return "-"
    return "yes" if os.path.isfile(_prior_path(m)) else "missing"


def _table(columns):
    from rich import box
    from rich.table import Table

    tab = Table(box=box.SIMPLE_HEAD, padding=(0, 1), pad_edge=False, collapse_padding=True, show_edge=False)
    for col in columns:
        # Fold rather than cut with an ellipsis when a terminal is narrower still.
        tab.add_column(col, justify="left" if col == "name" else "right", overflow="fold")
    return tab


def _json(m) -> dict:
    d = m.to_json()
    d["prior_installed"] = bool(m.prior) and os.path.isfile(_prior_path(m))
    return d


def _key(k: str):
    return (0, int(k), k) if str(k).isdigit() else (1, 0, str(k))


def _print_renders(out, installed) -> None:
    """The models' validation figures as renders: PSNR dB / Delta E 2000 per N (or
    ``encode``), and how they were measured (which materials, held out or not)."""
    have = [m for m in installed if m.renders.get("psnr")]
    if not have:
        return
    keys = sorted({k for m in have for k in m.renders["psnr"]}, key=_key)
    out.print("\nValidation: renders, PSNR dB / Delta E 2000 (N: from N samples; encode: encode + decode; "
              "-: not measured; which materials, below)")
    val = _table(("name", *(f"N={k}" if str(k).isdigit() else str(k) for k in keys)))
    for m in have:
        p, e = m.renders["psnr"], m.renders.get("delta_e", {})
        val.add_row(m.name, *(f"{p[k]:.1f}/{e[k]:.2f}" if k in p and k in e else "-" for k in keys))
    out.print(val)
    for m in have:
        r = m.renders
        out.print(f"{m.name}: {r.get('materials', 'held-out materials')}; scenes "
                  f"{', '.join(r.get('scenes', ['reference']))}; {r.get('resolution', '?')} px", soft_wrap=True)


@click.command("models")
@click.option("--json", "as_json", is_flag=True, help="Print the manifest's entries as JSON on stdout.")
@click.option("--check", is_flag=True,
              help="Also load each model (and learnt prior) and check its weights against the manifest.")
def command(as_json, check):
    """List the built-in models: the names `-m` takes, with how each was trained.

    Validation figures are renders (PSNR and Delta E 2000) of reconstructions from N
    samples of held-out materials, or of encode + decode (the materials named, held out
    or not), then the BRDF log RMSE. A
    model with a learnt prior (column prior) reconstructs sparse samples with it by
    default (`brdfkit sparse`, docs/models.md). The folder is the package's
    brdfkit/models, or $BRDFKIT_BUILTIN_MODELS when set.
    """
    from brdfkit.models.builtin import read_manifest
    from brdfkit.hypernet.packing import load_builtin

    man = read_manifest()
    installed = man.installed()
    if check:
        from brdfkit.methods.prior.prior_file import load_prior
        from brdfkit.models.builtin import resolve_basis, resolve_prior

        for m in installed:
            # Resolving checks the file's recorded fingerprint against the manifest,
            # loading its weights against the recorded fingerprint: FormatError if not.
            load_builtin(m.name, device="cpu")
            if m.prior:
                load_prior(resolve_prior(m.name), device="cpu")  # and its basis file's digest
            if m.basis:
                resolve_basis(m.name)  # the basis file's SHA-256 against the manifest's
    if as_json:
        click.echo(json.dumps({"folder": man.folder, "default": man.default,
                               "models": [_json(m) for m in man.models]}, indent=1))
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
    tab = _table(("name", "dim", "prior", "mats", "steps", "time"))
    for m in installed:
        tab.add_row(m.name + (" *" if m.default else ""), str(m.latent_dim), _prior_state(m),
                    "-" if m.materials is None else str(m.materials), "-" if m.steps is None else f"{m.steps:,}",
                    _duration(m.train_seconds))
    out.print(tab)
    out.print("*: the default. prior: has a learnt prior (sparse's default method with it).")
    _print_renders(out, installed)
    if ns:
        out.print("\nBRDF-space: log RMSE on held-out materials from N samples (-: not measured)")
        val = _table(("name", *(f"N={n}" for n in ns)))
        for m in installed:
            val.add_row(m.name, *("-" if m.validation.get(n) is None else f"{m.validation[n]:.3f}" for n in ns))
        out.print(val)
    out.print()
    for m in installed:
        lists = f"; materials: {m.materials_list}" if m.materials_list else ""
        out.print(f"{m.name}: {m.path} (fingerprint {m.fingerprint[:12]}{lists})", soft_wrap=True)
        if m.prior:
            out.print(f"{m.name} learnt prior: {_prior_path(m)} (fingerprint {m.prior_fingerprint[:12]})",
                      soft_wrap=True)
    missing = [m.name for m in man.models if not m.installed]
    if missing:
        out.print(f"in the manifest but not installed: {', '.join(missing)}")
    if check:
        priors = sum(1 for m in installed if m.prior)
        also = f" and {priors} learnt prior(s)" if priors else ""
        out.print(f"checked: {len(installed)} model(s){also} load and match the manifest")
