"""The thematic texture as data: the index grid, the project (grid + themes + layers) and its file.

Modules: ``grid``, ``project`` (and its ``.ttproj`` file), ``manifest``, ``layers``
(optional per-pixel layers), ``colour_map``, ``map_prediction`` (what the grid predicts
of a colour map), ``index_image`` (grids as pictures).
"""

from terratheme.core.model.colour_map import ColourMap
from terratheme.core.model.grid import IndexGrid
from terratheme.core.model.index_image import project_from_index_image
from terratheme.core.model.project import (
    PROJECT_SUFFIX,
    ThematicTexture,
    check_vertex_count,
    load_project,
    save_project,
)

__all__ = [
    "PROJECT_SUFFIX",
    "ColourMap",
    "IndexGrid",
    "ThematicTexture",
    "check_vertex_count",
    "load_project",
    "project_from_index_image",
    "save_project",
]
