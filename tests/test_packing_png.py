"""Palette PNGs of index layers: the streamed writer, indices read back, display colours."""

from __future__ import annotations

import struct
import zlib

import numpy as np
import pytest
from terratheme.core.errors import CorruptFileError, TerrathemeError
from terratheme.core.io.images import read_image, read_labels, write_image
from terratheme.core.io.png import palette_indices, png_palette
from terratheme.core.packing import pack
from terratheme.core.packing.export import write_layer_image
from terratheme.core.packing.index_png import PalettePngWriter, display_colours, read_index_image

COLOURS = np.array([[0, 0, 0], [255, 0, 0], [0, 128, 255], [10, 200, 30]], np.uint8)


def _chunks(data: bytes) -> list[tuple[bytes, bytes]]:
    out, pos = [], 8
    while pos < len(data):
        size, kind = struct.unpack_from(">I4s", data, pos)
        out.append((kind, data[pos + 8: pos + 8 + size]))
        pos += 12 + size
    return out


def test_writer_bands_make_one_valid_png(tmp_path):
    idx = np.arange(7 * 5, dtype=np.uint8).reshape(7, 5) % 4
    path = tmp_path / "a.png"
    with PalettePngWriter(path, 5, 7, COLOURS) as out:
        out.write_rows(idx[:3])
        out.write_rows(idx[3:])
    data = path.read_bytes()
    kinds = [k for k, _ in _chunks(data)]
    assert kinds[0] == b"IHDR" and kinds[1] == b"PLTE" and kinds[-1] == b"IEND"
    width, height, depth, colour_type = struct.unpack(">IIBB", _chunks(data)[0][1][:10])
    assert (width, height, depth, colour_type) == (5, 7, 8, 3)
    # The stored scanlines are filter byte 0 then the indices themselves.
    raw = zlib.decompress(b"".join(d for k, d in _chunks(data) if k == b"IDAT"))
    assert raw == b"".join(b"\0" + row.tobytes() for row in idx)
    assert np.array_equal(read_image(path), COLOURS[idx])
    assert np.array_equal(png_palette(path), COLOURS)


def test_alpha_goes_to_trns_and_reads_back(tmp_path):
    rgba = np.concatenate([COLOURS, np.array([[0], [255], [128], [255]], np.uint8)], axis=1)
    idx = np.array([[0, 1, 2, 3]], np.uint8)
    path = tmp_path / "a.png"
    with PalettePngWriter(path, 4, 1, rgba) as out:
        out.write_rows(idx)
    assert dict(_chunks(path.read_bytes()))[b"tRNS"] == bytes([0, 255, 128, 255])
    back, colours = read_index_image(path)
    assert np.array_equal(back, idx) and np.array_equal(colours, rgba)


def test_one_fully_transparent_entry_reads_back(tmp_path):
    # A tRNS of one 0 among 255s: Pillow gives it as that entry's index, not the bytes.
    rgba = np.concatenate([COLOURS, np.array([[255], [0], [255], [255]], np.uint8)], axis=1)
    path = tmp_path / "a.png"
    with PalettePngWriter(path, 4, 1, rgba) as out:
        out.write_rows(np.array([[0, 1, 2, 3]], np.uint8))
    assert dict(_chunks(path.read_bytes()))[b"tRNS"] == bytes([255, 0, 255, 255])
    assert png_palette(path)[:, 3].tolist() == [255, 0, 255, 255]
    assert np.array_equal(png_palette(path)[:, :3], COLOURS)


def test_writer_refuses_bad_bands_and_leaves_no_file(tmp_path):
    path = tmp_path / "a.png"
    with pytest.raises(TerrathemeError, match="band of shape"), \
            PalettePngWriter(path, 4, 2, COLOURS) as out:
        out.write_rows(np.zeros((1, 5), np.uint8))
    with pytest.raises(TerrathemeError, match="1 of 2 rows"), \
            PalettePngWriter(path, 4, 2, COLOURS) as out:
        out.write_rows(np.zeros((1, 4), np.uint8))
    with pytest.raises(TerrathemeError, match="index 7 has no palette colour"), \
            PalettePngWriter(path, 4, 1, COLOURS) as out:
        out.write_rows(np.full((1, 4), 7, np.uint8))
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(TerrathemeError, match="palette of shape"):
        PalettePngWriter(path, 4, 1, np.zeros((300, 3), np.uint8))


def test_grey_png_has_no_palette(tmp_path):
    write_image(tmp_path / "g.png", np.zeros((3, 3, 1), np.uint8))
    assert png_palette(tmp_path / "g.png") is None
    image, colours = read_index_image(tmp_path / "g.png")
    assert colours is None and image.shape == (3, 3, 1)


def test_palette_indices_refuse_ambiguous_or_unknown_colours():
    pixels = COLOURS[np.array([[1, 2]])]
    table = np.concatenate([COLOURS, COLOURS[1:2]])  # index 4 repeats index 1's colour
    with pytest.raises(CorruptFileError, match="cannot be told apart"):
        palette_indices(pixels, table, "x.png")
    # A repeated colour that no pixel uses is harmless.
    assert palette_indices(COLOURS[np.array([[2, 3]])], table, "x.png").tolist() == [[2, 3]]
    with pytest.raises(CorruptFileError, match="not in the file's palette"):
        palette_indices(np.full((1, 1, 3), 77, np.uint8), COLOURS, "x.png")


def _palette_png(plte: bytes | None) -> bytes:
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(
            ">I", zlib.crc32(kind + data))
    ihdr = struct.pack(">IIBBBBB", 2, 1, 8, 3, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr)
            + (chunk(b"PLTE", plte) if plte is not None else b"")
            + chunk(b"IDAT", zlib.compress(b"\x00\x00\x01")) + chunk(b"IEND", b""))


@pytest.mark.parametrize("plte", [None, b"", bytes(7)])
def test_one_palette_reader_for_labels_and_packing(tmp_path, plte):
    # Issue 37: pack's reader took a bad PLTE for "no palette" and packed the expanded
    # colours; the labels reader refused it. Both refuse it now.
    path = tmp_path / "bad.png"
    path.write_bytes(_palette_png(plte))
    for read in (png_palette, read_index_image, read_labels):
        with pytest.raises(TerrathemeError, match="bad.png"):
            read(path)


def test_display_colours_are_distinct():
    colours = display_colours(256)
    assert colours.shape == (256, 3)
    assert len({tuple(c) for c in colours}) == 256


def test_layer_with_display_colours_writes_them(tmp_path):
    idx = np.array([[0, 1, 1], [3, 3, 2]], np.uint8)
    layer = pack(idx, colours=COLOURS)
    assert write_layer_image(layer, tmp_path / "a.png") == "palette PNG"
    assert np.array_equal(png_palette(tmp_path / "a.png"), COLOURS)
    back = type(layer).from_bytes(layer.to_bytes())
    assert np.array_equal(back.colours, COLOURS)
    with pytest.raises(TerrathemeError, match="index image"):
        pack(np.stack([idx] * 3, axis=2), colours=COLOURS)
    with pytest.raises(TerrathemeError, match="display colours of shape"):
        pack(idx, colours=COLOURS[:2])
