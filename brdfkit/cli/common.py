"""Options and helpers shared by the subcommands."""

from __future__ import annotations

import json
import os

import click

from ..errors import InputError

MODEL_ENV = "BRDFKIT_MODEL"


def model_option(f):
    """``-m/--model``, falling back to ``$BRDFKIT_MODEL``."""
    return click.option("-m", "--model", "model_path", type=click.Path(dir_okay=False),
                        default=None, envvar=MODEL_ENV, show_envvar=True,
                        help="Model file (.safetensors) made by `brdfkit fit`.")(f)


def require_model(model_path: str | None) -> str:
    """The model path, or an error saying how to get one."""
    if not model_path:
        raise InputError("no model given: pass -m MODEL.safetensors or set BRDFKIT_MODEL "
                         "(make one with `brdfkit fit DATA... -o model.safetensors`, "
                         "or run `brdfkit demo`, which trains one)")
    return os.fspath(model_path)


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
