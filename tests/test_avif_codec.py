"""The colour map's AVIF codec: round trips, true colours, and the size read from its header."""

from __future__ import annotations

import struct

import numpy as np
import pytest
from terratheme.core.errors import CorruptFileError
from terratheme.core.io.codec import decode_image, encode_image
from terratheme.core.io.image_format import avif_size
from terratheme.core.model.colour_map import ColourMap


def box(kind: bytes, payload: bytes) -> bytes:
    return struct.pack(">I", 8 + len(payload)) + kind + payload


def forged_header(width: int, height: int) -> bytes:
    """ftyp, then meta > iprp > ipco > ispe declaring width x height (ISO/IEC 23008-12 6.5.3);
    no image data follows."""
    ispe = box(b"ispe", bytes(4) + struct.pack(">II", width, height))
    meta = box(b"meta", bytes(4) + box(b"hdlr", bytes(24)) + box(b"iprp", box(b"ipco", ispe)))
    return box(b"ftyp", b"avif" + bytes(4) + b"avifmif1") + meta


@pytest.mark.parametrize(("width", "height"), [(1, 1), (53, 37), (16384, 16384), (1 << 20, 3)])
def test_size_of_a_forged_header(width, height):
    assert avif_size(forged_header(width, height)) == (width, height)


def test_not_an_avif_header():
    assert avif_size(b"") is None
    assert avif_size(b"\x89PNG\r\n\x1a\n" + bytes(40)) is None
    assert avif_size(box(b"ftyp", b"avif" + bytes(4)) + box(b"free", bytes(8))) is None
    # A box claiming to be smaller than its own header ends the walk.
    assert avif_size(box(b"ftyp", b"avif" + bytes(4)) + struct.pack(">I4s", 3, b"meta")) is None


@pytest.mark.parametrize(("h", "w", "c"), [(1, 1, 3), (37, 53, 3), (16, 9, 1), (20, 30, 4)])
def test_round_trip_keeps_the_shape(h, w, c):
    image = np.random.default_rng(h * w).integers(0, 256, (h, w, c), dtype=np.uint8)
    data = encode_image(image, codec="avif", quality=90)
    assert avif_size(data) == (w, h)
    assert decode_image(data, codec="avif", shape=(h, w)).shape == (h, w, c)


def test_flat_colours_come_back():
    for colour in [(200, 100, 50), (128, 128, 128), (0, 255, 0)]:
        image = np.full((24, 40, 3), colour, np.uint8)
        back = decode_image(encode_image(image, codec="avif", quality=95), codec="avif")
        assert np.abs(back.astype(int) - image).max() <= 2


def test_a_colour_ramp_keeps_its_mean():
    # imagecodecs' default matrix (BT.601 coding, decoded otherwise) shifted a ramp's channel
    # means by -0.63, +0.48, -0.77: the map's colours would drift.
    y, x = np.mgrid[0:64, 0:64]
    ramp = np.stack([x * 4, y * 4, 255 - 2 * x - 2 * y], -1).astype(np.uint8)
    back = decode_image(encode_image(ramp, codec="avif", quality=95), codec="avif")
    assert np.all(np.abs((back.astype(float) - ramp).mean(axis=(0, 1))) < 0.3)


def test_a_forged_size_is_refused_before_decoding():
    with pytest.raises(CorruptFileError, match="avif image is 16384 x 16384, expected 4 x 4"):
        decode_image(forged_header(16384, 16384), codec="avif", shape=(4, 4))


def test_a_truncated_map_is_one_clear_error():
    data = encode_image(np.full((40, 40, 3), 90, np.uint8), codec="avif", quality=80)
    with pytest.raises(CorruptFileError, match="damaged avif image"):
        decode_image(data[:-20], codec="avif", shape=(40, 40))


def test_a_colour_map_round_trips_in_avif():
    gain = np.random.default_rng(3).integers(100, 160, (5, 7, 3), dtype=np.uint8)
    cmap = ColourMap.encode(gain, 8, "avif", 95)
    back = ColourMap.from_bytes(cmap.data, "avif", cmap.scale, gain.shape[:2])
    assert np.array_equal(back.pixels, cmap.pixels)
    assert np.abs(cmap.pixels.astype(int) - gain).mean() < 3
