"""The hypernetwork BRDF model of Gokbudak et al. 2024 ("Hypernetworks for Generalizable
BRDF Representation", ECCV): training modules, model files, encoding and decoding.

One module per concept, in the order data flows:

* :mod:`~brdfkit.model.network`: the trainable ``nn.Module``\\ s (set encoder,
  hypernetwork decoder, batched hyponet), :class:`HyperConfig` and the paper's loss.
* :mod:`~brdfkit.model.file`: model files (``.safetensors``): :func:`save_model`,
  :func:`load_model`, :func:`weights_fingerprint`; never unpickles.
* :mod:`~brdfkit.model.storage`: compact storage in model files (the reference table at
  its measured cells, float16, a reference file shared by several models).
* :mod:`~brdfkit.model.builtin`: the built-in pretrained models (``brdfkit/models/``,
  ``$BRDFKIT_BUILTIN_MODELS``): listing, names to files, their fingerprints checked.
* :mod:`~brdfkit.model.loaded`: :class:`NeuralModel`, a loaded model with its reference
  table lookups and a typed cache of what is derived from it.
* :mod:`~brdfkit.model.kernels`: the fused inference kernels (encoder mean, decoder for
  one latent, blocked hyponet), built from the network's public layer lists.
* :mod:`~brdfkit.model.encoding`: :func:`encode_samples`, :func:`encode_table`
  (measurements in, embedding out).
* :mod:`~brdfkit.model.brdf`: :class:`NeuralBRDF`, one material's decoded hyponet
  (``eval_hd``, ``eval_dirs`` for renderers, ``to_table``: the dense decode).

The names are imported lazily: ``import brdfkit.model`` loads no torch.
"""

from __future__ import annotations

import importlib

# public name -> defining module
_NAMES = {
    "HyperConfig": "network",
    "HyperBRDF": "network",
    "hyper_loss": "network",
    "hyponet_forward": "network",
    "hyponet_shapes": "network",
    "IN_FEATURES": "network",
    "OUT_FEATURES": "network",
    "save_model": "file",
    "load_model": "file",
    "weights_fingerprint": "file",
    "state_fingerprint": "file",
    "MODEL_FORMAT": "file",
    "MODEL_VERSION": "file",
    "MODEL_VERSIONS": "file",
    "builtin_models": "builtin",
    "resolve_model": "builtin",
    "load_builtin": "builtin",
    "pack_model": "builtin",
    "NeuralModel": "loaded",
    "ModelCache": "loaded",
    "encode_samples": "encoding",
    "encode_table": "encoding",
    "NeuralBRDF": "brdf",
}

__all__ = sorted(_NAMES)


def __getattr__(name):
    if name in _NAMES:
        value = getattr(importlib.import_module(f"brdfkit.model.{_NAMES[name]}"), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'brdfkit.model' has no attribute {name!r}")


def __dir__():
    return __all__
