"""Decided: not to ship it yet (the product does not use it). The residual adds +3.39 dB over
full-precision PCA-3 on unseen MERL at 9 numbers (+4.20 dB chosen per material by the
objective scenes) but loses 0.33 dB on RGL by itself; shipping it needs a residual file per
basis and size and an embedding kind that records it. Reported in
``docs/notes/compression.md``, "The basis plus a hypernetwork residual (study, 2026-11-27,
64 px screens, the six judged scenes)".

Study: the basis plus a hypernetwork residual, at the small sizes where a linear basis
has too few components.

A basis embedding of ``3 K`` numbers decodes, channel by channel, the mapped table
``x' = mean + U_K c`` (:class:`brdfkit.basis.PcaBasis`). This study adds a correction that
the coefficients condition::

    x'(cell) = mean + U_K c + f(HD(cell); W(c / sigma))

``W`` is a hypernetwork (the paper's idea): from the ``K`` coefficients of one channel, in
training standard deviations, it predicts the weights of a small hyponet ``6 -> H -> H -> 1``
that is evaluated at each cell's Rusinkiewicz HD vector. The hyponet's weights are a learnt
base plus the predicted change, and the last layer's base and change start at 0: with no
correction the model *is* the basis. Channels are separate observations, as they are to the
basis, so ``M`` training tables give ``3 M`` (coefficients, residual) pairs, and a
permutation of the channels is no new data. Augmentation (``--mixup P``): with probability
``P`` a pair is blended with another in the mapped space, where a blend of two materials'
mapped tables has exactly the blend of their coefficients and residuals (NeuMaDiff's blends).

Training: the training tables' own least-squares coefficients (the start of every basis
embedding), the loss is the mean square of the mapped residual over cells drawn uniformly
from the basis's cells, a budget in steps (``--steps``; checkpoints every ``--eval-every``
steps, ``--resume`` continues). The basis is a built-in's (``merl80-basis``: the 80 MERL
training tables only), so the test materials were seen by neither part.

Scoring: each held-out table's projection onto ``K`` components, decoded by the basis alone,
by the basis plus the correction (at the projection's coefficients, and at coefficients fitted
through the correction, ``--fit-steps``), and by a full-precision PCA of the same size fitted
on the same training tables; rendered on the six suite scenes' screens
(:func:`brdfkit.render.screen.screen`, ``--resolution`` px) against the table's own, and the
mapped RMSE. No refinement on renders for any row.

    python benchmarks/studies/study_basis_residual.py --proxies proxies/merl \\
        --train-list train80.txt --test-list ../shared/data/merl-test.txt -k 3 --steps 6000 -o residual-k3
    python benchmarks/studies/study_basis_residual.py --proxies proxies/merl ... -o residual-k3 --resume --steps 12000
    python benchmarks/studies/study_basis_residual.py table residual-k3/result.json
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np
import torch

HERE = os.path.dirname(os.path.abspath(__file__))


def _names(path):
    with open(path, encoding="utf-8") as f:
        return [w for line in f for w in [line.split("#")[0].strip()] if w]


class Residual(torch.nn.Module):
    """Hypernetwork ``K -> 64 -> 64 -> weights`` of a hyponet ``6 -> H -> H -> 1``."""

    def __init__(self, k: int, width: int = 32, hidden: int = 64):
        super().__init__()
        self.k, self.h = k, width  # k: the input's width (2 K_max for a network of every size)
        self.shapes = [(6, width), (width,), (width, width), (width,), (width, 1), (1,)]
        sizes = [int(np.prod(s)) for s in self.shapes]
        self.sizes = sizes
        self.body = torch.nn.Sequential(torch.nn.Linear(k, hidden), torch.nn.ReLU(),
                                        torch.nn.Linear(hidden, hidden), torch.nn.ReLU())
        self.head = torch.nn.Linear(hidden, sum(sizes))
        base = []
        for shape in self.shapes:
            p = torch.zeros(shape)
            if len(shape) == 2 and shape[1] != 1:
                torch.nn.init.kaiming_uniform_(p.T, a=5 ** 0.5)
            base.append(p)
        self.base = torch.nn.ParameterList([torch.nn.Parameter(p) for p in base])
        with torch.no_grad():
            self.head.weight.mul_(0.1)
            self.head.bias.zero_()
            last = sum(sizes[:4])
            self.head.weight[last:].zero_()  # the last layer's change starts at 0

    def weights(self, z):
        """Per-row hyponet weights from ``z (B, K)``."""
        flat = self.head(self.body(z))
        out, at = [], 0
        for base, shape, n in zip(self.base, self.shapes, self.sizes):
            out.append(base + flat[:, at:at + n].reshape((-1,) + shape))
            at += n
        return out

    def forward(self, z, x):
        """Correction ``(B, C)`` at HD vectors ``x (B, C, 6)`` or ``(C, 6)`` (shared)."""
        w1, b1, w2, b2, w3, b3 = self.weights(z)
        if x.dim() == 2:
            h = torch.relu(torch.einsum("cd,bdh->bch", x, w1) + b1[:, None])
        else:
            h = torch.relu(torch.bmm(x, w1) + b1[:, None])
        h = torch.relu(torch.bmm(h, w2) + b2[:, None])
        return (torch.bmm(h, w3) + b3[:, None])[..., 0]


def net_input(c_norm, k_max):
    """The network's input for coefficients in training standard deviations ``(B, K)``:
    as they are (``k_max`` 0, a network of one size), or padded to ``k_max`` with a mask of
    the ``K`` given beside them (a network of every size ``K <= k_max``)."""
    c_norm = torch.as_tensor(c_norm, dtype=torch.float32)
    if not k_max:
        return c_norm
    b, k = c_norm.shape
    z = torch.zeros(b, 2 * k_max)
    z[:, :k] = c_norm
    z[:, k_max:k_max + k] = 1.0
    return z


def mapped(part, table):
    """Mapped table at the basis's cells, ``(P, 3)`` float64, minus the mean."""
    from brdfkit.basis.mapping import to_mapped
    from brdfkit.geometry import N_CELLS

    flat = np.asarray(table, np.float64).reshape(N_CELLS, 3)[part.cells]
    ref = part.reference[:, None].astype(np.float64)
    return to_mapped(np.nan_to_num(flat), part.cell_weight()[:, None], ref) - part.mean[:, None]


def unmap(part, x_mapped):
    """Dense table from a mapped ``(P, 3)`` (mean included), as :meth:`PcaBasis.decode`."""
    from brdfkit.basis.mapping import from_mapped
    from brdfkit.geometry import GRID_SHAPE, N_CELLS

    ref = part.reference[:, None].astype(np.float64)
    out = np.full((N_CELLS, 3), np.nan)
    out[part.cells] = from_mapped(x_mapped, part.cell_weight()[:, None], ref, floor=0)
    return out.reshape(GRID_SHAPE + (3,))


def training_pairs(part, paths, whole=False):
    """``z (3 M, K)`` float32 and residuals ``(3 M, P)`` float16 of the training tables
    (``whole``: the mapped tables less the mean, not the residuals)."""
    from brdfkit.io.merl import read_merl

    comp = part.components.astype(np.float64)
    zs, rs = [], []
    for p in paths:
        table = read_merl(p)
        b = mapped(part, table)
        c = part.project(table)  # (K, 3)
        r = b if whole else b - comp.T @ c
        zs.append((c / part.sigma[:, None]).T)
        rs.append(r.T.astype(np.float16))
    return np.concatenate(zs).astype(np.float32), np.concatenate(rs)


def correction(net, part, hd, c, chunk=131072, k_max=0):
    """The network's correction at every basis cell, ``(P, 3)`` float64, coefficients ``(K, 3)``."""
    z = net_input((c / part.sigma[:len(c), None]).T, k_max)
    out = []
    with torch.no_grad():
        for i in range(0, hd.shape[0], chunk):
            out.append(net(z, hd[i:i + chunk]).T.double().numpy())
    return np.concatenate(out)


def fit_through(net, part, hd, b, c0, steps, cells=65536, seed=0, k_max=0):
    """Coefficients minimising the mapped error of basis + correction, from ``c0``."""
    g = np.random.default_rng(seed)
    idx = torch.as_tensor(g.choice(hd.shape[0], size=min(cells, hd.shape[0]), replace=False))
    x, target = hd[idx], torch.as_tensor(b[idx.numpy()].T, dtype=torch.float32)  # (3, C)
    comp = torch.as_tensor(part.components[:, idx.numpy()], dtype=torch.float32)  # (K, C)
    sigma = torch.as_tensor(part.sigma, dtype=torch.float32)
    z = torch.tensor((c0 / part.sigma[:, None]).T, dtype=torch.float32, requires_grad=True)
    opt = torch.optim.Adam([z], lr=0.02)
    for _ in range(steps):
        pred = (z * sigma) @ comp + net(net_input(z, k_max) if k_max else z, x)
        loss = ((pred - target) ** 2).mean()
        opt.zero_grad()
        loss.backward()
        opt.step()
    return (z.detach().numpy() * part.sigma).T.astype(np.float64)


def train(net, opt, z, r, hd, a, step0, log, comp=None, sigma=None):
    """The step loop; with ``a.k_max`` (``comp`` ``(K_max, P)``, ``sigma`` ``(K_max,)``:
    ``r`` then holds the mapped tables less the mean) each row of a step draws its size
    ``K`` in ``1 .. k_max`` and its target is the residual of its leading ``K``."""
    g = torch.Generator().manual_seed(a.seed * 1_000_003 + step0)
    zt, n, p = torch.as_tensor(z), z.shape[0], r.shape[1]
    for step in range(step0, a.steps):
        rows = torch.randint(n, (a.batch,), generator=g)
        cells = torch.randint(p, (a.batch, a.cells), generator=g)
        zb = zt[rows]
        tb = torch.as_tensor(r[rows.numpy()[:, None], cells.numpy()], dtype=torch.float32)
        if a.mixup > 0:
            other = torch.randint(n, (a.batch,), generator=g)
            t = torch.rand(a.batch, generator=g) * (torch.rand(a.batch, generator=g) < a.mixup)
            zb = (1 - t[:, None]) * zb + t[:, None] * zt[other]
            to = torch.as_tensor(r[other.numpy()[:, None], cells.numpy()], dtype=torch.float32)
            tb = (1 - t[:, None]) * tb + t[:, None] * to
        if a.k_max:
            ks = torch.randint(1, a.k_max + 1, (a.batch,), generator=g)
            mask = (torch.arange(a.k_max)[None, :] < ks[:, None]).float()  # (B, K_max)
            zb = zb * mask
            tb = tb - torch.einsum("bk,kbc->bc", zb * sigma, comp[:, cells])
            zb = torch.cat([zb, mask], dim=1)
        pred = net(zb, hd[cells])
        loss = ((pred - tb) ** 2).mean()
        opt.zero_grad()
        loss.backward()
        opt.step()
        if step % 200 == 0:
            log(f"step {step} loss {loss.item():.5f} (the basis alone {float((tb ** 2).mean()):.5f})")
        if (step + 1) % a.eval_every == 0 or step + 1 == a.steps:
            yield step + 1


def score(net, part, full, hd, names, folder, a):
    from brdfkit.io.merl import read_merl
    from brdfkit.render.scene_suite import SUITE, scene_env
    from brdfkit.render.screen import screen, screen_psnr

    from brdfkit.render.objective import OBJECTIVE

    screens = {s: screen(None, a.resolution, env=scene_env(s)) for s in SUITE}
    objective = {s: screen(None, 32, env=scene_env(s)) for s in OBJECTIVE}
    recs = []
    for n in names:
        table = read_merl(os.path.join(folder, n + ".binary"))
        b = mapped(part, table)
        comp = part.components.astype(np.float64)
        c = part.project(table)
        rows = {"basis": b - comp.T @ c}
        rows["basis+residual"] = rows["basis"] - correction(net, part, hd, c, k_max=a.k_max)
        if a.fit_steps:
            cf = fit_through(net, part, hd, b, c, a.fit_steps, k_max=a.k_max)
            rows["basis+residual, fitted"] = b - comp.T @ cf - correction(net, part, hd, cf, k_max=a.k_max)
        tables = {k: unmap(part, b - err + part.mean[:, None]) for k, err in rows.items()}
        rmse = {k: float(np.sqrt(np.mean(err ** 2))) for k, err in rows.items()}
        if full is not None:
            tables["full PCA"] = full.decode(full.project(table))
            rmse["full PCA"] = None
        with torch.no_grad():
            # The encoder may choose per material, by renders of scenes never judged.
            seen = {s: sc.render_table(table) for s, sc in objective.items()}
            pick = {k: np.mean([screen_psnr(sc.render_table(tables[k]), seen[s]) for s, sc in objective.items()])
                    for k in rows}
            tables["chosen by objective scenes"] = tables[max(pick, key=pick.get)]
            if a.render:
                per = rendered(table, tables, a.resolution)
            else:
                refs = {s: sc.render_table(table) for s, sc in screens.items()}
                per = {k: {s: float(screen_psnr(sc.render_table(t), refs[s])) for s, sc in screens.items()}
                       for k, t in tables.items()}
        recs.append({"material": n, "mapped_rmse": rmse, "psnr": per, "chosen": max(pick, key=pick.get)})
        print(n, {k: round(float(np.mean([x for s, x in v.items() if ":" not in s])), 2) for k, v in per.items()},
              flush=True)
    return recs


def rendered(table, tables, resolution):
    """``{row: {scene: PSNR}}`` and ``{row: {scene: Delta E}}`` folded into one dict
    (``scene`` and ``scene:delta_e``) from the renderer the bench uses, at ``resolution``."""
    from brdfkit.evaluation.metrics import score as score_images
    from brdfkit.render.scene import reference_scene
    from brdfkit.render.quadrature import render_many
    from brdfkit.render.renderable import TableBRDF
    from brdfkit.render.scene_suite import SUITE, scene_env

    keys = list(tables)
    brdfs = [TableBRDF(table)] + [TableBRDF(tables[k]) for k in keys]
    per = {k: {} for k in keys}
    for s in SUITE:
        imgs = [img for img, _ in render_many(brdfs, reference_scene(resolution), env=scene_env(s))]
        for k, img in zip(keys, imgs[1:]):
            m = score_images(img, imgs[0])
            per[k][s], per[k][s + ":delta_e"] = float(m["psnr"]), float(m["delta_e"])
    return per


def summarise(recs):
    rows = {}
    for k in recs[0]["psnr"]:
        keys = list(recs[0]["psnr"][k])
        per = {s: float(np.mean([r["psnr"][k][s] for r in recs])) for s in keys if ":" not in s}
        rows[k] = {"suite": float(np.mean(list(per.values()))), "scenes": per}
        de = [r["psnr"][k][s] for r in recs for s in keys if s.endswith(":delta_e")]
        if de:
            rows[k]["delta_e"] = float(np.mean(de))
    return rows


def print_table(paths):
    """Markdown rows of ``result.json`` files: each row's suite mean and scenes, and its
    margin over the full-precision PCA of equal size (mean, worst scene)."""
    for path in paths:
        with open(path, encoding="utf-8") as f:
            doc = json.load(f)
        for name, block in doc["sets"].items():
            summ = block["summary"]
            scenes = list(summ["basis"]["scenes"])
            print(f"\n{name} ({len(block['records'])}), K = {doc['k']} ({3 * doc['k']} numbers), {doc['steps']} steps\n")
            print("| row | suite | Delta E | " + " | ".join(scenes) + " | vs full PCA: mean | worst scene |")
            print("| --- | ---: | ---: | " + " | ".join("---:" for _ in scenes) + " | ---: | ---: |")
            full = summ.get("full PCA")
            for row, v in summ.items():
                d = ([v["scenes"][s] - full["scenes"][s] for s in scenes] if full else [])
                tail = f"{v['suite'] - full['suite']:+.2f} | {min(d):+.2f}" if full else " | "
                de = f"{v['delta_e']:.3f}" if "delta_e" in v else "-"
                print(f"| {row} | {v['suite']:.2f} | {de} | " + " | ".join(f"{v['scenes'][s]:.2f}" for s in scenes)
                      + f" | {tail} |")
            chosen = [r.get("chosen") for r in block["records"] if r.get("chosen")]
            if chosen:
                print("\nchosen: " + ", ".join(f"{k} {chosen.count(k)}" for k in sorted(set(chosen))))


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["table"]:
        return print_table(argv[1:])
    ap = argparse.ArgumentParser()
    ap.add_argument("--basis", default=os.path.join(HERE, "..", "..", "brdfkit", "models", "merl80-basis.safetensors"))
    ap.add_argument("--proxies", required=True)
    ap.add_argument("--train-list", required=True)
    ap.add_argument("--test-list", required=True)
    ap.add_argument("--sets", nargs="*", default=[], help="NAME=FOLDER: every table of FOLDER scored too")
    ap.add_argument("-k", type=int, default=3, help="the size K scored (and trained, without --k-max)")
    ap.add_argument("--k-max", type=int, default=0,
                    help="one network of every size: each row of a step draws K in 1 .. K_MAX")
    ap.add_argument("--score-k", type=int, nargs="*", default=None, help="with --k-max: the sizes scored")
    ap.add_argument("--steps", type=int, default=6000)
    ap.add_argument("--batch", type=int, default=24, help="(coefficients, residual) rows per step")
    ap.add_argument("--cells", type=int, default=4096, help="cells drawn per row and step")
    ap.add_argument("--width", type=int, default=32, help="the hyponet's hidden width H")
    ap.add_argument("--lr", type=float, default=1e-3)
    ap.add_argument("--mixup", type=float, default=0.5)
    ap.add_argument("--fit-steps", type=int, default=60,
                    help="steps of the coefficients' fit through the correction (0: the projection alone)")
    ap.add_argument("--eval-every", type=int, default=2000, help="steps between checkpoints and scores")
    ap.add_argument("--resolution", type=int, default=64)
    ap.add_argument("--no-full", action="store_true")
    ap.add_argument("--render", action="store_true", help="score renders (PSNR, Delta E) as the bench does, not screens")
    ap.add_argument("--every", type=int, default=1, help="score every n-th material of each set")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--resume", action="store_true")
    ap.add_argument("-o", "--output", required=True)
    a = ap.parse_args(argv)
    from brdfkit.basis import fit_basis, load_basis, save_basis
    from brdfkit.geometry import grid_hd
    from brdfkit.runtime import set_torch_threads

    set_torch_threads()
    os.makedirs(a.output, exist_ok=True)
    logf = open(os.path.join(a.output, "log.txt"), "a", encoding="utf-8")

    def log(msg):
        print(msg, flush=True)
        logf.write(msg + "\n")
        logf.flush()

    torch.manual_seed(a.seed)
    whole_basis = load_basis(a.basis)
    part = whole_basis.leading(a.k_max or a.k)
    train_names = _names(a.train_list)
    train_paths = [os.path.join(a.proxies, n + ".binary") for n in train_names]
    full = None
    if not a.no_full and not a.k_max:
        full_path = os.path.join(a.output, f"full-pca-{a.k}.safetensors")
        if not os.path.exists(full_path):
            save_basis(full_path, fit_basis(train_paths, a.k, names=train_names))
        full = load_basis(full_path)
    t = time.perf_counter()
    z, r = training_pairs(part, train_paths, whole=bool(a.k_max))
    log(f"{len(train_paths)} tables, {r.shape[1]} cells, pairs in {time.perf_counter() - t:.0f} s")
    hd = torch.as_tensor(np.ascontiguousarray(grid_hd()[part.cells]))
    net = Residual(2 * a.k_max if a.k_max else a.k, a.width)
    opt = torch.optim.Adam(net.parameters(), lr=a.lr)
    ckpt, step0 = os.path.join(a.output, "checkpoint.pt"), 0
    if a.resume and os.path.exists(ckpt):
        state = torch.load(ckpt, weights_only=True)
        net.load_state_dict(state["net"])
        opt.load_state_dict(state["opt"])
        step0 = int(state["step"])
        log(f"resumed at step {step0}")
    tests = _names(a.test_list)
    t = time.perf_counter()
    comp = torch.as_tensor(part.components) if a.k_max else None
    sig = torch.as_tensor(part.sigma) if a.k_max else None
    for step in train(net, opt, z, r, hd, a, step0, log, comp, sig):
        torch.save({"net": net.state_dict(), "opt": opt.state_dict(), "step": step}, ckpt + ".tmp")
        os.replace(ckpt + ".tmp", ckpt)
        log(f"checkpoint at step {step}, {time.perf_counter() - t:.0f} s")
    net.eval()
    del z, r
    if a.k_max:  # score each size as its own run would, into result-kK.json
        import copy
        for k in a.score_k or [a.k]:
            b = copy.copy(a)
            b.k = k
            if not a.no_full:
                full_path = os.path.join(a.output, f"full-pca-{k}.safetensors")
                if not os.path.exists(full_path):
                    save_basis(full_path, fit_basis(train_paths, k, names=train_names))
                b.full = load_basis(full_path)
            write_result(net, whole_basis.leading(k), getattr(b, "full", None), hd, tests, b, log,
                         f"result-k{k}.json")
        return
    write_result(net, part, full, hd, tests, a, log, "result.json")


def write_result(net, part, full, hd, tests, a, log, name):
    result = {"basis": os.path.basename(a.basis), "k": a.k, "steps": a.steps, "args": {k: v for k, v in vars(a).items()
              if k not in ("proxies", "train_list", "test_list", "output", "basis", "sets", "full")}, "sets": {}}
    sets = [("merl-test", a.proxies, tests)] + [
        (s.split("=")[0], s.split("=")[1], sorted(f[:-7] for f in os.listdir(s.split("=")[1]) if f.endswith(".binary")))
        for s in a.sets]
    for set_name, folder, names in sets:
        recs = score(net, part, full, hd, names[::a.every], folder, a)
        result["sets"][set_name] = {"records": recs, "summary": summarise(recs)}
        for k, v in result["sets"][set_name]["summary"].items():
            log(f"{set_name} {k}: suite {v['suite']:.2f} | " + " ".join(f"{s} {p:.2f}" for s, p in v["scenes"].items()))
    with open(os.path.join(a.output, name + ".tmp"), "w", encoding="utf-8") as f:
        json.dump(result, f, indent=1)
    os.replace(os.path.join(a.output, name + ".tmp"), os.path.join(a.output, name))


if __name__ == "__main__":
    main()
