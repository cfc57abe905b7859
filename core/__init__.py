"""terratheme core library: thematic terrain textures without Qt, argparse or printing.

One package per part, lowest first (a package imports only those above it):

* ``core.errors`` -- the exceptions every part raises for bad input;
* ``core.io`` -- image files, tiles of large images, free memory, georeference, atomic writes;
* ``core.curves`` -- Hilbert and Morton space-filling curves;
* ``core.themes`` -- tileable theme textures: the library, making and scoring them;
* ``core.model`` -- the index grid and the project (its file format);
* ``core.render`` -- the diagonal-split renderer, full resolution and overviews;
* ``core.classify`` -- orthophoto classification (k-means, Extra-Trees);
* ``core.convert`` -- orthophoto to thematic texture;
* ``core.edit`` -- the edit model behind the editor;
* ``core.packing`` -- index layers packed along a curve;
* ``core.perspective`` -- the low-angle preview and its anisotropic filters;
* ``core.fidelity`` -- how much a texture looks like its photo, and what it costs;
* ``core.exchange`` -- exports for terrain engines and GIS, and the way back.

The design notes, with the papers' equations, are in ``docs/design.md``.
"""

__version__ = "0.1.0"
