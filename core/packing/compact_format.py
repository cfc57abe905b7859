"""The compact run payload (encoding 1, docs/formats.md): two separated, entropy-coded streams.

Palette indices and run lengths are coded apart, each by whichever is smaller for the
layer: :data:`Codec.MODEL` (the context models of :mod:`.range_coder`) or
:data:`Codec.ZSTD`, which wins where a map repeats long stretches of runs.
"""

from __future__ import annotations

import enum
import struct

import numpy as np
import zstandard
from terratheme.core.errors import CorruptFileError
from terratheme.core.packing import range_coder
from terratheme.core.packing.seed_format import decode_varint_stream, encode_varints

_HEAD = struct.Struct("<BBQQ")


class Codec(enum.IntEnum):
    """Entropy stage of one stream."""

    MODEL = 0
    ZSTD = 1


def _depth(n_used: int) -> int:
    return max(1, int(n_used - 1).bit_length())


def _model_symbols(sym: np.ndarray, n_used: int) -> bytes:
    depth = _depth(n_used)
    size = sym.size * depth * 3 // 8 + 64
    while True:
        out = np.empty(size, np.uint8)
        used, over = range_coder.encode_symbols(sym, n_used, depth, n_used <= 16, out)
        if not over:
            return out[: int(used)].tobytes()
        size *= 4


def _model_lengths(lengths: np.ndarray, sym: np.ndarray, n_used: int) -> bytes:
    size = lengths.size * 2 + 64
    while True:
        out = np.empty(size, np.uint8)
        used, over = range_coder.encode_lengths(lengths, sym, n_used, out)
        if not over:
            return out[: int(used)].tobytes()
        size *= 4


def _general(raw: bytes) -> dict[Codec, bytes]:
    return {Codec.ZSTD: zstandard.ZstdCompressor(level=19).compress(raw)}


def encode_runs(lengths: np.ndarray, indices: np.ndarray, palette_size: int) -> bytes:
    """Compact payload of runs (lengths >= 1, indices < palette_size)."""
    indices = np.asarray(indices, dtype=np.uint8)
    used = np.unique(indices)
    rank = np.zeros(256, dtype=np.int64)
    rank[used] = np.arange(used.size)
    sym = rank[indices]
    # Candidate encodings of each stream; keep the smallest.
    p_opts = {Codec.MODEL: _model_symbols(sym, used.size), **_general(indices.tobytes())}
    table, mask = encode_varints(lengths)
    l_opts = {Codec.MODEL: _model_lengths(np.asarray(lengths, np.int64), sym, used.size),
              **_general(table[mask].tobytes())}
    p_codec = min(p_opts, key=lambda c: len(p_opts[c]))
    l_codec = min(l_opts, key=lambda c: len(l_opts[c]))
    head = bytes([used.size - 1]) + used.astype(np.uint8).tobytes()
    head += _HEAD.pack(p_codec, l_codec, len(p_opts[p_codec]), len(l_opts[l_codec]))
    return head + p_opts[p_codec] + l_opts[l_codec]


def _inflate(data: bytes, name: str, what: str, limit: int) -> bytes:
    """A zstd stream's content, refused as soon as it would pass ``limit`` bytes.

    The frame header's declared size is checked first and the content is then
    read through a bounded stream reader, so neither a forged content size nor
    a decompression bomb can make the reader allocate more than ``limit``.
    """
    try:
        declared = zstandard.frame_content_size(data)
        if declared > limit:
            raise CorruptFileError(
                f"{name}: {what} stream declares {declared} bytes, at most {limit} expected")
        reader = zstandard.ZstdDecompressor().stream_reader(data)
        parts: list[bytes] = []
        size = 0
        while size <= limit:
            chunk = reader.read(min(1 << 20, limit + 1 - size))
            if not chunk:
                break
            parts.append(chunk)
            size += len(chunk)
    except zstandard.ZstdError as exc:
        raise CorruptFileError(f"{name}: damaged {what} stream ({exc})") from None
    if size > limit:
        raise CorruptFileError(f"{name}: {what} stream inflates past {limit} bytes")
    return b"".join(parts)


def decode_runs(
    payload: bytes, count: int, palette_size: int, *, name: str
) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of :func:`encode_runs`: ``count`` lengths (int64) and indices (uint8).

    Raises CorruptFileError for truncated or inconsistent streams, an unknown codec or
    impossible values.
    """
    if len(payload) < 1:
        raise CorruptFileError(f"{name}: empty run payload")
    n_used = payload[0] + 1
    start = 1 + n_used + _HEAD.size
    if len(payload) < start:
        raise CorruptFileError(f"{name}: truncated run payload header")
    used = np.frombuffer(payload, np.uint8, count=n_used, offset=1)
    p_codec, l_codec, p_len, l_len = _HEAD.unpack_from(payload, 1 + n_used)
    if p_codec not in Codec._value2member_map_ or l_codec not in Codec._value2member_map_:
        raise CorruptFileError(f"{name}: unknown stream codec ({p_codec}, {l_codec})")
    if start + p_len + l_len != len(payload):
        raise CorruptFileError(f"{name}: stream sizes do not match the payload size")
    if np.any(np.diff(used.astype(int)) <= 0):
        raise CorruptFileError(f"{name}: used-index list is not increasing")
    p_data = payload[start: start + p_len]
    l_data = payload[start + p_len:]
    # Palette indices first: the length model's contexts depend on them.
    if p_codec == Codec.MODEL:
        sym = np.empty(count, np.int64)
        err = range_coder.decode_symbols(np.frombuffer(p_data, np.uint8), count, n_used,
                                         _depth(n_used), n_used <= 16, sym)
        if err:
            raise CorruptFileError(f"{name}: damaged palette-index stream")
        indices = used[sym]
    else:
        raw = _inflate(p_data, name, "palette-index", count + 1)
        if len(raw) != count:
            raise CorruptFileError(f"{name}: palette-index stream holds {len(raw)} of {count}")
        indices = np.frombuffer(raw, np.uint8)
        rank = np.full(256, -1, dtype=np.int64)
        rank[used] = np.arange(n_used)
        sym = rank[indices]
        if sym.min() < 0:
            raise CorruptFileError(f"{name}: palette index outside the used-index list")
    if l_codec == Codec.MODEL:
        lengths = np.empty(count, np.int64)
        err = range_coder.decode_lengths(np.frombuffer(l_data, np.uint8), sym, n_used, lengths)
        if err:
            raise CorruptFileError(f"{name}: damaged run-length stream")
    else:
        raw = _inflate(l_data, name, "run-length", 5 * count + 1)
        lengths = decode_varint_stream(raw, count, name=name)
    return lengths, np.ascontiguousarray(indices, dtype=np.uint8)
