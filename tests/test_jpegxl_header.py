"""A JPEG XL image's size read from its header, before OpenImageIO decodes it (issue 33).

OpenImageIO decodes JPEG XL inside ``open()``: a 46 KB flat 16384^2 colour map cost 5 s
and 1 GiB before its size was compared with the project's.
"""

from __future__ import annotations

import numpy as np
import pytest
from terratheme.core.errors import CorruptFileError
from terratheme.core.io.codec import decode_image, encode_image
from terratheme.core.io.image_format import jpegxl_size
from terratheme.core.io.images import read_image

CONTAINER = b"\x00\x00\x00\x0cJXL \r\n\x87\n"


def bare_codestream(width: int, height: int) -> bytes:
    """A codestream signature and a SizeHeader (ISO/IEC 18181-1 D.2) declaring width x height,
    without div8 or ratio; then filler bytes (no image follows)."""
    fields = [(0, 1)]  # div8 = false
    for side in (height,):
        sel = next(i for i, b in enumerate((9, 13, 18, 30)) if side - 1 < 1 << b)
        fields += [(sel, 2), (side - 1, (9, 13, 18, 30)[sel])]
    fields.append((0, 3))  # ratio 0: the width follows
    sel = next(i for i, b in enumerate((9, 13, 18, 30)) if width - 1 < 1 << b)
    fields += [(sel, 2), (width - 1, (9, 13, 18, 30)[sel])]
    bits = pos = 0
    for value, n in fields:
        bits |= value << pos
        pos += n
    return b"\xff\x0a" + bits.to_bytes(12, "little") + bytes(64)


def in_container(stream: bytes, split: int) -> bytes:
    """``stream`` in a container as two jxlp boxes, the first ``split`` bytes long."""
    def box(kind: bytes, payload: bytes) -> bytes:
        return (8 + len(payload)).to_bytes(4, "big") + kind + payload
    return (CONTAINER + box(b"ftyp", b"jxl \x00\x00\x00\x00jxl ")
            + box(b"jxlp", bytes(4) + stream[:split])
            + box(b"jxlp", b"\x80\x00\x00\x01" + stream[split:]))


@pytest.mark.parametrize(("width", "height"), [
    (1, 1), (512, 1), (513, 8193), (16384, 16384), (262144, 3), (1 << 30, 7)])
def test_size_header_known_answers(width, height):
    stream = bare_codestream(width, height)
    assert jpegxl_size(stream) == (width, height)
    assert jpegxl_size(in_container(stream, 5)) == (width, height)


@pytest.mark.parametrize(("h", "w"), [(1, 1), (8, 16), (100, 37), (513, 1000), (9, 16)])
def test_size_of_encoded_images(h, w):
    data = encode_image(np.full((h, w, 3), 128, np.uint8), codec="jpegxl", quality=90)
    assert jpegxl_size(data) == (w, h)
    assert decode_image(data, codec="jpegxl", shape=(h, w)).shape[:2] == (h, w)


def test_not_a_size_header():
    assert jpegxl_size(b"") is None
    assert jpegxl_size(b"\x89PNG\r\n\x1a\n" + bytes(40)) is None
    assert jpegxl_size(CONTAINER + bytes(8)) is None


def test_a_forged_colour_map_size_is_refused_before_decoding():
    forged = in_container(bare_codestream(16384, 16384), 6)
    with pytest.raises(CorruptFileError, match="jpegxl image is 16384 x 16384, expected 4 x 4"):
        decode_image(forged, codec="jpegxl", shape=(4, 4))


def test_a_forged_jxl_file_is_refused_before_opening(tmp_path):
    path = tmp_path / "photo.jxl"
    path.write_bytes(in_container(bare_codestream(65536, 65536), 6))
    with pytest.raises(CorruptFileError, match="header declares 65536 x 65536"):
        read_image(path)
