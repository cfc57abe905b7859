"""Exports that terrain engines and GIS read, and the way back (docs/engines.md).

Weights come from the renderer's rule (``core.render.rules``): every map
pixel gets the exact barycentric weight of each theme at its grid position
(``weights``), 8-bit weights summing to exactly 255 per pixel. Modules:
``options`` (Engine, ExportOptions), ``layout`` (map sizes, shared-border
tiles, world units), ``weights`` (theme weights at map pixels), ``plan``
(the files of an export, theme textures, manifests), ``unity``, ``unreal``,
``terrain3d`` (Godot), ``geotiff`` (GIS) with ``cog`` (the Cloud Optimized
GeoTIFF layout), ``export`` (plan, then write), ``maps_to_grid`` (the way
back: engine maps to a vertex grid).
"""

from core.exchange.export import plan_export, write_export
from core.exchange.layout import ExportLayout, TilePiece, WorldFrame, world_frame
from core.exchange.maps_to_grid import grid_from_labels, labels_from_weights
from core.exchange.options import Engine, ExportOptions
from core.exchange.plan import ExportPlan
from core.exchange.terrain3d import (
    control_labels,
    decode_control,
    encode_control,
    read_control_map,
)
from core.exchange.unity import read_splatmaps
from core.exchange.unreal import read_weight_maps
from core.exchange.weights import sample_corners, strongest_two, theme_weights

__all__ = [
    "Engine",
    "ExportLayout",
    "ExportOptions",
    "ExportPlan",
    "TilePiece",
    "WorldFrame",
    "control_labels",
    "decode_control",
    "encode_control",
    "grid_from_labels",
    "labels_from_weights",
    "plan_export",
    "read_control_map",
    "read_splatmaps",
    "read_weight_maps",
    "sample_corners",
    "strongest_two",
    "theme_weights",
    "world_frame",
    "write_export",
]
