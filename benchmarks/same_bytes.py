"""Whether this checkout encodes and decodes as a git revision did: the same embeddings
(their documents, apart from a field renamed since) and the same decoded tables, byte for
byte, for each route given, on the shipped materials (``brdfkit material``).

A change that should leave renders alone (a refactor, a new check, a faster path) shows
here as every route ``same``; a route whose numbers moved shows ``DIFFER`` with the keys
that differ. The revision runs from a ``git worktree`` in a temporary folder, with its
own built-in models, through its own command line (``PYTHONPATH``); its decode takes the
routes whose files it can read (before issue 55 it refused ``merl80-l40``'s residual
embeddings, ``correction.1``), and this checkout decodes the rest.

    python benchmarks/same_bytes.py e81e1de

Prints one line a route and material; exit code 1 if any differs.
"""

from __future__ import annotations

import argparse
import filecmp
import json
import os
import subprocess
import sys
import tempfile

ROUTES = ("merl80-l40:residual:9", "merl80-l40:residual:39", "merl-rgl-l40:residual:39",
          "merl80-l40:basis:21", "merl80-l40:hypernet:40")
IGNORED = {"solver"}
"""Keys of an embedding's document renamed since the revisions compared (the refinement's
record named Levenberg-Marquardt ``gauss-newton`` before issue 55)."""


def _brdfkit(root: str | None, *args) -> bool:
    """``brdfkit ARGS`` of this checkout (``root`` None) or of the worktree ``root``."""
    env = dict(os.environ, **({"PYTHONPATH": root} if root else {}))
    cmd = [sys.executable, "-c", "import sys; from brdfkit.cli import main; main(sys.argv[1:])", *map(str, args)]
    return subprocess.run(cmd, cwd=root, env=env, capture_output=True).returncode == 0


def _document(path: str):
    def strip(x):
        if isinstance(x, dict):
            return {k: strip(v) for k, v in x.items() if k not in IGNORED}
        return [strip(v) for v in x] if isinstance(x, list) else x
    return strip(json.load(open(path, encoding="utf-8")))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("rev", help="the git revision to compare with")
    ap.add_argument("--routes", nargs="+", default=list(ROUTES), help="MODEL:KIND:SIZE")
    ap.add_argument("--materials", nargs="+", default=["teflon", "chrome-steel"])
    a = ap.parse_args(argv)
    if subprocess.run(["git", "rev-parse", "--verify", "--quiet", f"{a.rev}^{{commit}}"], capture_output=True).returncode:
        ap.error(f"{a.rev}: not a commit of this repository")
    tmp = tempfile.mkdtemp(prefix="same-bytes-")
    old = os.path.join(tmp, "rev")
    subprocess.run(["git", "worktree", "add", "--detach", old, a.rev], check=True, capture_output=True)
    differ = False
    try:
        tables = [os.path.join(tmp, f"{m}.binary") for m in a.materials]
        for m, t in zip(a.materials, tables):
            assert _brdfkit(None, "material", m, "-o", t), m
        for route in a.routes:
            model, kind, size = route.split(":")
            out = {w: os.path.join(tmp, f"{w}-{model}-{kind}-{size}") for w in ("rev", "head")}
            for w, root in (("rev", old), ("head", None)):
                _brdfkit(root, "encode", *tables, "-m", model, "--kind", kind, "--size", size, "-o", out[w])
            for m in a.materials:
                e = {w: os.path.join(out[w], f"{m}.emb") for w in out}
                d = {w: os.path.join(tmp, f"{w}-{model}-{kind}-{size}-{m}.binary") for w in out}
                docs = {w: _document(e[w]) for w in e}
                keys = sorted(k for k in set(docs["rev"]) | set(docs["head"]) if docs["rev"].get(k) != docs["head"].get(k))
                if not _brdfkit(old, "decode", e["rev"], "-o", d["rev"]):
                    _brdfkit(None, "decode", e["rev"], "-o", d["rev"])
                _brdfkit(None, "decode", e["head"], "-o", d["head"])
                table = filecmp.cmp(d["rev"], d["head"], shallow=False)
                differ |= bool(keys) or not table
                print(f"{route} {m}: embedding {'DIFFER in ' + ', '.join(keys) if keys else 'same'}, "
                      f"decoded table {'same' if table else 'DIFFER'}")
    finally:
        subprocess.run(["git", "worktree", "remove", "--force", old], capture_output=True)
    return int(differ)


if __name__ == "__main__":
    sys.exit(main())
