"""Editing an index grid by hand: the undo model, the tools, the live preview, fidelity.

Modules: ``session`` (EditSession: undo atoms, strokes, change events),
``tools`` (brush, rectangle, flood fill, eyedropper as vertex selections),
``preview`` (a render kept current by re-rendering dirty cells), ``fidelity``
(per-cell colour difference between render and photo).
"""

from core.edit.fidelity import fidelity_map, heat_colours
from core.edit.preview import RenderPreview
from core.edit.session import EditAtom, EditSession, GridChange
from core.edit.tools import (
    Connectivity,
    VertexSelection,
    capsule_footprint,
    eyedropper,
    flood_footprint,
    rect_footprint,
)

__all__ = [
    "Connectivity",
    "EditAtom",
    "EditSession",
    "GridChange",
    "RenderPreview",
    "VertexSelection",
    "capsule_footprint",
    "eyedropper",
    "fidelity_map",
    "flood_footprint",
    "heat_colours",
    "rect_footprint",
]
