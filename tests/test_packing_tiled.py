"""Tiled containers (layers beyond 65536 x 65536) and packing image files band by band."""

from __future__ import annotations

import json
import struct
import zlib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from terratheme.app.cli import main
from terratheme.core.errors import CorruptFileError, TerrathemeError, UnsupportedVersionError
from terratheme.core.io.images import read_image, write_image
from terratheme.core.packing import PackedLayer, TiledLayer, layer_info, load_layer, pack, pack_file
from terratheme.core.packing.index_png import PalettePngWriter, display_colours, read_index_image


def _blocks(rng, h, w, cell=5, k=4):
    grid = rng.integers(0, k, (h // cell + 1, w // cell + 1))
    return np.kron(grid, np.ones((cell, cell), int))[:h, :w].astype(np.uint8)


@pytest.mark.parametrize("curve", ["hilbert", "morton", "auto"])
@pytest.mark.parametrize("tile_bits", [6, 7])
def test_tiled_round_trip_and_lookup(tmp_path, curve, tile_bits):
    rng = np.random.default_rng(tile_bits)
    img = _blocks(rng, 150, 201)
    layer = pack(img, curve, tile_bits=tile_bits)
    assert isinstance(layer, TiledLayer)
    side = 1 << tile_bits
    assert (layer.tiles_x, layer.tiles_y) == (-(-201 // side), -(-150 // side))
    assert np.array_equal(layer.unpack(), img)
    xs, ys = rng.integers(0, 201, 3000), rng.integers(0, 150, 3000)
    assert np.array_equal(layer.lookup(xs, ys), img[ys, xs])
    assert layer.lookup(200, 149) == img[149, 200]
    # Each tile is the packed layer of its own window.
    for i in range(layer.tiles_x * layer.tiles_y):
        x, y, w, h = layer.tile_rect(i)
        assert np.array_equal(layer.tile(i).unpack(), img[y: y + h, x: x + w])
    layer.save(tmp_path / "t.ttpack")
    back = load_layer(tmp_path / "t.ttpack")
    assert isinstance(back, TiledLayer) and np.array_equal(back.unpack(), img)
    assert back.run_count == sum(back.tile(i).run_count for i in range(back.tiles_x * back.tiles_y))
    info = layer_info(tmp_path / "t.ttpack")
    assert (info.tiles, info.tile_side, info.run_count) == (layer.tiles_x * layer.tiles_y, side,
                                                             back.run_count)
    assert back.memory_bytes <= info.memory_bytes_max


def test_colour_image_tiles_share_one_palette():
    rng = np.random.default_rng(2)
    idx = _blocks(rng, 100, 130, k=6)
    colours = np.array([[9, 8, 7], [200, 0, 0], [0, 99, 0], [1, 2, 255], [50, 50, 50],
                        [255, 255, 0]], np.uint8)
    rgb = colours[idx]
    layer = pack(rgb, tile_bits=6)
    assert not layer.identity and len(layer.palette) == 6
    assert np.array_equal(layer.unpack(), rgb)
    xs, ys = rng.integers(0, 130, 500), rng.integers(0, 100, 500)
    assert np.array_equal(layer.lookup(xs, ys), rgb[ys, xs])


def test_layers_over_65536_a_side_are_tiled():
    img = np.zeros((3, 70000), np.uint8)
    img[1, 69990:] = 4
    img[:, 65536] = 2
    layer = pack(img)
    assert isinstance(layer, TiledLayer) and (layer.tiles_x, layer.tiles_y) == (2, 1)
    assert layer.lookup(69995, 1) == 4 and layer.lookup(65536, 0) == 2
    assert layer.lookup(np.array([0, 69999]), np.array([2, 1])).tolist() == [0, 4]
    with pytest.raises(TerrathemeError, match=r"texel \(70000, 0\) is outside"):
        layer.lookup(np.array([70000]), np.array([0]))
    assert np.array_equal(TiledLayer.from_bytes(layer.to_bytes()).unpack(), img)


@settings(max_examples=25, deadline=None)
@given(st.integers(1, 140), st.integers(1, 140), st.integers(6, 7), st.integers(0, 2**31))
def test_any_size_tiles_back(w, h, tile_bits, seed):
    img = _blocks(np.random.default_rng(seed), h, w, cell=3)
    layer = pack(img, tile_bits=tile_bits)
    assert np.array_equal(TiledLayer.from_bytes(layer.to_bytes()).unpack(), img)


@pytest.fixture
def files(tmp_path):
    rng = np.random.default_rng(5)
    img = _blocks(rng, 530, 611, cell=9, k=5)
    write_image(tmp_path / "i.png", img)
    write_image(tmp_path / "i.tif", img, tile=64)
    rgb = np.stack([img * 30, 255 - img * 20, img], 2).astype(np.uint8)
    write_image(tmp_path / "rgb.png", rgb)
    write_image(tmp_path / "u16.tif", (img.astype(np.uint16) * 3000)[:, :, None])
    with PalettePngWriter(tmp_path / "pal.png", 611, 530, display_colours(5)) as out:
        out.write_rows(img)
    return tmp_path, img, rgb


FILE_NAMES = ["i.png", "i.tif", "rgb.png", "u16.tif", "pal.png"]


# Every file kind with the curve chosen per layer, and one with a fixed curve; the fixed
# curve on the other kinds (0.6-1.3 s each) runs with the slow suite.
@pytest.mark.parametrize(("name", "curve"), [
    *((name, "auto") for name in FILE_NAMES),
    *(pytest.param(name, "hilbert", marks=[] if name == "i.png" else pytest.mark.slow)
      for name in FILE_NAMES),
])
def test_pack_file_band_by_band_equals_pack(files, name, curve):
    tmp_path, _, _ = files
    image, colours = read_index_image(tmp_path / name)
    whole = pack(image, curve, colours=colours)
    assert pack_file(tmp_path / name, curve).to_bytes() == whole.to_bytes()
    tiled = pack_file(tmp_path / name, curve, tile_bits=8)
    assert tiled.to_bytes() == pack(image, curve, tile_bits=8, colours=colours).to_bytes()
    assert np.array_equal(tiled.unpack(), image)


def test_cli_tiled_pack_info_unpack(files, capsys):
    tmp_path, img, _ = files
    out = tmp_path / "t.ttpack"
    assert main(["pack", str(tmp_path / "i.png"), str(out), "--tile", "256"]) == 0
    assert "3 x 3 tiles" in capsys.readouterr().out
    assert main(["info", str(out), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert (info["tiles"], info["tile_side"], info["width"]) == (9, 256, 611)
    assert main(["unpack", str(out), str(tmp_path / "back.png")]) == 0
    assert np.array_equal(read_index_image(tmp_path / "back.png")[0], img)
    assert main(["info", str(out), "--runs"]) == 2
    assert "tiled container" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["pack", str(tmp_path / "i.png"), str(out), "--tile", "100"])
    assert "a power of two from 64 to 65536" in capsys.readouterr().err


def _container(tile_bits=6) -> bytes:
    return pack(_blocks(np.random.default_rng(1), 70, 90), tile_bits=tile_bits).to_bytes()


def test_truncated_container_at_every_length():
    data = _container()
    for cut in range(0, len(data), 7):
        with pytest.raises(CorruptFileError):
            TiledLayer.from_bytes(data[:cut]).unpack()


def _refix(data: bytes, **fields) -> bytes:
    """A container with header fields changed and its header checksum made right."""
    layer = TiledLayer.from_bytes(data)
    body = bytearray(data)
    offsets = {"version": (4, "<B"), "tile_bits": (10, "<B"), "width": (12, "<I"),
               "tiles_x": (20, "<I")}
    for key, value in fields.items():
        struct.pack_into(offsets[key][1], body, offsets[key][0], value)
    at = 36 + 16 * layer.tiles_x * layer.tiles_y
    struct.pack_into("<I", body, at, zlib.crc32(body[:at]))
    return bytes(body)


def test_container_header_checks():
    data = _container()
    with pytest.raises(UnsupportedVersionError, match="version 2"):
        TiledLayer.from_bytes(_refix(data, version=2))
    with pytest.raises(CorruptFileError, match="2 x 2 tiles for 129 x 70"):
        TiledLayer.from_bytes(_refix(data, width=129))
    with pytest.raises(CorruptFileError, match="tile side 2"):
        TiledLayer.from_bytes(_refix(data, tile_bits=17))
    bad = bytearray(data)
    bad[40] ^= 1
    with pytest.raises(CorruptFileError, match="checksum mismatch"):
        TiledLayer.from_bytes(bytes(bad))
    with pytest.raises(CorruptFileError, match="not a terratheme tiled layer"):
        TiledLayer.from_bytes(b"XXXX" + data[4:])


def test_a_tile_of_the_wrong_size_is_refused_when_decoded():
    data = _container()
    layer = TiledLayer.from_bytes(data)
    # Swap in a 3 x 3 layer for the first tile, with the index lengths kept consistent.
    small = pack(np.zeros((3, 3), np.uint8)).to_bytes()
    tiles = [small] + [layer._blob(i) for i in range(1, 4)]
    forged = TiledLayer.from_tile_bytes(90, 70, 6, tiles, layer.palette, identity=True,
                                        squeeze=True)
    with pytest.raises(CorruptFileError, match=r"tile \(0, 0\): a 3 x 3 index layer where a "
                                               r"64 x 64 index tile belongs"):
        forged.lookup(0, 0)
    colour = pack(np.stack([np.zeros((64, 64), np.uint8)] * 3, 2)).to_bytes()
    forged = TiledLayer.from_tile_bytes(90, 70, 6, [colour] + tiles[1:], layer.palette,
                                        identity=True, squeeze=True)
    with pytest.raises(CorruptFileError, match="colour layer"):
        forged.unpack()


def test_single_layer_load_dispatch(tmp_path):
    layer = pack(np.zeros((5, 5), np.uint8))
    layer.save(tmp_path / "one.ttpack")
    assert isinstance(load_layer(tmp_path / "one.ttpack"), PackedLayer)
    with pytest.raises(TerrathemeError, match="no such file"):
        load_layer(tmp_path / "none.ttpack")


def test_cli_packs_a_strip_wider_than_65536_band_by_band(tmp_path, capsys):
    img = np.zeros((3, 70000), np.uint8)
    img[1, 69990:] = 4
    img[:, 65536] = 2
    write_image(tmp_path / "strip.png", img[:, :, None])
    out = tmp_path / "strip.ttpack"
    assert main(["pack", str(tmp_path / "strip.png"), str(out)]) == 0
    assert "2 x 1 tiles" in capsys.readouterr().out
    layer = load_layer(out)
    assert isinstance(layer, TiledLayer) and layer.lookup(69995, 1) == 4
    assert main(["unpack", str(out), str(tmp_path / "back.png")]) == 0
    assert np.array_equal(read_index_image(tmp_path / "back.png")[0], img)
    assert main(["unpack", str(out), str(tmp_path / "back.tif")]) == 0
    assert np.array_equal(read_image(tmp_path / "back.tif")[:, :, 0], img)


def test_tiled_pack_of_a_palette_png_with_unused_colours(tmp_path, capsys):
    # classify writes 256 colours for 3 used values: the container keeps the first 3 (issue 36).
    table = np.array([[0, 0, 0], [200, 10, 10], [10, 200, 10]] + [[i, i, 255] for i in
                                                                 range(253)], np.uint8)
    values = np.tile(np.array([[0, 1, 2, 1]], np.uint8), (70, 33))
    write_image(tmp_path / "labels.png", values[:, :, None], palette=table)
    out = tmp_path / "t.ttpack"
    assert main(["pack", str(tmp_path / "labels.png"), str(out), "--tile", "64"]) == 0
    layer = load_layer(out)
    assert layer.colours.tolist() == table[:3].tolist()
    assert np.array_equal(layer.unpack(indices_only=True), values)


def test_info_checks_every_tiles_checksum(tmp_path, capsys):
    # A flipped payload byte in the last tile was reported as a fine layer (issue 36).
    values = np.tile(np.array([[0, 1, 2, 1]], np.uint8), (70, 33))
    out = tmp_path / "t.ttpack"
    pack(values, "hilbert", tile_bits=6).save(out)
    assert layer_info(out).tiles == 6
    data = bytearray(out.read_bytes())
    data[-10] ^= 0xFF
    out.write_bytes(bytes(data))
    with pytest.raises(CorruptFileError, match="tile 5: checksum mismatch"):
        layer_info(out)
    assert main(["info", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "checksum mismatch" in err
