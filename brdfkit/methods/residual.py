"""The learnt prior's fit decoded through the basis plus the correction trained on such
fits: ``brdfkit sparse``'s default with the built-in models (:mod:`brdfkit.prior.corrected`).

The method takes a model's ``residual`` part (a built-in's, or a residual file of
``brdfkit fit --method correction``) and the learnt prior whose fits its network corrects:
the one its record names among the installed built-ins, or ``-O prior=FILE``. What it
gains over ``--method prior`` on materials and scenes it never saw: ``docs/reconstruct.md``.

May import: what :mod:`brdfkit.methods` may.
"""

from __future__ import annotations

import dataclasses
import os

from brdfkit.methods.method import Method, MethodOptions

__all__ = ["METHOD", "ResidualOptions"]


@dataclasses.dataclass(frozen=True)
class ResidualOptions(MethodOptions):
    """``correction``: ``"auto"`` (kept where the held-out samples say it helps), ``"on"``
    or ``"off"``; ``prior``: the learnt-prior file the correction was trained on (default:
    the installed built-in its file names)."""

    correction: str = "auto"
    prior: str | None = None


def _load(path, device):
    from brdfkit.models.parts import load_part

    return load_part(path, "residual", device), path


def _model(loaded, options):
    """The :class:`~brdfkit.prior.corrected.CorrectedPrior` of a loaded residual and its
    learnt prior: ``options.prior``, else the one the residual's record names, else the
    prior of the installed built-in whose residual it is."""
    from brdfkit.errors import InputError
    from brdfkit.io.digest import file_digest
    from brdfkit.models.builtin import bundle_of_part, find_by_digest, resolve_prior
    from brdfkit.prior.corrected import CorrectedPrior
    from brdfkit.prior.prior_file import load_prior

    residual, path = loaded
    named = (residual.meta.get("sparse") or residual.meta).get("prior_digest")
    where = resolve_prior(options.prior) if options.prior else find_by_digest(named)
    if where is None:
        bundle = bundle_of_part(path, "residual")
        where = resolve_prior(bundle.name) if bundle is not None and bundle.part("prior") else None
    if where is None:
        raise InputError(f"{path}: the learnt prior its correction was trained on is not installed; "
                         f"give it with -O prior=FILE")
    prior = load_prior(where)
    if named and not options.prior and prior.digest != named:
        raise InputError(f"{where}: not the learnt prior {os.path.basename(path)}'s correction was trained on")
    return CorrectedPrior(prior, residual, file_digest(path))


def _reconstruct(samples, loaded, options, *, seed, device):
    model = _model(loaded, options)
    fit = model.fit(samples, correction=options.correction)
    return model.decode(fit), model.embedding(fit, samples.source)


def _describe(loaded, path):
    residual, _ = loaded
    stem = os.path.splitext(os.path.basename(os.fspath(path)))[0]
    k = residual.basis.n_components
    return f"residual-{3 * k} ({stem})", 3 * k, set(residual.meta.get("materials") or ())


METHOD = Method("residual", "the learnt prior's basis fit plus a hypernetwork correction trained on such fits, kept "
                "where held-out samples say it helps (brdfkit's default, docs/reconstruct.md)",
                "basis residual with a sparse correction (.safetensors from `brdfkit fit --method correction`, or a "
                "built-in name)", options=ResidualOptions, part="residual", load_fn=_load,
                reconstruct_fn=_reconstruct, describe_fn=_describe)
