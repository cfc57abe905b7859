"""The tiled container file (``TTPT``): packed layers beyond 65536 x 65536, with an index.

Square tiles of ``2^t`` texels, each a complete packed-layer file (:mod:`.container`) of
indices into the container's one palette. Byte layout and checks: docs/formats.md, P2.
"""

from __future__ import annotations

import os
import struct
import zlib
from typing import NamedTuple

import numpy as np
from terratheme.core.errors import CorruptFileError, UnsupportedVersionError
from terratheme.core.io.inputs import check_input_file
from terratheme.core.packing.container import FLAG_ALPHA, FLAG_COLOURS, FLAG_IDENTITY, ValueFormat

MAGIC = b"TTPT"
VERSION = 1
HEADER = struct.Struct("<4sBBBBHBBIIIIQ")
INDEX_ENTRY = struct.Struct("<QQ")
#: Largest side of a tiled layer.
MAX_TILED_SIDE = (1 << 31) - 1
#: Tile sides, log2.
MIN_TILE_BITS, MAX_TILE_BITS = 6, 16
#: Most tiles in one container (a 16 MiB index).
MAX_TILES = 1 << 20


class TiledHeader(NamedTuple):
    """The fixed part of a tiled container, checked (:func:`read_tiled_header`)."""

    values: ValueFormat
    tile_bits: int
    width: int
    height: int
    tiles_x: int
    tiles_y: int
    tile_bytes: int

    @property
    def tiles(self) -> int:
        """Number of tiles ``N``."""
        return self.tiles_x * self.tiles_y

    @property
    def index_at(self) -> int:
        """Offset of the tile index."""
        return HEADER.size + self.values.table_bytes

    @property
    def tiles_at(self) -> int:
        """Offset of the first tile (after the index and its checksum)."""
        return self.index_at + INDEX_ENTRY.size * self.tiles + 4

    @property
    def file_bytes(self) -> int:
        """Length of the whole file."""
        return self.tiles_at + self.tile_bytes


def tiles_along(size: int, tile_bits: int) -> int:
    """Tiles of side ``2^tile_bits`` that cover ``size`` texels."""
    return -(-int(size) // (1 << int(tile_bits)))


def encode_head(head: TiledHeader, palette: np.ndarray, colours: np.ndarray | None,
                lengths: list[int]) -> bytes:
    """Header, palette, colours, index and checksum of a container whose tiles have
    ``lengths`` bytes (the tiles follow)."""
    v = head.values
    out = HEADER.pack(MAGIC, VERSION, v.flags, v.channels, v.sample, v.k, head.tile_bits, 0,
                      head.width, head.height, head.tiles_x, head.tiles_y,
                      sum(lengths))
    if not v.identity:
        out += palette.astype(palette.dtype.newbyteorder("<")).tobytes()
    if colours is not None:
        out += np.ascontiguousarray(colours, np.uint8).tobytes()
    offsets = np.concatenate([[0], np.cumsum(lengths, dtype=np.int64)[:-1]])
    out += b"".join(INDEX_ENTRY.pack(int(o), int(n)) for o, n in zip(offsets, lengths,
                                                                      strict=True))
    return out + struct.pack("<I", zlib.crc32(out))


def read_tiled_header(data: bytes, *, name: str, file_bytes: int) -> TiledHeader:
    """Parse and check the fixed header of a container of ``file_bytes`` bytes.

    Raises CorruptFileError (or UnsupportedVersionError for a newer version).
    """
    if len(data) < HEADER.size:
        raise CorruptFileError(f"{name}: truncated tiled-layer header ({len(data)} bytes)")
    (magic, version, flags, channels, sample, k, tile_bits, reserved, width, height, tx, ty,
     tile_bytes) = HEADER.unpack_from(data)
    if magic != MAGIC:
        raise CorruptFileError(f"{name}: not a terratheme tiled layer (magic {magic!r})")
    if version > VERSION:
        raise UnsupportedVersionError(
            f"{name}: tiled-layer format version {version}; this build reads up to {VERSION}")
    checks = (
        (version >= 1, f"format version {version}"),
        (not flags & ~15, f"flags {flags:#x}"),
        (1 <= channels <= 4 and sample in (1, 2), f"{channels} channels of {sample} bytes"),
        (1 <= k <= 256, f"palette of {k} colours"),
        (not flags & FLAG_IDENTITY or channels == 1, "identity palette with colour channels"),
        (not flags & (FLAG_COLOURS | FLAG_ALPHA) or flags & FLAG_IDENTITY and flags & FLAG_COLOURS,
         "display colours without an identity palette"),
        (MIN_TILE_BITS <= tile_bits <= MAX_TILE_BITS and reserved == 0,
         f"tile side 2^{tile_bits}"),
        (1 <= width <= MAX_TILED_SIDE and 1 <= height <= MAX_TILED_SIDE,
         f"size {width} x {height}"),
        (tx == tiles_along(width, tile_bits) and ty == tiles_along(height, tile_bits),
         f"{tx} x {ty} tiles for {width} x {height} texels"),
        (tx * ty <= MAX_TILES, f"{tx * ty} tiles (at most {MAX_TILES})"),
    )
    for ok, what in checks:
        if not ok:
            raise CorruptFileError(f"{name}: bad tiled-layer header: {what}")
    head = TiledHeader(ValueFormat.from_flags(flags, channels, sample, k), tile_bits, width,
                       height, tx, ty, tile_bytes)
    if file_bytes != head.file_bytes:
        raise CorruptFileError(
            f"{name}: {file_bytes} bytes, but the tiled-layer header says {head.file_bytes}")
    return head


def read_index(data: bytes, head: TiledHeader, *, name: str) -> tuple[np.ndarray, np.ndarray]:
    """Check the index and its checksum (``data``: the file up to the first tile); returns
    each tile's byte offset in the file and length, (N,) int64 each."""
    if len(data) < head.tiles_at:
        raise CorruptFileError(f"{name}: truncated tile index")
    (stored,) = struct.unpack_from("<I", data, head.tiles_at - 4)
    if zlib.crc32(memoryview(data)[: head.tiles_at - 4]) != stored:
        raise CorruptFileError(f"{name}: checksum mismatch in the tiled-layer header or index")
    index = np.frombuffer(data, "<u8", count=2 * head.tiles, offset=head.index_at)
    offsets, lengths = index[0::2].astype(np.uint64), index[1::2].astype(np.uint64)
    # Each length at most the tiles' bytes, and the ends rising: a sum that wraps 2^64
    # (lengths near 2^63 adding up to the file) would otherwise pass as end to end.
    ends = np.cumsum(lengths)
    if (lengths.min() < 40 or lengths.max() > head.tile_bytes
            or np.any(ends[1:] <= ends[:-1]) or ends[-1] != head.tile_bytes
            or not np.array_equal(offsets, ends - lengths)):
        raise CorruptFileError(f"{name}: tile index does not run end to end over the tiles")
    return offsets.astype(np.int64) + head.tiles_at, lengths.astype(np.int64)


def layer_file_kind(path: str | os.PathLike) -> tuple[str, bool]:
    """A packed-layer file's path as a string, and whether it is a tiled container."""
    p = os.fspath(check_input_file(path, "a packed layer"))
    with open(p, "rb") as fh:
        return p, fh.read(4) == MAGIC
