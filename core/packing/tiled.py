"""Packed layers beyond 65536 x 65536: a grid of packed tiles behind the PackedLayer API.

Tiles are packed layers of indices into the whole layer's palette (file layout:
:mod:`.tiled_format`), decoded when first needed. Random access reads one ``uint32`` table:
the joined table (:mod:`.joined`), or the tiles' tables end to end (:mod:`.batch`).
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np
from terratheme.core.curves.fill import fill_window
from terratheme.core.curves.square import MAX_SIDE
from terratheme.core.errors import CorruptFileError, TerrathemeError
from terratheme.core.io.atomic import write_bytes_atomic
from terratheme.core.io.inputs import check_input_file
from terratheme.core.packing import tiled_format as fmt
from terratheme.core.packing.batch import lookup_batch, tiled_words
from terratheme.core.packing.container import HEADER as LAYER_HEADER
from terratheme.core.packing.container import (
    LayerHeader,
    ValueFormat,
    read_colours,
    read_header,
    read_palette,
)
from terratheme.core.packing.joined import join_tables
from terratheme.core.packing.layer import PARALLEL_FROM, PackedLayer
from terratheme.core.packing.layout import grid_bits
from terratheme.core.packing.lookup import scalar_lookup_function, table_runs
from terratheme.core.packing.palette import check_colours, palette_values, scalar_values
from terratheme.core.packing.scalar import QUICK_MIN_BITS, tiled_quick_cells

#: Tile side used when none is asked for: the largest a packed layer has.
DEFAULT_TILE_BITS = 16


@dataclass(frozen=True, eq=False)
class TiledLayer:
    """A layer as a grid of packed tiles of ``2^tile_bits`` texels a side.

    ``palette`` (K, C) is the whole layer's (tiles hold indices into it); ``identity``,
    ``squeeze``, ``colours`` and ``threads`` as for :class:`PackedLayer`. ``join``: look
    texels up through one joined table (:mod:`.joined`) when the tiles allow it (same answers).
    """

    width: int
    height: int
    tile_bits: int
    palette: np.ndarray
    identity: bool
    squeeze: bool
    colours: np.ndarray | None
    _name: str = field(repr=False)
    _source: object = field(repr=False)  # the file's bytes or its path
    _offsets: np.ndarray = field(repr=False)
    _lengths: np.ndarray = field(repr=False)
    _cache: dict = field(repr=False, default_factory=dict)
    threads: int = 2
    join: bool = True

    # ------------------------------------------------------------ construction

    @classmethod
    def from_tile_bytes(cls, width: int, height: int, tile_bits: int, tiles: list[bytes],
                        palette: np.ndarray, *, identity: bool, squeeze: bool,
                        colours: np.ndarray | None = None) -> TiledLayer:
        """A tiled layer from its tiles' files (rows from the top-left): packed index layers
        ``2^tile_bits`` a side except in the last column and row, checked when first decoded."""
        # A palette PNG's table lists more colours than the image uses: keep the palette's K.
        colours = check_colours(colours, len(palette), identity)
        head = _header(width, height, tile_bits, palette, identity, squeeze, colours)
        if len(tiles) != head.tiles:
            raise TerrathemeError(f"{len(tiles)} tiles for a {head.tiles_x} x {head.tiles_y} grid")
        data = fmt.encode_head(head, np.asarray(palette), colours, [len(b) for b in tiles])
        return cls.from_bytes(data + b"".join(tiles))

    @classmethod
    def load(cls, path: str | os.PathLike) -> TiledLayer:
        """Open a container file: its header and index are read and checked, tiles later."""
        p = os.fspath(check_input_file(path, "a packed layer"))
        size = os.path.getsize(p)
        with open(p, "rb") as fh:
            head = fmt.read_tiled_header(fh.read(fmt.HEADER.size), name=p, file_bytes=size)
            fh.seek(0)
            prefix = fh.read(head.tiles_at)
        return cls._open(prefix, head, p, p)

    @classmethod
    def from_bytes(cls, data: bytes, *, name: str = "<bytes>") -> TiledLayer:
        """Parse a container held in memory."""
        head = fmt.read_tiled_header(data, name=name, file_bytes=len(data))
        return cls._open(data, head, name, bytes(data))

    @classmethod
    def _open(cls, prefix: bytes, head: fmt.TiledHeader, name: str, source: object
              ) -> TiledLayer:
        offsets, lengths = fmt.read_index(prefix, head, name=name)
        v = head.values
        palette = read_palette(prefix, v, at=fmt.HEADER.size)
        palette.setflags(write=False)
        return cls(head.width, head.height, head.tile_bits, palette, v.identity, v.squeeze,
                   read_colours(prefix, v, at=fmt.HEADER.size), name, source, offsets, lengths)

    # ------------------------------------------------------------ the grid

    @property
    def tile_side(self) -> int:
        """Texels along a tile's side."""
        return 1 << self.tile_bits

    @property
    def tiles_x(self) -> int:
        """Tiles across."""
        return fmt.tiles_along(self.width, self.tile_bits)

    @property
    def tiles_y(self) -> int:
        """Tiles down."""
        return fmt.tiles_along(self.height, self.tile_bits)

    @property
    def channels(self) -> int:
        """Colour channels of a texel."""
        return int(self.palette.shape[1])

    def tile_rect(self, i: int) -> tuple[int, int, int, int]:
        """``(x, y, w, h)`` of tile ``i`` (rows from the top-left), row 0 = top."""
        ty, tx = divmod(int(i), self.tiles_x)
        x, y = tx * self.tile_side, ty * self.tile_side
        return x, y, min(self.tile_side, self.width - x), min(self.tile_side, self.height - y)

    def _blob(self, i: int, size: int | None = None) -> bytes:
        off, n = int(self._offsets[i]), int(self._lengths[i]) if size is None else size
        if isinstance(self._source, bytes):
            return self._source[off: off + n]
        with open(self._source, "rb") as fh:
            fh.seek(off)
            return fh.read(n)

    def tile_header(self, i: int) -> LayerHeader:
        """The packed-layer header of tile ``i`` (read without decoding the tile)."""
        return read_header(self._blob(i, LAYER_HEADER.size + 4), name=self._tile_name(i))

    def _tile_name(self, i: int) -> str:
        ty, tx = divmod(int(i), self.tiles_x)
        return f"{self._name} tile ({tx}, {ty})"

    def _decode(self, i: int) -> PackedLayer:
        name = self._tile_name(i)
        tile = PackedLayer.from_bytes(self._blob(i), name=name)
        _, _, w, h = self.tile_rect(i)
        if (tile.width, tile.height) != (w, h) or not tile.identity:
            raise CorruptFileError(f"{name}: a {tile.width} x {tile.height} "
                                   f"{'index' if tile.identity else 'colour'} layer where a "
                                   f"{w} x {h} index tile belongs")
        if len(tile.palette) > len(self.palette):
            raise CorruptFileError(f"{name}: palette index {len(tile.palette) - 1} out of range "
                                   f"(the layer's palette has {len(self.palette)})")
        return dataclasses.replace(tile, threads=self.threads)

    def tile(self, i: int) -> PackedLayer:
        """Tile ``i`` (rows from the top-left) as a packed layer of palette indices."""
        if not 0 <= int(i) < len(self._lengths):
            raise TerrathemeError(f"tile {i} of {len(self._lengths)}")
        if ("tiles", False) in self._cache:
            return self._cache["tiles", False][int(i)]
        return self._decode(int(i))

    @property
    def run_count(self) -> int:
        """Runs of all tiles (from the tiles' headers)."""
        return sum(self.tile_header(i).runs for i in range(len(self._lengths)))

    @property
    def memory_bytes(self) -> int:
        """Bytes of the random-access tables of all tiles (decodes them)."""
        return int(self._tables()[0].nbytes)

    # ------------------------------------------------------------ reading texels

    def _tables(self) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray] | None]:
        """The table the kernels read, built once: the joined table (and None), or all
        tiles' tables end to end and the tile words the kernels read (:mod:`.batch`)."""
        key = ("tables", self.join)
        if key not in self._cache:
            decoded = [self._decode(i) for i in range(len(self._lengths))]
            # One grid block side for all tiles, the whole layer's: the kernels' walks and
            # searches then have the same length whichever tile a texel falls in.
            levels = (max(self.width, self.height) - 1).bit_length()
            bits = grid_bits(levels, self.width, self.height, sum(t.run_count for t in decoded))
            decoded = [t.with_grid_bits(bits) for t in decoded]
            joined = join_tables([t.table for t in decoded], self.width, self.height,
                                 self.tile_bits, self.tiles_x) if self.join else None
            # What scalar calls read first (:func:`.scalar.tiled_quick_cells`): the cells, the
            # values of palette indices, and for a joined table the compiled call on it.
            cells = tiled_quick_cells([t.table for t in decoded], self.tiles_x, self.width,
                                      self.height)
            self._cache["quick"] = () if cells is None else (
                cells, self.width, scalar_values(self.palette, self.squeeze),
                None if joined is None else scalar_lookup_function(), joined)
            if joined is not None:
                self._cache[key] = (joined, None)
                return self._cache[key]
            # Their tables end to end, each tile kept as a view into them.
            starts = np.concatenate([[0], np.cumsum([t.table.size for t in decoded])])
            table = np.concatenate([t.table for t in decoded])
            tiles = [t.with_table(table[a:b]) for t, a, b in zip(decoded, starts[:-1], starts[1:],
                                                                   strict=True)]
            words = tiled_words(table, starts[:-1], self.width, self.height, self.tile_bits,
                                self.tiles_x)
            self._cache[key] = (table, words)
            self._cache["tiles", False] = tiles
        return self._cache[key]

    def lookup(self, xs: np.ndarray | int, ys: np.ndarray | int) -> np.ndarray:
        """Texel values at columns ``xs``, rows ``ys`` (as :meth:`PackedLayer.lookup`).

        Raises TerrathemeError (a coordinate outside the layer).
        """
        quick = self._cache.get("quick")
        if quick and type(xs) is int and type(ys) is int:
            # Scalar fast path (:mod:`.scalar`): a uniform quick cell's value, or the compiled
            # call on the joined table; tiles looked up on their own go the way below.
            rows, w, values, call, joined = quick
            if (xs | ys) >= 0 and xs < w and ys < len(rows):
                i = rows[ys][xs >> QUICK_MIN_BITS]
                if i != 255:
                    return values[i]
                if call is not None:
                    return values[call(xs, ys, joined)]
        table, words = self._tables()
        if (isinstance(xs, int | np.integer) and isinstance(ys, int | np.integer)
                and not isinstance(xs, bool) and not isinstance(ys, bool)):
            # One texel: its tile's scalar lookup, then the layer's palette.
            x, row = int(xs), int(ys)
            if not (0 <= x < self.width and 0 <= row < self.height):
                raise TerrathemeError(f"texel ({x}, {row}) is outside the {self.width} x "
                                      f"{self.height} layer")
            if words is None:
                return self.values_of(np.asarray(scalar_lookup_function()(x, row, table)))[()]
            mask = self.tile_side - 1
            tile = self._cache["tiles", False][(row >> self.tile_bits) * self.tiles_x
                                               + (x >> self.tile_bits)]
            return self.values_of(np.asarray(tile.lookup(x & mask, row & mask)))[()]
        xs_b, ys_b = np.broadcast_arrays(np.asarray(xs), np.asarray(ys))
        if xs_b.dtype.kind not in "iu" or ys_b.dtype.kind not in "iu":
            raise TerrathemeError("texel coordinates must be integers")
        shape = xs_b.shape
        flat_x = np.ascontiguousarray(xs_b.reshape(-1), dtype=np.int64)
        flat_y = np.ascontiguousarray(ys_b.reshape(-1), dtype=np.int64)
        idx = np.empty(flat_x.size, np.uint8)
        threads = self.threads if flat_x.size >= PARALLEL_FROM else 1
        bad = lookup_batch(flat_x, flat_y, table, idx, threads, words)
        if bad >= 0:
            raise TerrathemeError(f"texel ({int(flat_x[bad])}, {int(flat_y[bad])}) is outside "
                                  f"the {self.width} x {self.height} layer")
        out = self.values_of(idx).reshape(shape + ((self.channels,) if not self.squeeze else ()))
        return out[()] if out.ndim == 0 else out

    def values_of(self, indices: np.ndarray) -> np.ndarray:
        """Texel values of palette indices (as :meth:`PackedLayer.values_of`)."""
        return palette_values(self.palette, self.identity, self.squeeze, indices)

    def bands(self, rows: int = 256) -> Iterator[tuple[int, np.ndarray]]:
        """Palette-index bands, top to bottom, one tile row decoded at a time.

        Yields ``(y, band)`` with ``band`` a ``(h, width)`` uint8 ndarray (reused).
        """
        rows = max(1, int(rows))
        buf = np.empty((min(rows, self.height), self.width), np.uint8)
        for ty in range(self.tiles_y):
            runs = []
            for tx in range(self.tiles_x):
                tile = self.tile(ty * self.tiles_x + tx)
                runs.append((tile, *table_runs(tile.table)))
            y0 = ty * self.tile_side
            th = runs[0][0].height
            for y in range(0, th, rows):
                h = min(rows, th - y)
                for tx, (tile, steps, values) in enumerate(runs):
                    x0 = tx * self.tile_side
                    fill_window(steps, values, tile.width, tile.height, tile.curve, 0, y,
                                tile.width, h, out=buf[:h, x0: x0 + tile.width],
                                threads=self.threads)
                yield y0 + y, buf[:h]

    def unpack(self, *, indices_only: bool = False) -> np.ndarray:
        """The whole image (for layers that fit in memory; see :meth:`bands`)."""
        idx = np.empty((self.height, self.width), np.uint8)
        for y, band in self.bands(self.tile_side):
            idx[y: y + band.shape[0]] = band
        return idx if indices_only else self.values_of(idx)

    # ------------------------------------------------------------ files

    def to_bytes(self, *, format: str = "compact") -> bytes:
        """The container's bytes, every tile re-encoded in ``format``."""
        tiles = [self.tile(i) for i in range(len(self._lengths))]
        head = _header(self.width, self.height, self.tile_bits, self.palette, self.identity,
                       self.squeeze, self.colours)
        blobs = [t.to_bytes(format=format) for t in tiles]
        return fmt.encode_head(head, self.palette, self.colours,
                               [len(b) for b in blobs]) + b"".join(blobs)

    def save(self, path: str | os.PathLike, *, format: str = "compact") -> int:
        """Write the container atomically; returns the bytes written."""
        data = self.to_bytes(format=format)
        write_bytes_atomic(path, data)
        return len(data)


def _header(width: int, height: int, tile_bits: int, palette: np.ndarray, identity: bool,
            squeeze: bool, colours: np.ndarray | None) -> fmt.TiledHeader:
    if not fmt.MIN_TILE_BITS <= tile_bits <= fmt.MAX_TILE_BITS:
        raise TerrathemeError(f"tile side 2^{tile_bits}: 2^{fmt.MIN_TILE_BITS} to "
                              f"2^{fmt.MAX_TILE_BITS} texels expected")
    if not (1 <= width <= fmt.MAX_TILED_SIDE and 1 <= height <= fmt.MAX_TILED_SIDE):
        raise TerrathemeError(f"layer of {width} x {height} texels: sides of 1 to "
                              f"{fmt.MAX_TILED_SIDE} expected")
    tx, ty = fmt.tiles_along(width, tile_bits), fmt.tiles_along(height, tile_bits)
    if tx * ty > fmt.MAX_TILES:
        raise TerrathemeError(f"{tx * ty} tiles: at most {fmt.MAX_TILES}; use larger tiles")
    values = ValueFormat.of(palette, identity, squeeze, colours)
    return fmt.TiledHeader(values, int(tile_bits), int(width), int(height), tx, ty, 0)


def needs_tiles(width: int, height: int) -> bool:
    """Whether a layer of this size must be tiled (a side over 65536)."""
    return width > MAX_SIDE or height > MAX_SIDE


def load_layer(path: str | os.PathLike) -> PackedLayer | TiledLayer:
    """Open a packed-layer file of either kind; raises CorruptFileError for a damaged file."""
    p, tiled = fmt.layer_file_kind(path)
    return TiledLayer.load(p) if tiled else PackedLayer.load(p)
