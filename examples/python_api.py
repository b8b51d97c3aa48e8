"""The brdfkit library API end to end: encode, decode, sparse, interpolate.

Usage::

    python examples/python_api.py MODEL.safetensors

Writes 6 synthetic GGX materials (MERL tables) into a temporary folder, then with the
given model (from ``brdfkit fit`` or ``brdfkit demo``):

1. encodes each table into an embedding and writes it as ``.emb``;
2. decodes one embedding back into a dense table and writes it as a MERL file;
3. reconstructs a dense table from 400 sparse samples;
4. blends two materials' embeddings and evaluates the blend at a few direction pairs.

It prints the BRDF-space error (``brdfkit.evaluation.metrics.brdf_log_rmse``) of each
reconstruction against the original table. With an untrained model the errors are large;
the point is the calls, which are the same for a trained one.
"""

from __future__ import annotations

import os
import sys
import tempfile


def main(argv: list[str]) -> int:
    if len(argv) != 1:
        print("usage: python examples/python_api.py MODEL.safetensors", file=sys.stderr)
        return 2
    import numpy as np
    import torch

    import brdfkit
    from brdfkit.evaluation.metrics import brdf_log_rmse
    from brdfkit.embeddings import decoder_for, open_embedding
    from brdfkit.materials.synthetic import write_library

    # The library leaves torch's thread pool as it is; size it to the idle cores first, as
    # the command line does (on a busy machine torch's default of one thread per core made
    # this script 10x slower: 104-143 s against 10.7 s; docs/notes/performance.md).
    brdfkit.set_torch_threads()

    model = brdfkit.load_model(argv[0])
    print(f"model {argv[0]}: latent {model.cfg.latent_dim}, digest {model.digest[:12]}, "
          f"device {model.device}")

    with tempfile.TemporaryDirectory() as tmp:
        paths = write_library(tmp, 6, seed=7, stiff=False)
        print(f"wrote {len(paths)} synthetic MERL tables into {tmp}")

        # 1. Encode every table from all its measured cells.
        embs = {}
        for path in paths:
            emb = brdfkit.encode(path, model)
            brdfkit.write_embedding(path.replace(".binary", ".emb"), emb)
            embs[os.path.basename(path)] = emb
            print(f"  {emb.source}: {emb.sample_count:,} cells -> {emb.size} numbers "
                  f"({os.path.getsize(path.replace('.binary', '.emb'))} bytes as .emb)")

        # 2. Decode one back into a dense table (NaN below the horizon) and write it.
        name = os.path.basename(paths[0])
        original = brdfkit.read_merl(paths[0])
        emb = brdfkit.read_embedding(paths[0].replace(".binary", ".emb"))
        decoded = brdfkit.decode(emb, model)
        brdfkit.write_merl(os.path.join(tmp, "decoded.binary"), decoded)
        print(f"decode {name}: log-RMSE {brdf_log_rmse(decoded, original):.4f}")

        # 3. Sparse reconstruction from 400 measurements.
        samples = brdfkit.draw_samples(original, 400, seed=0, source=name)
        sparse_table, sparse_emb = brdfkit.sparse(samples, model)
        print(f"sparse {name} from {len(samples)} samples: log-RMSE "
              f"{brdf_log_rmse(sparse_table, original):.4f}")

        # 4. Interpolate two materials and evaluate the blend at a few direction pairs
        #    (a renderable BRDF of either kind of embedding, from the decoder that made it).
        a, b = embs[os.path.basename(paths[1])], embs[os.path.basename(paths[2])]
        decoder = decoder_for(a, argv[0])
        for t in (0.0, 0.3, 1.0):
            mix = brdfkit.interpolate(a, b, t)
            brdf = open_embedding(mix, decoder)
            wi = torch.tensor([[0.0, 0.0, 1.0], [0.6, 0.0, 0.8]])
            wo = torch.tensor([[0.0, 0.0, 1.0], [-0.6, 0.0, 0.8]])
            values = brdf.eval_dirs(wi, wo).cpu().numpy()
            print(f"interpolate t={t:.1f}: BRDF at normal incidence {np.round(values[0], 4)}, "
                  f"at 37 degrees mirror {np.round(values[1], 4)} 1/sr")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
