"""Decided: the basis decoders' lower bound (``brdfkit.basis.mapping.FLOOR``, ``CAP``, issue
41) costs nothing in renders: ``merl80-l40``'s basis embeddings of the first N MERL test
materials (encoded as ``brdfkit encode --kind basis`` does), decoded with the bound and
with Nielsen's inverse clamped at 0 (``floor=0``), differ by -0.01 to +0.02 dB in every
judged scene at 9, 21 and 39 numbers (128 px; 5 materials). Reported in
``docs/notes/compression.md``, "The residual shipped in merl80-l40".

    PROXIES=proxies python benchmarks/studies/study_floor_renders.py 5   # proxies/merl, proxies/merl-test.txt
"""
import os

import sys, json
import numpy as np
import brdfkit
from brdfkit.embeddings import choose_decoder
from brdfkit.io.merl import read_merl
from brdfkit.render.scene import Scene
from brdfkit.render.scene_suite import scene_env, SUITE
from brdfkit.render.quadrature import render
from brdfkit.render.renderable import TableBRDF
from brdfkit.evaluation.metrics import score
from brdfkit.runtime import set_torch_threads

set_torch_threads()
PROXIES = os.environ.get('PROXIES', 'proxies')  # the MERL proxies (merl/) and merl-test.txt
names = [l.strip() for l in open(os.path.join(PROXIES, 'merl-test.txt')) if l.strip()][:int(sys.argv[1])]
scene = Scene(resolution=128)
scenes = ["reference", "backlight", "rim", "small-lights", "overcast", "sunset"]
envs = {s: scene_env(s) for s in scenes}
def imgs(t):
    b = TableBRDF(t, device="cpu")
    return {s: render(b, scene, env=e)[0] for s, e in envs.items()}
out = {}
for name in names:
    ref = read_merl(os.path.join(PROXIES, 'merl', f'{name}.binary'))
    ri = imgs(ref)
    for size in (9, 21, 39):
        dec = choose_decoder("basis", "merl80-l40", size=size)
        emb = brdfkit.encode(ref, dec, size=size, source=name)
        from brdfkit.basis.coefficients import check_coefficients
        c = check_coefficients(emb, dec.obj, dec.digest)
        basis = dec.obj.leading(c.shape[0])
        row = {}
        for fl, tag in ((None, "floor"), (0.0, "none")):
            t = basis.decode(c) if fl is None else basis.decode(c, floor=0.0)
            ii = imgs(t)
            row[tag] = {s: score(ii[s], ri[s])["psnr"] for s in scenes}
        d = {s: row["floor"][s] - row["none"][s] for s in scenes}
        out.setdefault(size, []).append(d)
        print(name, size, "floor - none: mean %+.3f" % np.mean(list(d.values())), {s: round(v, 3) for s, v in d.items()}, flush=True)
for size, rows in out.items():
    per = {s: np.mean([r[s] for r in rows]) for s in scenes}
    print(f"size {size}: {len(rows)} materials, mean {np.mean(list(per.values())):+.3f} dB, worst scene {min(per.values()):+.3f}; "
          + ", ".join(f"{s} {v:+.3f}" for s, v in per.items()))
