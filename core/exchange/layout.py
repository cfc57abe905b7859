"""Where an export's pixels lie: on the grid, in tiles, and in the world.

A map of ``W x H`` pixels spans the grid corner to corner (the engines' convention,
``docs/engines.md``): pixel ``i`` sits at texel position ``i * Wtex / (W - 1)``, so a
map of ``Wtex + 1`` pixels holds exactly the renderer's texels plus the far edge.
Tiles of ``T`` pixels share their border row and column (tile ``t`` starts at pixel
``t * (T - 1)``), as Unity terrains and Unreal landscape tiles do.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass

import numpy as np
from terratheme.core.errors import OptionError, TerrathemeError
from terratheme.core.io.georef import world_file_lines

#: most pixels one weight or control map may hold (bounded work per export)
MAX_MAP_PIXELS = 1 << 28
_MODEL_TYPE_KEY = 1024
_LINEAR_UNITS_KEY = 3076
#: EPSG linear units -> (name, metres per unit)
_UNITS = {9001: ("metre", 1.0), 9002: ("foot", 0.3048), 9003: ("US survey foot", 1200 / 3937)}
_METRES_PER_DEGREE = 111_319.49


@dataclass(frozen=True)
class TilePiece:
    """One tile of an export map: tile column/row and its pixel window in the whole map."""

    tx: int
    ty: int
    x: int
    y: int
    w: int
    h: int

    @property
    def suffix(self) -> str:
        """``_x{tx}_y{ty}``: the tile naming Unreal's tiled landscape import reads."""
        return f"_x{self.tx}_y{self.ty}"


@dataclass(frozen=True)
class ExportLayout:
    """A whole export map of ``size = (W, H)`` pixels, cut into tiles of ``tile`` pixels or not
    (then ``W - 1`` and ``H - 1`` are multiples of ``tile - 1``)."""

    size: tuple[int, int]
    tile: int | None = None

    def __post_init__(self) -> None:
        w, h = self.size
        if w < 2 or h < 2:
            raise TerrathemeError(f"an export map needs at least 2 x 2 pixels, got {w} x {h}")
        if w * h > MAX_MAP_PIXELS:
            raise OptionError(
                f"an export map of {w} x {h} pixels is larger than {MAX_MAP_PIXELS:,} pixels; "
                "use {tile} or a smaller {size}"
            )
        if self.tile is not None:
            t = self.tile
            if t < 2:
                raise TerrathemeError(f"tile must be at least 2 pixels, got {t}")
            if (w - 1) % (t - 1) or (h - 1) % (t - 1):
                raise TerrathemeError(
                    f"a {w} x {h} map does not cut into {t}-pixel tiles sharing their borders: "
                    f"width and height must be k * {t - 1} + 1 (e.g. {tiled_length(w, t)})"
                )

    @property
    def tiles(self) -> tuple[int, int]:
        """``(kx, ky)``: tile columns and rows (1 x 1 untiled)."""
        if self.tile is None:
            return 1, 1
        return (self.size[0] - 1) // (self.tile - 1), (self.size[1] - 1) // (self.tile - 1)

    def pieces(self) -> list[TilePiece]:
        """Every tile, row by row from the top (north) row, left to right."""
        if self.tile is None:
            return [TilePiece(0, 0, 0, 0, *self.size)]
        kx, ky = self.tiles
        step = self.tile - 1
        return [TilePiece(tx, ty, tx * step, ty * step, self.tile, self.tile)
                for ty in range(ky) for tx in range(kx)]


def tiled_length(length: int, tile: int) -> int:
    """The smallest ``k * (tile - 1) + 1 >= length``: a length cut into shared-border tiles."""
    k = max(1, -(-(length - 1) // (tile - 1)))
    return k * (tile - 1) + 1


def tiled_layout(texture_size: tuple[int, int], tile: int,
                 size: tuple[int, int] | None = None) -> ExportLayout:
    """A map cut into ``tile``-pixel tiles: ``size`` ``(W, H)`` or, by default, the fewest
    tiles that hold one pixel per texel of a ``(Wtex, Htex)`` texture and its far edge."""
    wtex, htex = texture_size
    return ExportLayout(size or (tiled_length(wtex + 1, tile), tiled_length(htex + 1, tile)),
                        tile)


def nearest_texels(n_pixels: int, n_texels: int, start: int, count: int) -> np.ndarray:
    """Texels (count,) int64 in ``0..n_texels`` nearest pixels ``start..start+count-1``:
    pixel ``i`` lies at ``i * n_texels / (n_pixels - 1)``, rounded half up."""
    den = n_pixels - 1
    i = start + np.arange(count, dtype=np.int64)
    return (2 * i * n_texels + den) // (2 * den)


@dataclass(frozen=True)
class WorldFrame:
    """World units of a project: the size of one texel and where texel (0, 0) lies.

    ``texel_size`` (x east, y south) is in ``units``: ``"metre"`` (feet and degrees
    converted), ``"CRS unit"`` or ``"texel"`` (no georeference); ``origin`` is the CRS
    position of the top-left pixel's centre, in ``crs_units``; ``rotation_deg`` is a
    ModelTransformation's rotation (engines get the map unrotated).
    """

    texel_size: tuple[float, float] = (1.0, 1.0)
    origin: tuple[float, float] = (0.0, 0.0)
    units: str = "texel"
    rotation_deg: float = 0.0
    crs_units: str = "texel"


def world_frame(georeference: dict | None, texture_size: tuple[int, int], *,
                owner: str = "project") -> WorldFrame:
    """The :class:`WorldFrame` of a project's ``metadata["georeference"]`` (``{}`` or None:
    texels); ``texture_size`` gives a geographic CRS's centre latitude. TerrathemeError
    when the texture's corners or size in the world are not finite numbers, a texel
    size is subnormal, or a geographic centre latitude is beyond the poles: an export
    must write real numbers. ``owner`` names the georeference's holder in the message."""
    world = world_file_lines(georeference) if georeference else None
    if world is None:
        return WorldFrame()
    frame = _frame(world, georeference, texture_size, owner)
    w, h = texture_size
    extent = (frame.texel_size[0] * w, frame.texel_size[1] * h)
    # the farthest corner from 0 along each axis (x = A col + B row + C, y = D col + E row + F)
    corner = (abs(world[4]) + abs(world[0] * w) + abs(world[2] * h),
              abs(world[5]) + abs(world[1] * w) + abs(world[3] * h))
    if not all(math.isfinite(v) for v in (*frame.texel_size, *frame.origin, *extent, *corner)) \
            or min(frame.texel_size) < sys.float_info.min:  # subnormal: spacings round to 0
        raise TerrathemeError(f"the {owner}'s georeference {world} places a {w} x {h} texture "
                              "beyond the range of floating-point numbers")
    return frame


def _frame(world: list[float], georeference: dict,
           texture_size: tuple[int, int], owner: str) -> WorldFrame:
    a, d, b, e, c, f = (float(v) for v in world)
    sx, sy = math.hypot(a, d), math.hypot(b, e)
    # Zero-length or parallel pixel axes (a singular frame) place no image.
    if (sx <= 0 or sy <= 0 or not all(math.isfinite(v) for v in world)
            or not abs((a / sx) * (e / sy) - (b / sy) * (d / sx)) > 1e-9):
        raise TerrathemeError(f"the {owner}'s georeference has a degenerate pixel size {world}")
    keys = _geo_keys(georeference)
    rotation = math.degrees(math.atan2(d, a))
    if keys.get(_MODEL_TYPE_KEY) == 2:
        # Geographic CRS: degrees to metres at the centre latitude (spherical approximation).
        centre = f + e * texture_size[1] / 2
        if not abs(centre) <= 90:
            raise TerrathemeError(f"the {owner}'s georeference is geographic but its centre "
                                  f"latitude {centre:.6g} is beyond the poles")
        lat = math.radians(centre)
        scale = (_METRES_PER_DEGREE * math.cos(lat), _METRES_PER_DEGREE)
        return WorldFrame((sx * scale[0], sy * scale[1]), (c, f), "metre", rotation, "degree")
    unit = _UNITS.get(keys.get(_LINEAR_UNITS_KEY, 9001))
    if unit is None:
        return WorldFrame((sx, sy), (c, f), "CRS unit", rotation, "CRS unit")
    # Engines work in metres: CRS feet become metres.
    return WorldFrame((sx * unit[1], sy * unit[1]), (c, f), "metre", rotation, unit[0])


def _geo_keys(georeference: dict) -> dict[int, int]:
    """Short-valued GeoKeys of a GeoKeyDirectory (key -> value)."""
    raw = list(georeference.get("GeoKeyDirectory") or [])
    out = {}
    for i in range(4, len(raw) - 3, 4):
        key, location, _, value = raw[i : i + 4]
        if location == 0:
            out[int(key)] = int(value)
    return out
