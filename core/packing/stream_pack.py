"""``pack_file(path)``: pack an image file of any size with bounded memory.

The image is read in row bands of :data:`BAND_ROWS`, each cut into the curve's aligned
squares of that side; a square is a contiguous stretch of the curve, so each is scanned
alone and the squares' runs in curve order are the layer's. Colour images need a first
pass to gather their at most 256 colours.
"""

from __future__ import annotations

import os

import numpy as np
from terratheme.core.curves.plan import curve_squares
from terratheme.core.curves.scan import join_runs, scan_square
from terratheme.core.errors import TerrathemeError
from terratheme.core.io.images import image_info, read_bands, read_region
from terratheme.core.io.png import palette_indices, png_palette
from terratheme.core.packing.index_png import index_dtype
from terratheme.core.packing.layer import PackedLayer
from terratheme.core.packing.packer import CurveChoice, ProgressFn, TilePalette, tile_from_runs
from terratheme.core.packing.palette import MAX_COLOURS, SUPPORTED_DTYPES, colour_keys
from terratheme.core.packing.tiled import DEFAULT_TILE_BITS, TiledLayer, needs_tiles
from terratheme.core.packing.tiled_format import MAX_TILED_SIDE

#: Rows read at once, and the side of the curve squares scanned alone (log2).
SQUARE_BITS = 9
BAND_ROWS = 1 << SQUARE_BITS


def pack_file(
    path: str | os.PathLike,
    curve: str | CurveChoice = "hilbert",
    *,
    tile_bits: int | None = None,
    progress: ProgressFn | None = None,
) -> PackedLayer | TiledLayer:
    """Pack an image file band by band (the same layer :func:`core.packing.pack` makes).

    ``path``: any image OpenImageIO reads (a palette PNG's indices are packed, its colours
    kept as display colours). ``curve``, ``tile_bits``: as :func:`core.packing.pack`;
    ``progress(bands done, bands)``. Returns a PackedLayer or TiledLayer; raises
    TerrathemeError for an unreadable file, unsupported pixels, too large a side, or more
    than 256 colours.
    """
    p = os.fspath(path)
    choice = CurveChoice.parse(curve)
    info = image_info(p)
    w, h, c = info.width, info.height, info.channels
    dtype = info.dtype
    top = _largest(p, info) if c == 1 and dtype != np.uint8 else 0
    if c == 1 and dtype == np.uint32:
        # An EXR index (unpack writes 32-bit UINT, EXR has no 8- or 16-bit integers).
        dtype = index_dtype(top, p)
    if dtype not in SUPPORTED_DTYPES or not 1 <= c <= 4:
        raise TerrathemeError(f"{p}: {c} channels of {info.dtype} cannot be packed: index "
                              "layers are 1, 3 or 4 channels of uint8 or uint16")
    if w > MAX_TILED_SIDE or h > MAX_TILED_SIDE:
        raise TerrathemeError(f"{p}: {w} x {h} texels exceeds the tiled layer's "
                              f"{MAX_TILED_SIDE} a side")
    colours = png_palette(p)
    identity = colours is not None or (c == 1 and top < MAX_COLOURS)
    palette = TilePalette(identity, c, np.uint8 if colours is not None else dtype)
    tiled = tile_bits is not None or needs_tiles(w, h)
    side = 1 << (DEFAULT_TILE_BITS if tile_bits is None else int(tile_bits)) if tiled else max(w, h)
    rects = [(x, y, min(side, w - x), min(side, h - y))
             for y in range(0, h, side) for x in range(0, w, side)]
    total = sum(-(-th // BAND_ROWS) for _, _, _, th in rects)
    done = [0, total, progress]

    def keys_of(pixels: np.ndarray) -> np.ndarray:
        # Palette PNG: its indices; index image: the values; else packed colours.
        if colours is not None:
            return palette_indices(pixels, colours, p)
        pixels = pixels.astype(dtype, copy=False)
        return pixels[:, :, 0] if identity else colour_keys(pixels)

    tiles = []
    for rect in rects:
        cands = _rect_runs(p, rect, choice, keys_of, done)
        tiles.append(tile_from_runs(rect[2], rect[3], cands, palette))
    # A palette PNG's indices are a 2-D image; other files keep their channel axis
    # (as core.packing.index_png.read_index_image gives them).
    squeeze = colours is not None
    if not tiled:
        # One layer: the tile's runs with the whole image's palette and kind.
        tile = tiles[0]
        return PackedLayer.from_runs(w, h, tile.curve, tile.steps, tile.P, palette.palette,
                                     identity=identity, squeeze=squeeze, colours=colours)
    return TiledLayer.from_tile_bytes(w, h, int(np.log2(side)), [t.to_bytes() for t in tiles],
                                      palette.palette, identity=identity, squeeze=squeeze,
                                      colours=colours)


def _largest(path: str, info) -> int:
    """Largest value of a single-channel file (one pass)."""
    top = 0
    for _, band in read_bands(path, BAND_ROWS):
        top = max(top, int(band.max()))
    return top


def _rect_runs(path: str, rect: tuple[int, int, int, int], choice: CurveChoice, keys_of,
               done: list) -> dict:
    """Runs of keys of one rectangle (a tile or the whole image) along each curve asked for."""
    x0, y0, w, h = rect
    squares = {cv: curve_squares(w, h, cv, SQUARE_BITS) for cv in choice.curves}
    parts: dict = {cv: {} for cv in choice.curves}
    side = 1 << next(iter(squares.values())).g
    # Bands of one square row each, from the top (squares are aligned from the bottom).
    edges = sorted({h} | {max(0, h - side * k) for k in range(1, -(-h // side) + 1)})
    for top, bottom in zip([0, *edges[:-1]], edges, strict=True):
        if bottom <= top:
            continue
        band = keys_of(read_region(path, x0, y0 + top, w, bottom - top))
        for cv, sq in squares.items():
            for k in range(sq.sx.size):
                x, y, sw, sh = sq.rect(k, w, h)
                if y == top:
                    parts[cv][k] = scan_square(band[:, x: x + sw], w, h, cv, sq, k)
        done[0] += 1
        if done[2] is not None:
            done[2](done[0], done[1])
    return {cv: join_runs([parts[cv][k] for k in range(sq.sx.size)])
            for cv, sq in squares.items()}
