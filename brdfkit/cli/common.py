"""Options and helpers shared by the subcommands."""

from __future__ import annotations

import json

import click

from brdfkit.errors import InputError

MODEL_ENV = "BRDFKIT_MODEL"


def model_option(f):
    """``-m/--model``, falling back to ``$BRDFKIT_MODEL``: a model file or the name of a
    built-in model (each command resolves it to the part it takes)."""
    return click.option("-m", "--model", "model_path", type=click.Path(dir_okay=False),
                        default=None, envvar=MODEL_ENV, show_envvar=True, metavar="NAME|FILE",
                        help="Built-in model name (`brdfkit models`) or model file (.safetensors) "
                             "made by `brdfkit fit`; default: the built-in default (for an embedding: the "
                             "built-in that made it).")(f)


def require_model(model_path: str | None) -> str:
    """The hypernetwork's network file to use: ``-m`` / ``$BRDFKIT_MODEL`` (a file or a
    built-in name), else the default built-in; else an error saying how to get one."""
    from brdfkit.models.builtin import default_bundle, resolve_network

    if model_path:
        return resolve_network(model_path)
    found = default_bundle()
    if found is None or found.part("network") is None:
        raise InputError("no model given: pass -m NAME or -m MODEL.safetensors, or set BRDFKIT_MODEL (no default "
                         "built-in model is installed; `brdfkit models` lists the built-in ones; make a model with "
                         "`brdfkit fit DATA... -o model.safetensors`, or run `brdfkit demo`, which trains one)")
    return resolve_network(found.name)


def parse_float(value: str, name: str) -> float:
    """A finite float from an option string, or an InputError naming the option."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{name}: {value!r} is not a number") from None
    if x != x or x in (float("inf"), float("-inf")):
        raise InputError(f"{name}: {value!r} is not a finite number")
    return x


def parse_option(text: str) -> tuple[str, object]:
    """``-O KEY=VALUE``: the key (``-`` read as ``_``) and the value parsed as JSON (a
    list becomes a tuple), or the bare word."""
    if "=" not in text:
        raise InputError(f"-O {text!r}: expected KEY=VALUE (see docs/training.md for the keys)")
    key, value = text.split("=", 1)
    key = key.strip().replace("-", "_")
    try:
        parsed = json.loads(value)
    except ValueError:
        parsed = value  # a bare word, e.g. lr_schedule=cosine
    if isinstance(parsed, list):
        parsed = tuple(parsed)
    return key, parsed
