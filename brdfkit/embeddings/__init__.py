"""Embeddings: a material as a few numbers of one *kind*, decoded by one part of a model.

An embedding (:class:`brdfkit.io.embedding.Embedding`) is a material as ``size`` numbers
of one kind, decoded by one file, its *decoder*, which it names by digest:

============ ================================================= =========================
kind         what the numbers are                              decoder (model part)
============ ================================================= =========================
``residual`` coefficients of a PCA basis's leading components  a basis-residual file
             plus the weight of a hypernetwork's correction,   (:mod:`brdfkit.residual`)
             ``3 K`` numbers, chosen per material
``basis``    coefficients of a PCA basis's leading components, a basis file
             ``3 K`` numbers, refined on renders               (:mod:`brdfkit.basis`)
``hypernet`` a hypernetwork's latent (Gokbudak et al. 2024),   a hypernetwork file
             refined on renders (``latent`` before)            (:mod:`brdfkit.hypernet`)
============ ================================================= =========================

With no kind asked for, ``encode`` takes the first of these (:data:`KINDS`' order) whose
part a built-in ships and whose decoder offers the size asked for: a residual embedding
with the 40-D built-ins (``merl-rgl-l40``, the default, and ``merl80-l40``) at the sizes
their residuals offer, a basis embedding with them at the other sizes, a latent with
``merl-rgl-l7``; a model file gives the kind of the part it is.

Each kind is one :class:`EmbeddingKind` in :data:`KINDS`, registered by name as
:data:`brdfkit.methods.METHODS` registers the reconstruction methods; each names the part
of a model that decodes it in the part registry :data:`brdfkit.models.parts.PARTS`.
Modules:

* :mod:`~brdfkit.embeddings.kind`: :class:`EmbeddingKind` (and :class:`~brdfkit.embeddings.kind.Offer`,
  what a decoder file offers, read from its header);
* :mod:`~brdfkit.embeddings.registry`: :data:`KINDS`, one module per kind beside it;
* :mod:`~brdfkit.embeddings.decoders`: the decoder ``encode`` uses (the kind and file that
  what the model serves gives, :mod:`brdfkit.methods.service`) and the one an embedding
  needs;
* :mod:`~brdfkit.embeddings.blend`: two embeddings blended (``brdfkit interpolate``).

May import: the ground floor, :mod:`brdfkit.geometry`, :mod:`brdfkit.io`,
:mod:`brdfkit.models`, :mod:`brdfkit.render` and the packages of the parts
(:mod:`brdfkit.basis`, :mod:`brdfkit.hypernet`, :mod:`brdfkit.prior`,
:mod:`brdfkit.residual`), each inside the functions of the kind that needs it; and
:mod:`brdfkit.methods.service` (the same layer), inside :mod:`~brdfkit.embeddings.decoders`'
functions.
"""

from __future__ import annotations

from brdfkit.embeddings.blend import interpolate
from brdfkit.embeddings.decoders import Decoder, choose_decoder, decoder_for, encode_with, load_decoder, open_embedding
from brdfkit.embeddings.kind import EmbeddingKind
from brdfkit.embeddings.registry import KINDS, get_kind, kind_of_part

__all__ = ["EmbeddingKind", "KINDS", "get_kind", "kind_of_part", "Decoder", "load_decoder", "choose_decoder",
           "decoder_for", "open_embedding", "encode_with", "interpolate"]
