"""Looking at BRDFs: a self-contained HTML page that renders them live in WebGL2
(``brdfkit view``), and an embedding's decoder as GLSL for an engine (``brdfkit export
--glsl``).

* :mod:`~brdfkit.view.quadrature_data`: the reference scene's quadrature (nodes, shares,
  normalisation table, environment) as the arrays the page's shader integrates over;
* :mod:`~brdfkit.view.textures`: tables as float16 3D textures, and the page's binary
  blobs (base64, gzip where asked);
* :mod:`~brdfkit.view.live`: a basis or residual embedding as what the shader decodes
  (the basis's components, the correction network's weights, each material's numbers);
* :mod:`~brdfkit.view.inputs`: the inputs of a page, read (tables, embeddings, sample
  files);
* :mod:`~brdfkit.view.page`: the page, assembled from the package's assets
  (``brdfkit/view/assets``: HTML, JavaScript, GLSL);
* :mod:`~brdfkit.view.export`: ``brdfkit export --glsl``;
* :mod:`~brdfkit.view.browser`: a page opened in headless Chromium and its screenshot
  (the tests' and the docs' measurements).

May import: everything below it (render, io, the basis, the residual, the embeddings,
:mod:`brdfkit.files`); nothing here imports torch at module level.
"""
