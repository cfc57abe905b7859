"""Damaged or hostile packed-layer files: always a clear error, never a crash."""

from __future__ import annotations

import os
import struct
import zlib

import numpy as np
import pytest
import terratheme.core.io.atomic
import zstandard
from hypothesis import given, settings
from hypothesis import strategies as st
from terratheme.core.errors import CorruptFileError, TerrathemeError, UnsupportedVersionError
from terratheme.core.packing import PackedLayer, pack

HEADER = struct.Struct("<4sBBBBBBHIIQQ")


def _file(*, width=4, height=2, runs=(), k=2, identity=True, encoding=0, version=1,
          magic=b"TTPK", payload=None, palette=b"", channels=1) -> bytes:
    """A layer file written by hand (independent of the encoder): seed encoding by default."""
    if payload is None:
        # Seed pairs: one-byte varints (high bit = last byte) then P.
        payload = b"".join(bytes([0x80 | n, p]) for n, p in runs)
    flags = 1 | (2 if identity else 0)
    head = HEADER.pack(magic, version, encoding, 0, flags, channels, 1, k, width, height,
                       len(runs), len(payload))
    body = head + palette + payload
    return body + struct.pack("<I", zlib.crc32(body))


def _load(tmp_path, data: bytes) -> PackedLayer:
    path = tmp_path / "layer.ttp"
    path.write_bytes(data)
    return PackedLayer.load(path)


def test_hand_written_file_loads(tmp_path):
    # 4 x 2 image, Hilbert: 3 texels of 0 then 5 of 1.
    layer = _load(tmp_path, _file(runs=[(3, 0), (5, 1)]))
    assert layer.lengths.tolist() == [3, 5]
    assert layer.unpack().sum() == 5


@pytest.fixture
def good(tmp_path) -> bytes:
    img = np.random.default_rng(0).integers(0, 3, (20, 30)).astype(np.uint8)
    return pack(img).to_bytes(format="compact")


@pytest.mark.parametrize("cut", [0, 3, 10, 36, -30, -5, -1])
def test_truncated_file(tmp_path, good, cut):
    with pytest.raises(CorruptFileError, match="truncated|empty"):
        _load(tmp_path, good[:cut])


def test_wrong_magic(tmp_path, good):
    with pytest.raises(CorruptFileError, match="not a terratheme packed layer"):
        _load(tmp_path, b"\x89PNG" + good[4:])


def test_png_is_not_a_layer(tmp_path):
    with pytest.raises(CorruptFileError, match="magic"):
        _load(tmp_path, b"\x89PNG\r\n\x1a\n" + bytes(100))


@pytest.mark.parametrize("where", [40, 60, -8])
def test_bad_checksum(tmp_path, good, where):
    data = bytearray(good)
    data[where] ^= 0x40
    with pytest.raises(CorruptFileError, match="checksum"):
        _load(tmp_path, bytes(data))


def test_newer_version(tmp_path):
    with pytest.raises(UnsupportedVersionError, match="version 3; this build reads up to 2"):
        _load(tmp_path, _file(runs=[(8, 0)], version=3))


def _compact_payload(indices: bytes, lengths: bytes, *, used=(0, 1), codecs=(1, 1)) -> bytes:
    """A compact (encoding 1) payload by hand: used-index list, codecs, stream sizes, streams."""
    head = bytes([len(used) - 1, *used]) + struct.pack("<BBQQ", *codecs, len(indices),
                                                        len(lengths))
    return head + indices + lengths


def test_hand_written_version_1_compact_file_loads(tmp_path):
    # Both streams through zstd: P bytes, and the seed's varints (high bit on the last byte).
    zc = zstandard.ZstdCompressor(level=3)
    payload = _compact_payload(zc.compress(bytes([0, 1])), zc.compress(bytes([0x83, 0x85])))
    data = _file(runs=[(3, 0), (5, 1)], payload=payload, encoding=1)
    layer = _load(tmp_path, data)
    assert layer.lengths.tolist() == [3, 5] and layer.P.tolist() == [0, 1]


def _with_runs(data: bytes, runs: int) -> bytes:
    body = bytearray(data[:-4])
    struct.pack_into("<Q", body, 20, runs)
    return bytes(body) + struct.pack("<I", zlib.crc32(body))


def test_tiny_file_declaring_2_30_runs_fails_at_once(tmp_path):
    # 70 bytes claiming 2^30 runs of a 65536 x 65536 layer: refused from the header alone.
    payload = _compact_payload(b"\x00" * 4, b"\x00" * 5, codecs=(0, 0))
    data = _with_runs(_file(width=65536, height=65536, runs=[(1, 0)], payload=payload,
                            encoding=1), 1 << 30)
    assert len(data) == 70
    with pytest.raises(CorruptFileError, match="1073741824 runs in 30 payload bytes"):
        _load(tmp_path, data)


def test_zstd_frame_declaring_a_huge_size(tmp_path):
    zc = zstandard.ZstdCompressor(level=3, write_content_size=True)
    frame = bytearray(zc.compress(bytes(64)))
    # Forge the declared content size (frame header: magic, descriptor, ... size field).
    huge = zc.compress(b"")[:4] + bytes([0xE0]) + struct.pack("<Q", 1 << 40) + bytes(frame[-3:])
    payload = _compact_payload(huge, zc.compress(bytes([0x83, 0x85])))
    with pytest.raises(CorruptFileError, match="palette-index stream"):
        _load(tmp_path, _file(runs=[(3, 0), (5, 1)], payload=payload, encoding=1))


@pytest.mark.parametrize("declared_size", [True, False])
def test_zstd_bomb_is_cut_at_the_expected_size(tmp_path, declared_size):
    # 16 MiB of zeros in about 600 bytes, where two runs need two index bytes.
    zc = zstandard.ZstdCompressor(level=19, write_content_size=declared_size)
    bomb = zc.compress(bytes(16 << 20))
    payload = _compact_payload(bomb, zc.compress(bytes([0x83, 0x85])))
    with pytest.raises(CorruptFileError, match="declares|inflates past"):
        _load(tmp_path, _file(runs=[(3, 0), (5, 1)], payload=payload, encoding=1))


def test_run_lengths_overrun_the_image(tmp_path):
    with pytest.raises(CorruptFileError, match="cover 9 texels but the image has 4 x 2 = 8"):
        _load(tmp_path, _file(runs=[(3, 0), (6, 1)]))


def test_run_lengths_fall_short(tmp_path):
    with pytest.raises(CorruptFileError, match="cover 7 texels"):
        _load(tmp_path, _file(runs=[(3, 0), (4, 1)]))


def test_zero_length_run(tmp_path):
    with pytest.raises(CorruptFileError, match="at least 1"):
        _load(tmp_path, _file(runs=[(0, 0), (8, 1)]))


def test_palette_index_out_of_range(tmp_path):
    with pytest.raises(CorruptFileError, match="palette index 5 out of range"):
        _load(tmp_path, _file(runs=[(3, 0), (5, 5)], k=2))


def test_colour_palette_index_out_of_range(tmp_path):
    data = _file(runs=[(4, 0), (4, 2)], k=2, identity=False, palette=bytes([10, 20]))
    with pytest.raises(CorruptFileError, match="palette index 2 out of range"):
        _load(tmp_path, data)


@pytest.mark.parametrize("w,h", [(0, 0), (0, 5), (70000, 1), (65537, 65536)])
def test_bad_size_in_header(tmp_path, w, h):
    with pytest.raises(CorruptFileError, match="bad header"):
        _load(tmp_path, _file(width=w, height=h, runs=[(1, 0)]))


def test_varint_too_long_and_stream_truncated(tmp_path):
    six = bytes([0, 0, 0, 0, 0, 0x81, 0])
    with pytest.raises(CorruptFileError, match="longer than 5 bytes"):
        _load(tmp_path, _file(runs=[(8, 0)], payload=six))
    with pytest.raises(CorruptFileError, match="truncated after 1 of 2"):
        _load(tmp_path, _file(runs=[(3, 0), (5, 1)], payload=bytes([0x83, 0, 0x05, 0x85])))


def test_header_run_count_larger_than_stream(tmp_path):
    data = _file(runs=[(8, 0)])
    body = bytearray(data[:-4])
    struct.pack_into("<Q", body, 20, 5)
    with pytest.raises(CorruptFileError, match="announces 5 runs"):
        _load(tmp_path, bytes(body) + struct.pack("<I", zlib.crc32(body)))


@settings(max_examples=60, deadline=None)
@given(st.binary(min_size=0, max_size=200), st.sampled_from([0, 1]))
def test_random_payload_with_valid_checksum(tmp_path_factory, payload, encoding):
    # Garbage behind a valid header and checksum: a clean error or a layer that is whole.
    data = _file(runs=[(4, 0), (4, 1)], payload=payload, encoding=encoding)
    data = bytearray(data)
    struct.pack_into("<Q", data, 20, 2)
    body = bytes(data[:-4])
    path = tmp_path_factory.mktemp("fuzz") / "f.ttp"
    path.write_bytes(body + struct.pack("<I", zlib.crc32(body)))
    try:
        layer = PackedLayer.load(path)
    except CorruptFileError:
        return
    assert layer.lengths.sum() == 8 and layer.unpack().shape == (2, 4)


def test_empty_image_and_missing_file(tmp_path):
    with pytest.raises(TerrathemeError, match="0 x 0 texels"):
        pack(np.zeros((0, 0), np.uint8))
    with pytest.raises(TerrathemeError, match="no such file"):
        PackedLayer.load(tmp_path / "missing.ttp")
    with pytest.raises(CorruptFileError, match="empty"):
        _load(tmp_path, b"")


def test_failed_write_leaves_no_file(tmp_path, monkeypatch):
    layer = pack(np.zeros((5, 5), np.uint8))
    target = tmp_path / "out.ttp"
    target.write_bytes(b"old content")

    def failing_replace(src, dst):
        raise OSError("disk full")

    monkeypatch.setattr(terratheme.core.io.atomic.os, "replace", failing_replace)
    with pytest.raises(OSError, match="disk full"):
        layer.save(target)
    assert target.read_bytes() == b"old content"
    assert os.listdir(tmp_path) == ["out.ttp"]


def test_unknown_format_name(tmp_path):
    layer = pack(np.zeros((5, 5), np.uint8))
    with pytest.raises(TerrathemeError, match="unknown packed format 'png'"):
        layer.save(tmp_path / "x.ttp", format="png")
    assert not (tmp_path / "x.ttp").exists()
