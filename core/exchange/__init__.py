"""Exports that terrain engines and GIS read, and the way back (docs/engines.md).

Weights follow the project's render style (shaped borders when it has them, else the
renderer's barycentric weights), 8-bit weights summing to exactly 255 per pixel; the
colour map goes with every export. ``maps_to_grid`` and ``carried`` are the way back.
"""

from terratheme.core.exchange.carried import project_from_export
from terratheme.core.exchange.colour import gain_at_pixels, linear_gain
from terratheme.core.exchange.export import plan_export, write_export
from terratheme.core.exchange.layout import ExportLayout, TilePiece, WorldFrame, world_frame
from terratheme.core.exchange.maps_to_grid import labels_from_weights
from terratheme.core.exchange.options import Engine, ExportOptions, WeightStyle
from terratheme.core.exchange.plan import ExportPlan
from terratheme.core.exchange.shaped import shaped_slots
from terratheme.core.exchange.style import export_boundary, map_labels, map_weights
from terratheme.core.exchange.terrain3d import (
    control_labels,
    decode_control,
    encode_control,
)
from terratheme.core.exchange.texture_tiff import write_texture_tiff
from terratheme.core.exchange.weights import sample_corners, strongest_two

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
    "labels_from_weights",
    "linear_gain",
    "map_labels",
    "map_weights",
    "plan_export",
    "project_from_export",
    "sample_corners",
    "shaped_slots",
    "strongest_two",
    "world_frame",
    "write_export",
    "write_texture_tiff",
]
