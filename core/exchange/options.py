"""What an export is asked for: the target engine or format, the map size and the tiling."""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

from terratheme.core.render.rules import SaddleRule


class Engine(Enum):
    """Where an export goes (``docs/engines.md`` says how to import each)."""

    #: RGBA8 splatmaps (4 themes per image), theme PNGs, terrain-layer JSON, an editor script
    UNITY = "unity"
    #: one 8-bit weight map per theme at a recommended landscape size, a flat heightmap
    UNREAL = "unreal"
    #: a Terrain3D control map (base/overlay ids and blend per vertex) and a texture list
    GODOT = "godot"
    #: the land-class map with a colour table and the baked texture as a COG-layout GeoTIFF
    GEOTIFF = "geotiff"


class WeightStyle(Enum):
    """Which blend an export's weights follow (``docs/engines.md``)."""

    #: the project's own render style (``core.render.project.project_style``): its shaped
    #: borders when it has them, else the paper's rule
    PROJECT = "project"
    #: the paper's barycentric weights, whatever the project's style
    LINEAR = "linear"


@dataclass(frozen=True)
class ExportOptions:
    """Options of an export: ``size`` (W, H) of the whole map (None: the engine's default),
    ``tile`` pieces sharing their border pixels (None: one), ``style`` the project's or the
    paper's linear weights.
    """

    engine: Engine = Engine.UNITY
    size: tuple[int, int] | None = None
    tile: int | None = None
    saddle: SaddleRule = SaddleRule.MINORITY
    style: WeightStyle = WeightStyle.PROJECT
