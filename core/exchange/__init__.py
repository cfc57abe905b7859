"""Exports that terrain engines and GIS read, and the way back (docs/engines.md).

Weights follow the project's look: by default its render style
(``core.render.project.project_style``), so with shaped boundaries every map
pixel gets the shaped blend's own weights (``shaped``), else, and with
``WeightStyle.LINEAR``, the exact barycentric weight of each theme at its
grid position by the renderer's rule (``weights``); 8-bit weights sum to
exactly 255 per pixel. The project's colour map goes with every export
(``colour``). Modules: ``options`` (Engine, WeightStyle, ExportOptions),
``layout`` (map sizes, shared-border tiles, world units), ``weights``
(barycentric weights at map pixels, quantisation), ``shaped`` (the shaped
blend's weights), ``style`` (which of the two an export follows),
``colour`` (the colour map's file, UV transforms and gain), ``plan`` (the
files of an export, theme textures, manifests), ``unity``, ``unreal``,
``terrain3d`` (Godot), ``geotiff`` (GIS) with ``cog`` (the Cloud Optimized
GeoTIFF layout), ``texture_tiff`` (a render larger than memory as such a
GeoTIFF, band by band: ``terratheme render --tiled``), ``export`` (plan,
then write), ``maps_to_grid`` (the way back: engine maps to a vertex grid),
``carried`` (the way back from an export: the project it carries, exactly).
"""

from terratheme.core.exchange.carried import project_from_export
from terratheme.core.exchange.colour import gain_at_pixels, linear_gain
from terratheme.core.exchange.export import plan_export, write_export
from terratheme.core.exchange.layout import ExportLayout, TilePiece, WorldFrame, world_frame
from terratheme.core.exchange.maps_to_grid import grid_from_labels, labels_from_weights
from terratheme.core.exchange.options import Engine, ExportOptions, WeightStyle
from terratheme.core.exchange.plan import ExportPlan
from terratheme.core.exchange.shaped import shaped_slots
from terratheme.core.exchange.style import export_boundary, map_labels, map_weights
from terratheme.core.exchange.terrain3d import (
    control_labels,
    decode_control,
    encode_control,
    read_control_map,
)
from terratheme.core.exchange.texture_tiff import write_texture_tiff
from terratheme.core.exchange.weights import sample_corners, strongest_two, theme_weights

__all__ = [
    "Engine",
    "ExportLayout",
    "ExportOptions",
    "ExportPlan",
    "TilePiece",
    "WeightStyle",
    "WorldFrame",
    "control_labels",
    "decode_control",
    "encode_control",
    "export_boundary",
    "gain_at_pixels",
    "grid_from_labels",
    "labels_from_weights",
    "linear_gain",
    "map_labels",
    "map_weights",
    "plan_export",
    "project_from_export",
    "read_control_map",
    "sample_corners",
    "shaped_slots",
    "strongest_two",
    "theme_weights",
    "world_frame",
    "write_export",
    "write_texture_tiff",
]
