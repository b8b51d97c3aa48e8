"""The hypernetwork BRDF model of Gokbudak et al. 2024 ("Hypernetworks for Generalizable
BRDF Representation", ECCV): its network, files, training and fitting, in one folder.

One module per concept, in the order data flows:

* :mod:`~brdfkit.hypernet.mapping`: the log-relative mapping of BRDF values against a
  per-cell reference table (the paper's pre-processing), reference tables.
* :mod:`~brdfkit.hypernet.network`: the trainable ``nn.Module``\\ s (set encoder,
  hypernetwork decoder, batched hyponet), :class:`HyperConfig` and the paper's loss.
* :mod:`~brdfkit.hypernet.network_file`: network files (``.safetensors``):
  :func:`save_network`, :func:`load_network`, :func:`weights_digest`; never unpickles.
* :mod:`~brdfkit.hypernet.network_storage`: compact storage in network files (the
  reference table at its measured cells, float16, a reference file shared by several
  networks).
* :mod:`~brdfkit.hypernet.packing`: a trained network packed for shipping as part of a
  built-in model (:mod:`brdfkit.models`), its bundle's manifest entry.
* :mod:`~brdfkit.hypernet.loaded`: :class:`LoadedNetwork`, a loaded network with its
  reference table lookups and a typed cache of what is derived from it.
* :mod:`~brdfkit.hypernet.kernels`: the fused inference kernels (encoder mean, decoder for
  one latent, blocked hyponet), built from the network's public layer lists.
* :mod:`~brdfkit.hypernet.encoding`: :func:`encode_samples`, :func:`encode_table`
  (measurements in, embedding out: the set encoder's pass).
* :mod:`~brdfkit.hypernet.neural_brdf`: :class:`NeuralBRDF`, one material's decoded
  hyponet (``eval_hd``, ``eval_dirs`` for renderers, ``to_table``: the dense decode).
* :mod:`~brdfkit.hypernet.refine_on_samples`: a sparse material's latent (and hyponet)
  refined on its own samples (``brdfkit sparse --method hypernet``).
* :mod:`~brdfkit.hypernet.refine_on_screen`: a dense table's latent refined on the
  render-aligned error (what ``brdfkit encode`` runs).
* :mod:`~brdfkit.hypernet.tuning`: ``brdfkit tune``, the auto-decoder stage on renders;
  :mod:`~brdfkit.hypernet.ratio_floor`, its loss on the decoded / true ratio.
* :mod:`~brdfkit.hypernet.training`: ``brdfkit fit``: the step loop, its options, the
  training data, checkpoints and DDP.

May import: the ground floor (``errors``, ``atomic``, ``console``, ``runtime``),
:mod:`brdfkit.geometry`, :mod:`brdfkit.io`, :mod:`brdfkit.models` and, for the
render-aligned error of the refinement and tuning, :mod:`brdfkit.render.screen`.
The names are imported lazily: ``import brdfkit.hypernet`` loads no torch.
"""

from __future__ import annotations

from brdfkit import lazy_attributes

# public name -> defining module
_NAMES = {
    **dict.fromkeys(("HyperConfig", "HyperBRDF", "hyper_loss", "hyponet_forward", "hyponet_shapes",
                     "IN_FEATURES", "OUT_FEATURES"), "brdfkit.hypernet.network"),
    **dict.fromkeys(("save_network", "load_network", "weights_digest", "state_digest", "MODEL_FORMAT",
                     "MODEL_VERSION", "MODEL_VERSIONS"), "brdfkit.hypernet.network_file"),
    **dict.fromkeys(("load_builtin", "pack_network", "manifest_entry"), "brdfkit.hypernet.packing"),
    **dict.fromkeys(("LoadedNetwork", "NeuralModel", "ModelCache"), "brdfkit.hypernet.loaded"),
    **dict.fromkeys(("encode_samples", "encode_table"), "brdfkit.hypernet.encoding"),
    "NeuralBRDF": "brdfkit.hypernet.neural_brdf",
}

__all__ = sorted(_NAMES)

__getattr__, __dir__ = lazy_attributes(__name__, _NAMES)
