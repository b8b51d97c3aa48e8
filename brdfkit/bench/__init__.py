"""Error against run time: the sparse-reconstruction and compression benchmark.

What is measured (Gokbudak et al. 2024, Sec. 4, on whatever tables are given)
--------------------------------------------------------------------------------
**Sparse reconstruction.** For every test material, every ``N`` in :data:`DEFAULT_N`,
every seed ``s = 0 .. K-1`` and every sampling of ``BenchConfig.sampling``, ``N``
samples are taken from the material's table by the benchmarks' one protocol
(:class:`brdfkit.acquisition.protocol.SamplingProtocol`, which ``benchmarks/eval_sparse.py`` uses
too: uniform over the Rusinkiewicz angles with the seed derived from ``(s, N, material
name)``, or the table measured at ``brdfkit plan``'s directions seeded by ``s``), so all
methods see the *same* samples, and every
method (by default :func:`default_methods`: the learnt prior of a built-in ``-m``, the
hypernetwork, IPCA, NBRDF) reconstructs a dense table from them. Each reconstruction is
scored:

* ``time_s``: wall time of ``Method.reconstruct`` alone (samples in, dense
  ``(90, 90, 180, 3)`` table out: encode + dense decode for the hypernetwork, ridge fit +
  decode for IPCA, the whole per-material fit + decode for NBRDF); model files are loaded
  once beforehand and each method makes one untimed warm-up reconstruction per process;
* ``log_rmse``: :func:`brdfkit.evaluation.metrics.brdf_log_rmse` against the material's table;
* ``psnr``, ``delta_e``, ``ssim``: :func:`brdfkit.evaluation.metrics.image_metrics` between the
  reference-scene renders (:func:`brdfkit.render.quadrature.render`, the deterministic
  quadrature renderer, at ``resolution`` pixels square, whole image) of the reconstruction
  and of the material's own table. The reference render of a material is made once and
  cached on disk (EXR, keyed by the file's SHA-256 and the scene settings).

**Compression.** For every material of the compression data and every compression model,
the full table is encoded and decoded (:func:`brdfkit.api.encode`, :func:`brdfkit.api.decode`)
and scored the same way (``time_s`` = encode + decode; ``size``, the numbers per
material, ``latent`` in the records of earlier runs); with a PCA basis, its best
reconstruction (:meth:`brdfkit.basis.PcaBasis.project` then ``decode``) too, and the
projection onto its ``K`` leading components for each ``basis-K`` entry (``pca-K`` before).

Every reconstruction is scored by :func:`brdfkit.evaluation.metrics.score`, the function
``brdfkit metrics`` uses, in the scenes of ``BenchConfig.scenes`` (the reference scene, or
the suite of :mod:`brdfkit.render.scene_suite`: then their mean, and each scene's). A failure of one reconstruction (or of reading one material)
is recorded with its message and left out of the means; the run goes on.

Outputs (in ``OUTDIR``)
-----------------------
``bench.json`` (configuration, environment, every record, summaries; rewritten after
every material, so an interrupted run keeps what it finished), ``bench.md`` (tables),
``error_vs_n.png``, ``error_vs_time.png`` (each method one curve through its ``N``
points, log time axis) and ``compression.png``; reference renders in ``cache/``.

Summaries: :mod:`.summary`.

Modules: :mod:`.config` (:class:`BenchConfig`), :mod:`.worker` (one process's models and
scoring), :mod:`.runner` (:func:`run_bench`, :func:`merge_results`), :mod:`.summary`,
:mod:`.report` (``bench.md`` and the plots).

May import: every library package below the CLI (methods, acquisition, render,
evaluation).
"""

from brdfkit.bench.config import DEFAULT_METHODS, DEFAULT_N, DEFAULT_RESOLUTION, METRICS, BenchConfig, default_methods, sample_seed
from brdfkit.bench.report import write_markdown, write_plots
from brdfkit.bench.runner import merge_results, run_bench
from brdfkit.bench.summary import summarise

__all__ = ["BenchConfig", "run_bench", "merge_results", "summarise", "write_markdown", "write_plots",
           "DEFAULT_N", "DEFAULT_METHODS", "DEFAULT_RESOLUTION", "METRICS", "sample_seed", "default_methods"]
