"""Training the hypernetwork (``brdfkit fit``): the step loop and what it needs.

* :mod:`~brdfkit.hypernet.training.loop`: :func:`~brdfkit.hypernet.training.loop.fit`, the
  step loop (single process or ``torchrun``), its log and the network file it writes.
* :mod:`~brdfkit.hypernet.training.options`: :class:`~brdfkit.hypernet.training.options.TrainOptions`,
  their checks with the architecture's, the learning-rate schedule.
* :mod:`~brdfkit.hypernet.training.dataset`: the training tables held compactly, batches
  of contexts and queries drawn on the fly.
* :mod:`~brdfkit.hypernet.training.checkpoint`: resumable state (``<model>.ckpt``).
* :mod:`brdfkit.distributed` (shared with the residual's training): the PyTorch DDP process group and stop
  signals.
* :mod:`~brdfkit.hypernet.training.display`: the run's log lines and progress bar on
  stderr (rank 0).

May import: what :mod:`brdfkit.hypernet` may, and the hypernetwork's own modules.
"""
