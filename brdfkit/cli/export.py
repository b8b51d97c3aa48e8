"""``brdfkit export``: an embedding's decoder as GLSL for an engine."""

from __future__ import annotations

import click

from brdfkit.cli.common import model_option


@click.command("export")
@click.argument("embedding", type=click.Path(dir_okay=False))
@model_option
@click.option("--glsl", "folder", required=True, type=click.Path(file_okay=False),
              help="Folder for the GLSL, its textures, material.json, README.md and view.html: new or empty.")
@click.option("--force", is_flag=True,
              help="Write into a folder that holds files (the export's files over those of the same names).")
def command(embedding, model_path, folder, force):
    """Write a basis or residual EMBEDDING (.emb) as GLSL for an engine: `vec3
    brdfkit_eval(vec3 wi, vec3 wo)`, the decoder that bakes its table on the GPU from the
    embedding's numbers, the basis as textures, the uniforms, a README on binding them,
    and view.html, the page that renders it with these files (docs/view.md).
    """
    from brdfkit.console import console
    from brdfkit.view.export import export_glsl

    done = export_glsl(embedding, folder, model_path=model_path, force=force)
    total = sum(n for _, n in done["files"])
    console().print(f"{folder}: {len(done['files'])} files, {total / 1e6:.1f} MB ({done['kind']} embedding of "
                    f"{done['size']} numbers): {', '.join(f for f, _ in done['files'])}", soft_wrap=True)
