"""Write the finished networks of a cut residual training as a residual file.

``brdfkit fit --method residual`` trains its networks in turn (``-O members=M`` networks a
size) and writes the file at the end. When a training is cut (a session ends), its
checkpoint ``OUTPUT.ckpt`` holds the networks already finished; this writes them as the
residual file ``OUTPUT`` (what the whole run would have written of them, a size then having
fewer members), and keeps the checkpoint, so that ``--resume`` finishes the rest::

    python tools/residual_checkpoint.py proxies/merl proxies/rgl -O basis=merl-rgl-l40 \\
        --steps 4000 -O lr_end=0.05 -O members=4 --seed 0 -o runs/merl-rgl-residual.safetensors

The arguments are the training's (``--exclude-list`` too), so that the checkpoint's identity
(tables, basis, options) is checked.
"""

from __future__ import annotations

import argparse
import sys


def main(argv=None) -> int:
    from brdfkit.cli.common import parse_option
    from brdfkit.errors import BrdfkitError
    from brdfkit.io.folders import read_exclude_list
    from brdfkit.residual.training import write_finished

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("data", nargs="+")
    ap.add_argument("-o", "--output", required=True)
    ap.add_argument("-O", dest="options", action="append", default=[], metavar="KEY=VALUE")
    ap.add_argument("--steps", type=int)
    ap.add_argument("--seed", type=int)
    ap.add_argument("--exclude-list")
    args = ap.parse_args(argv)
    try:
        # -O read as brdfkit fit reads it, so that the checkpoint's identity is the training's
        opts = dict(parse_option(o) for o in args.options)
        for key in ("steps", "seed"):
            if getattr(args, key) is not None:
                opts[key] = getattr(args, key)
        exclude = read_exclude_list(args.exclude_list) if args.exclude_list else ()
        n = write_finished(args.data, args.output, exclude=exclude, **opts)
    except BrdfkitError as e:
        print(f"residual_checkpoint: error: {e}", file=sys.stderr)
        return 2
    print(f"wrote {args.output}: {n} finished network(s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
