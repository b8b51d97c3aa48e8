"""Looking at BRDFs: a self-contained HTML page that renders them live in WebGL2
(``brdfkit view``), and an embedding's decoder as GLSL for an engine (``brdfkit export
--glsl``).

* :mod:`~brdfkit.view.quadrature_data`: the reference scene's quadrature, the renderer's
  own per-node constants and the shader's uniforms;
* :mod:`~brdfkit.view.textures`: tables as float16 3D textures, and the page's binary
  blobs (base64, gzip where asked);
* :mod:`~brdfkit.view.live`: a basis or residual embedding as what the shader decodes,
  every layout of the decoder written once (the basis's slots as textures, each
  channel's coefficients, the mapping's constants, the hyponet's weights);
* :mod:`~brdfkit.view.inputs`: the inputs of a page, read (tables, embeddings, sample
  files);
* :mod:`~brdfkit.view.page`: the page, assembled from the package's assets
  (``brdfkit/view/assets``: HTML, JavaScript, GLSL; each GLSL file names the files it
  requires) and the constants brdfkit defines (colours, display, lobe);
* :mod:`~brdfkit.view.export`: ``brdfkit export --glsl``;
* :mod:`~brdfkit.view.browser`: a page opened in headless Chromium and its screenshot
  (the tests' and the docs' measurements).

May import: everything below it (render, io, the basis, the residual, the embeddings,
:mod:`brdfkit.files`); nothing here imports torch at module level.
"""
