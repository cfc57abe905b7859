"""The plane payload (encoding 2, version 2): 2-D context mixing, and version-1 files still read."""

from __future__ import annotations

import json
import struct
import zlib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from terratheme.core.errors import CorruptFileError
from terratheme.core.packing import PackedLayer, pack
from terratheme.core.packing import plane_format as plane

# Files written by the version-1 code (commit 172b7ed) for the seed's 8 x 8 figure.
V1_COMPACT = bytes.fromhex(
    "5454504b010100030101070008000000080000000f0000000000000035000000000000000501020304050600"
    "000a0000000000000012000000000000000004dd3f46971c20000000001ff8a819378bfb6459ed5f0da0afd0"
    "005b8c544a")
V1_SEED = bytes.fromhex(
    "5454504b010000030101070008000000080000000f000000000000001e00000000000000810184028101840281"
    "0184028101820383018904840386018c0588068405e2c1f507")
V1_RGB_MORTON = bytes.fromhex(
    "5454504b0101010003010600080000000800000016000000000000003d000000000000001eeb013cd702b487"
    "06969b055ac30378af040500010203040500000d0000000000000017000000000000000004dd4009ff3aac3a"
    "55a0000000001ff8a81937a35fa42862b0b7787de00367d37d2d8023b53f91")


@pytest.fixture(scope="module")
def figure(shared_vectors):
    vec = json.loads((shared_vectors / "sfc_8x8.json").read_text())
    return np.array(vec["index_image"], np.uint8)


def test_version_1_files_still_read(figure):
    for data in (V1_COMPACT, V1_SEED):
        assert data[4] == 1
        assert np.array_equal(PackedLayer.from_bytes(data).unpack(), figure)
    rgb = np.stack([figure * 30, 255 - figure * 20, figure], 2).astype(np.uint8)
    layer = PackedLayer.from_bytes(V1_RGB_MORTON)
    assert layer.curve.name == "MORTON" and np.array_equal(layer.unpack(), rgb)
    # The run streams are still written byte for byte as version 1 wrote them.
    assert pack(figure).to_bytes(format="streams") == V1_COMPACT
    assert pack(figure).to_bytes(format="seed") == V1_SEED


def _blocks(rng, h, w, cell, k, noise=0.0):
    grid = rng.integers(0, k, (h // cell + 1, w // cell + 1))
    img = np.kron(grid, np.ones((cell, cell), int))[:h, :w]
    flip = rng.random(img.shape) < noise
    img[flip] = rng.integers(0, k, int(flip.sum()))
    return img.astype(np.uint8)


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 300), st.integers(1, 300), st.sampled_from(["hilbert", "morton"]),
       st.integers(1, 7), st.sampled_from([1, 2, 5, 30, 254]), st.integers(0, 2**31))
def test_plane_round_trip(h, w, curve, cell, k, seed):
    img = _blocks(np.random.default_rng(seed), h, w, cell, k, noise=0.02)
    layer = pack(img, curve)
    data = layer.to_bytes(format="plane")
    assert (data[4], data[5]) == (2, 2)
    back = PackedLayer.from_bytes(data)
    assert np.array_equal(back.unpack(), img)
    assert np.array_equal(back.steps, layer.steps)


def test_colour_layer_and_display_colours_round_trip():
    rng = np.random.default_rng(1)
    idx = _blocks(rng, 90, 70, 6, 4, noise=0.05)
    colours = np.array([[1, 2, 3], [250, 0, 0], [0, 250, 0], [0, 0, 250]], np.uint8)
    for layer in (pack(colours[idx]), pack(idx, colours=colours)):
        back = PackedLayer.from_bytes(layer.to_bytes(format="plane"))
        assert np.array_equal(back.unpack(), layer.unpack())
    assert np.array_equal(back.colours, colours)


def test_uniform_segment_is_one_decision():
    # 3 header bytes (one class used, index 4, segment bits 10) and the coder's 5 flush bytes.
    layer = PackedLayer.from_runs(1024, 1024, "hilbert", [1024 * 1024 - 1], [4],
                                  np.arange(6, dtype=np.uint8), identity=True, squeeze=True)
    data = layer.to_bytes(format="plane")
    assert struct.unpack_from("<Q", data, 28)[0] == 3 + 5
    assert data[36:39] == bytes([0, 4, 10])
    assert PackedLayer.from_bytes(data).unpack().max() == 4


def test_compact_keeps_the_smaller_payload():
    rng = np.random.default_rng(2)
    maps = _blocks(rng, 200, 240, 9, 6)
    assert pack(maps).to_bytes()[5] == 2  # plane wins on a map
    # 255 classes cannot be coded as a plane (255 marks unknown texels): run streams.
    many = np.arange(256 * 4, dtype=np.int64).reshape(32, 32).astype(np.uint8)
    data = pack(many).to_bytes(format="plane")
    assert (data[4], data[5]) == (1, 1)
    assert np.array_equal(PackedLayer.from_bytes(data).unpack(), many)


def test_layers_over_the_texel_ceiling_keep_the_run_streams(monkeypatch):
    img = _blocks(np.random.default_rng(3), 64, 64, 2, 3, noise=0.3)
    data = pack(img).to_bytes(format="plane")
    monkeypatch.setattr(plane, "MAX_TEXELS_PER_BYTE", 1)
    monkeypatch.setattr(plane, "TEXEL_ALLOWANCE", 100)
    assert pack(img).to_bytes(format="plane")[5] == 1
    with pytest.raises(CorruptFileError, match="codes more texels than its"):
        PackedLayer.from_bytes(data)


def _with_payload(data: bytes, payload: bytes, *, version: int = 2, runs: int | None = None
                  ) -> bytes:
    body = bytearray(data[:36])
    body[4] = version
    struct.pack_into("<Q", body, 28, len(payload))
    if runs is not None:
        struct.pack_into("<Q", body, 20, runs)
    body += payload
    return bytes(body) + struct.pack("<I", zlib.crc32(body))


def test_plane_payload_errors():
    img = _blocks(np.random.default_rng(4), 40, 50, 4, 3, noise=0.05)
    data = pack(img).to_bytes(format="plane")
    payload = data[36:-4]
    with pytest.raises(CorruptFileError, match="encoding 2 in a version-1 file"):
        PackedLayer.from_bytes(_with_payload(data, payload, version=1))
    with pytest.raises(CorruptFileError, match="truncated or impossible plane payload"):
        PackedLayer.from_bytes(_with_payload(data, bytes([254])))
    with pytest.raises(CorruptFileError, match="bad plane payload header"):
        PackedLayer.from_bytes(_with_payload(data, bytes([1, 2, 1, 10]) + payload[5:]))
    with pytest.raises(CorruptFileError, match="(ends inside|impossible class in) segment 0"):
        PackedLayer.from_bytes(_with_payload(data, payload[:12]))
    # Four classes: every tree leaf is a class, so a cut stream runs dry instead.
    four = pack(_blocks(np.random.default_rng(5), 40, 50, 4, 4, noise=0.05)).to_bytes(
        format="plane")
    with pytest.raises(CorruptFileError, match="ends inside segment 0"):
        PackedLayer.from_bytes(_with_payload(four, four[36:48]))
    with pytest.raises(CorruptFileError, match="runs"):
        PackedLayer.from_bytes(_with_payload(data, payload, runs=3))


def test_shared_map_crop_beats_the_run_streams(shared_data):
    from terratheme.core.io.images import read_image

    path = next((shared_data / "maps" / "esa_worldcover").glob("*.png"))
    crop = np.ascontiguousarray(read_image(path)[2000:3000, 2000:3200, 0])
    layer = pack(crop)
    data = layer.to_bytes(format="plane")
    assert len(data) < 0.8 * len(layer.to_bytes(format="streams"))
    assert np.array_equal(PackedLayer.from_bytes(data).unpack(), crop)
