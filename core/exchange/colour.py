"""The project's colour map in an export: the file, where engines sample it, and its gain.

The renderer multiplies every texel by the map's per-channel gain ``value / 128``,
the map bilinear at ``(X + 0.5) / s - 0.5`` map pixels for texel ``X``. Unity and
Unreal get ``colour_map.png`` and the affine UV transform to sample it
(:func:`unity_colour_st`, :func:`vertex_colour_uv`); Terrain3D one pixel per vertex
(:func:`gain_at_pixels`); GIS has it baked in. Engines decode sRGB, so shaders scale
the decoded map by :func:`linear_gain` (1 at neutral 128, ``docs/engines.md``).
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
from skimage.color import rgb2xyz
from terratheme.core.exchange.layout import ExportLayout, TilePiece, nearest_texels
from terratheme.core.exchange.weights import BAND_PIXELS, check_window
from terratheme.core.io.images import write_image
from terratheme.core.model.colour_map import NEUTRAL, ColourMap
from terratheme.core.model.project import ThematicTexture
from terratheme.core.render.colour_map import axis_weights

COLOUR_MAP = "colour_map.png"


@functools.cache
def linear_gain() -> float:
    """``1 / srgb_to_linear(128 / 255)``: the factor that makes a decoded neutral 128 exactly 1."""
    grey = np.full((1, 1, 3), NEUTRAL / 255.0)
    # A grey's CIE Y is its linear value (the sRGB matrix's Y row sums to 1).
    return float(1.0 / rgb2xyz(grey)[0, 0, 1])


def colour_manifest(project: ThematicTexture, file: str | None) -> dict | None:
    """The manifest's ``colour_map`` entry (None when the project has no colour map)."""
    cmap = project.colour_map
    if cmap is None:
        return None
    mh, mw = cmap.pixels.shape[:2]
    return {"file": file, "size": [mw, mh], "scale": cmap.scale, "neutral": NEUTRAL,
            "gain": "value / 128 per channel, over the blended themes",
            "linear_gain": linear_gain()}


def write_colour_map(path: Path, colour_map: ColourMap) -> None:
    """The project's colour map pixels as an RGB8 PNG (what the project renders with)."""
    write_image(path, colour_map.pixels)


def _texel_axis(layout_pixels: int, texels: int, start: int, tile_pixels: int,
                scale: int, map_pixels: int) -> tuple[float, float]:
    """``(a, b)`` with map texture coordinate ``a * t + b`` at ``t`` in 0..1 across a tile:
    ``(X + 0.5) / (s * mw)`` at ``X = (start + t * (tile_pixels - 1)) * texels /
    (layout_pixels - 1)``."""
    per_pixel = texels / (layout_pixels - 1)
    span = scale * map_pixels
    return (tile_pixels - 1) * per_pixel / span, (start * per_pixel + 0.5) / span


def unity_colour_st(project: ThematicTexture, layout: ExportLayout, piece: TilePiece
                    ) -> list[float]:
    """Unity's ``_ST`` (``[scale u, scale v, offset u, offset v]``) of a tile's colour-map lookup.

    Texture UV = terrain UV * scale + offset; both ``v`` run up from the south / bottom.
    """
    cmap = project.colour_map
    mh, mw = cmap.pixels.shape[:2]
    wtex, htex = project.grid.texture_size
    au, bu = _texel_axis(layout.size[0], wtex, piece.x, piece.w, cmap.scale, mw)
    # Rows: image row coordinate from the top at terrain v is that of pixel row y + (1 - v)(T - 1).
    av, bv = _texel_axis(layout.size[1], htex, piece.y, piece.h, cmap.scale, mh)
    return [au, av, bu, 1.0 - (av + bv)]


def vertex_colour_uv(project: ThematicTexture, layout: ExportLayout) -> dict:
    """Texture UV = vertex coordinate * ``uv_per_vertex`` + ``uv_offset`` (rows from the top),
    vertices counted from the north-west (Unreal's ``LandscapeLayerCoords``, scale 1)."""
    cmap = project.colour_map
    mh, mw = cmap.pixels.shape[:2]
    wtex, htex = project.grid.texture_size
    (w, h), s = layout.size, cmap.scale
    au, bu = _texel_axis(w, wtex, 0, 2, s, mw)
    av, bv = _texel_axis(h, htex, 0, 2, s, mh)
    return {"uv_per_vertex": [au, av], "uv_offset": [bu, bv]}


def gain_at_pixels(colour_map: ColourMap, texture_size: tuple[int, int], size: tuple[int, int],
                   window: tuple[int, int, int, int] | None = None) -> np.ndarray:
    """The renderer's gain at the texel nearest every pixel of a ``size = (W, H)`` map.

    Returns (h, w, 3) uint8 ``round(128 * gain)`` over ``window`` (default: all):
    what the renderer makes of a texel of value 128 there.
    """
    x, y, w, h = check_window(window, size)
    wtex, htex = texture_size
    s = colour_map.scale
    mh, mw = colour_map.pixels.shape[:2]
    pixels = colour_map.pixels.astype(np.int64)
    # Map pixels and integer weights of every texel (0 .. Wtex), then of each pixel's nearest.
    xi0, xi1, xw0, xw1 = (a[nearest_texels(size[0], wtex, x, w)]
                          for a in axis_weights(0, wtex + 1, s, mw))
    yi0, yi1, yw0, yw1 = (a[nearest_texels(size[1], htex, y, h)]
                          for a in axis_weights(0, htex + 1, s, mh))
    denom = NEUTRAL * (2 * s) ** 2
    out = np.empty((h, w, 3), np.uint8)
    rows = max(1, BAND_PIXELS // w)
    for r0 in range(0, h, rows):
        r1 = min(h, r0 + rows)
        a, b = yi0[r0:r1, None], yi1[r0:r1, None]
        wa, wb = yw0[r0:r1, None, None], yw1[r0:r1, None, None]
        # The renderer's integer bilinear sum G, applied to a texel of value 128.
        g = (wa * (xw0[None, :, None] * pixels[a, xi0[None, :]]
                   + xw1[None, :, None] * pixels[a, xi1[None, :]])
             + wb * (xw0[None, :, None] * pixels[b, xi0[None, :]]
                     + xw1[None, :, None] * pixels[b, xi1[None, :]]))
        out[r0:r1] = np.minimum((NEUTRAL * g + denom // 2) // denom, 255)
    return out
