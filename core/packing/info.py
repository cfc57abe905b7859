"""What a packed-layer file holds, from its headers alone (``terratheme info``).

Checks headers and checksums (a tiled container's tiles one at a time); decodes no
payload and loads no numba kernel.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

from terratheme.core.curves.square import Curve, curve_order
from terratheme.core.packing import tiled_format
from terratheme.core.packing.container import check_file, read_layer_file, read_palette
from terratheme.core.packing.layout import table_words_max


@dataclass(frozen=True)
class LayerInfo:
    """A packed layer's description (``memory_bytes_max`` bounds the loaded table;
    ``format`` is the payload encoding, a tiled container's tiles' joined by ``+``).
    """

    width: int
    height: int
    curve: str
    channels: int
    identity_palette: bool
    palette: list
    run_count: int
    file_bytes: int
    memory_bytes_max: int
    format: str
    version: int
    tiles: int = 1
    tile_side: int | None = None


def layer_info(path: str | os.PathLike) -> LayerInfo:
    """Describe a packed-layer file without decoding its runs.

    Raises TerrathemeError (missing file; :class:`CorruptFileError` for a damaged or foreign
    file).
    """
    p, tiled = tiled_format.layer_file_kind(path)
    with open(p, "rb") as fh:
        if tiled:
            return _tiled_info(fh, p)
        data = read_layer_file(fh, name=p)
    head = check_file(data, name=p)
    n = curve_order(head.width, head.height)
    return LayerInfo(
        width=head.width, height=head.height, curve=Curve(head.curve).name.lower(),
        channels=head.values.channels, identity_palette=head.values.identity,
        palette=read_palette(data, head.values).tolist(), run_count=head.runs,
        file_bytes=len(data),
        memory_bytes_max=4 * table_words_max(head.width, head.height, n, head.runs),
        format=head.encoding_name, version=head.version,
    )


def _tiled_info(fh, name: str) -> LayerInfo:
    """The description of a tiled container, from its index and each tile's header."""
    size = os.fstat(fh.fileno()).st_size
    fh.seek(0)
    head = tiled_format.read_tiled_header(fh.read(tiled_format.HEADER.size), name=name,
                                          file_bytes=size)
    fh.seek(0)
    prefix = fh.read(head.tiles_at)
    offsets, lengths = tiled_format.read_index(prefix, head, name=name)
    runs = memory = 0
    curves, formats = set(), set()
    for i, (off, length) in enumerate(zip(offsets, lengths, strict=True)):
        fh.seek(int(off))
        tile = check_file(fh.read(int(length)), name=f"{name} tile {i}")
        runs += tile.runs
        memory += 4 * table_words_max(tile.width, tile.height,
                                 curve_order(tile.width, tile.height), tile.runs)
        curves.add(Curve(tile.curve).name.lower())
        formats.add(tile.encoding_name)
    palette = read_palette(prefix, head.values, at=tiled_format.HEADER.size)
    return LayerInfo(
        width=head.width, height=head.height,
        curve=curves.pop() if len(curves) == 1 else "mixed", channels=head.values.channels,
        identity_palette=head.values.identity, palette=palette.tolist(),
        run_count=runs, file_bytes=size, memory_bytes_max=memory, format="+".join(sorted(formats)),
        version=tiled_format.VERSION, tiles=head.tiles, tile_side=1 << head.tile_bits,
    )
