"""The ``brdfkit`` command line: a thin Click group over the library.

Subcommands live in their own modules (``brdfkit/cli/<name>.py``, each defining
``command``) and are imported only when run, so ``brdfkit --help`` starts without torch,
mitsuba or colour-science. Errors a user can fix (:class:`brdfkit.errors.BrdfkitError`)
become one line on stderr and exit code 2.

May import: any library package, inside the command that needs it; nothing imports the
CLI (it is the top layer).
"""

from __future__ import annotations

import importlib
import importlib.util
import os
import sys

from brdfkit.runtime import start_profile

start_profile()  # $BRDFKIT_PROFILE: the process's stages, from here to its end (brdfkit.runtime.stage)

import click  # noqa: E402

from brdfkit.errors import BrdfkitError  # noqa: E402

# name -> one-line help, shown by ``brdfkit --help`` without importing the module.
COMMANDS = {
    "demo": "Try the built-in models on real materials (--train: synthetic).",
    "synth": "Write a library of synthetic (GGX) materials as MERL tables.",
    "material": "Write a real material that brdfkit ships as a MERL table.",
    "sample": "Measure a BRDF table into a CSV sample set (N random, or --at).",
    "plan": "Choose N measurement directions for a reconstruction.",
    "fit": "Train a hypernetwork (or a baseline) on MERL tables.",
    "tune": "Tune a trained hypernetwork on renders of its materials.",
    "encode": "Compress MERL tables into embedding (.emb) files.",
    "decode": "Expand an embedding into a dense MERL table.",
    "convert": "Convert MERL .binary <-> RGL .bsdf (Mitsuba 3, pbrt-v4).",
    "sparse": "Reconstruct a dense MERL table from sparse samples.",
    "validate": "Held-out error of sparse reconstructions on real measurements.",
    "interpolate": "Blend two embeddings (material editing).",
    "render": "Render a BRDF in the reference scene or a Mitsuba scene.",
    "metrics": "Image and BRDF-space errors between predictions and references.",
    "bench": "Error-against-run-time benchmark of the reconstruction methods.",
    "plot": "Plot BRDFs side by side: in-plane lobes and slices (PNG).",
    "compare": "Sheet of renders and error images against a reference.",
    "view": "Write an HTML page that renders BRDFs live in WebGL2.",
    "export": "Write an embedding's decoder as GLSL for an engine.",
    "models": "List the built-in pretrained models (the names -m takes).",
}


def _available(name: str) -> bool:
    return importlib.util.find_spec(f"brdfkit.cli.{name}") is not None


class LazyGroup(click.Group):
    def list_commands(self, ctx):
        return [n for n in COMMANDS if _available(n)]

    def get_command(self, ctx, name):
        if name not in COMMANDS or not _available(name):
            return None
        return importlib.import_module(f"brdfkit.cli.{name}").command

    def format_commands(self, ctx, formatter):
        rows = [(n, COMMANDS[n]) for n in self.list_commands(ctx)]
        if rows:
            with formatter.section("Commands"):
                formatter.write_dl(rows)


@click.group(cls=LazyGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="brdfkit")
def cli():
    """brdfkit: measured BRDFs and hypernetwork neural BRDFs.

    Reads and writes MERL .binary tables; reconstructs a dense table from a few BRDF
    samples (by default with a learnt prior over a PCA basis; with the hypernetwork of
    Gokbudak et al., ECCV 2024, by sparse --method hypernet); compresses tables into a
    few numbers; renders and scores the result. Start with `brdfkit demo`.
    """


def fail(message: str, code: int = 2):
    """Print ``brdfkit: error: message`` on stderr and exit with ``code``."""
    click.echo(f"brdfkit: error: {message}", err=True)
    sys.exit(code)


def main(argv=None):
    """Console-script entry point: runs the group and maps errors to exit codes."""
    from brdfkit.runtime import set_default_threads

    set_default_threads()  # before any command imports torch
    try:
        rv = cli.main(args=argv, prog_name="brdfkit", standalone_mode=False)
    except BrdfkitError as e:
        fail(str(e), e.exit_code)
    except click.exceptions.Abort:
        fail("interrupted", 130)
    except KeyboardInterrupt:
        fail("interrupted", 130)
    except click.UsageError as e:
        # One line, like every other bad input; Click's usage block is one --help away.
        cmd = e.ctx.command_path if e.ctx is not None else "brdfkit"
        fail(f"{e.format_message()} (see '{cmd} --help')", e.exit_code)
    except click.ClickException as e:
        fail(e.format_message(), e.exit_code)
    except click.exceptions.Exit as e:
        sys.exit(e.exit_code)
    except BrokenPipeError:
        sys.exit(1)
    except MemoryError:
        fail("out of memory", 1)
    except OSError as e:
        where = f"{e.filename}: " if getattr(e, "filename", None) else ""
        fail(f"{where}{e.strerror or e}", 2 if e.filename else 1)
    except Exception as e:  # a bug, not bad input: one line unless asked for the traceback
        if os.environ.get("BRDFKIT_DEBUG"):
            raise
        fail(f"internal error: {type(e).__name__}: {e} (set BRDFKIT_DEBUG=1 for the traceback)", 1)
    sys.exit(rv if isinstance(rv, int) else 0)
