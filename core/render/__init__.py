"""The renderer: an index grid and its themes to the full-resolution texture (design.md §1).

Modules: ``rules`` (splits, weights), ``renderer``, ``kernels`` (numba row loops),
``theme_pack``, ``overview`` (reduced resolution), ``project``, ``inputs`` (shared checks).
"""

from terratheme.core.render.overview import render_overview
from terratheme.core.render.project import render_project
from terratheme.core.render.renderer import BlendMode, RenderOptions, render_cells, render_labels
from terratheme.core.render.rules import SaddleRule, cell_splits, corner_weights

__all__ = [
    "BlendMode",
    "RenderOptions",
    "SaddleRule",
    "cell_splits",
    "corner_weights",
    "render_cells",
    "render_labels",
    "render_overview",
    "render_project",
]
