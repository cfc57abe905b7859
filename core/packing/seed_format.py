"""The seed's run stream (seed section 2.4): run lengths as varints, each followed by ``P``.

A length is written in groups of 7 value bits, least significant group first;
the high bit of a byte is **1 on the last byte** of a number and 0 before it
(the inverse of LEB128; ``vectors/sfc_8x8.json`` has worked examples). Each
run is the pair ``<length, P>``: the varint, then one byte of palette index.
"""

from __future__ import annotations

import numba
import numpy as np
from terratheme.core.errors import CorruptFileError

#: A run length is at most 2^32 texels (a 65536^2 layer): 5 varint bytes.
MAX_VARINT_BYTES = 5


def encode_varints(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(table, used)``, (R, 5) uint8 and bool: byte ``k`` of value ``i``'s varint, and which
    bytes belong to it (values < 2^35).
    """
    v = np.asarray(values, dtype=np.uint64)
    # Number of 7-bit groups: at least one, even for 0.
    nbytes = np.ones(v.shape, dtype=np.int64)
    for k in range(1, MAX_VARINT_BYTES):
        nbytes += v >= np.uint64(1 << (7 * k))
    shifts = np.arange(MAX_VARINT_BYTES, dtype=np.uint64) * np.uint64(7)
    table = ((v[:, None] >> shifts[None, :]) & np.uint64(0x7F)).astype(np.uint8)
    k = np.arange(MAX_VARINT_BYTES)[None, :]
    # The high bit marks the last byte of each number.
    table[k == (nbytes[:, None] - 1)] |= 0x80
    return table, k < nbytes[:, None]


def encode_seed_runs(lengths: np.ndarray, indices: np.ndarray) -> bytes:
    """Interleaved ``<varint length, P byte>`` pairs of runs (lengths >= 1, uint8 indices)."""
    table, used = encode_varints(lengths)
    # One row per run: its varint bytes then its palette index; keep the used cells in order.
    rows = np.concatenate([table, np.asarray(indices, np.uint8)[:, None]], axis=1)
    keep = np.concatenate([used, np.ones((used.shape[0], 1), bool)], axis=1)
    return rows[keep].tobytes()


@numba.njit(cache=True, nogil=True)
def _decode_kernel(buf, count, lengths, indices, paired):  # pragma: no cover - numba
    # Returns (runs decoded, bytes used, error code): 1 = truncated, 2 = varint too long.
    pos = 0
    n = buf.size
    for r in range(count):
        value = np.uint64(0)
        shift = np.uint64(0)
        k = 0
        while True:
            if pos >= n:
                return r, pos, 1
            byte = buf[pos]
            pos += 1
            value |= np.uint64(byte & 0x7F) << shift
            shift += np.uint64(7)
            k += 1
            if byte & 0x80:
                break
            if k == 5:
                return r, pos, 2
        lengths[r] = value
        if paired:
            # The run's palette index byte follows its length.
            if pos >= n:
                return r, pos, 1
            indices[r] = buf[pos]
            pos += 1
    return count, pos, 0


def decode_seed_runs(payload: bytes, count: int, *, name: str) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of :func:`encode_seed_runs`: ``count`` lengths (int64) and indices (uint8).

    Raises CorruptFileError for a stream that ends early, an over-long varint, or bytes left over.
    """
    buf = np.frombuffer(payload, dtype=np.uint8)
    if count > buf.size // 2:
        raise CorruptFileError(
            f"{name}: header announces {count} runs but the run stream has {buf.size} bytes"
        )
    lengths = np.empty(count, dtype=np.int64)
    indices = np.empty(count, dtype=np.uint8)
    _check(_decode_kernel(buf, count, lengths, indices, True), buf.size, count, name)
    return lengths, indices


def decode_varint_stream(raw: bytes, count: int, *, name: str) -> np.ndarray:
    """``count`` back-to-back varints as (count,) int64 (the compact format's raw length stream)."""
    buf = np.frombuffer(raw, dtype=np.uint8)
    if count > buf.size:
        raise CorruptFileError(f"{name}: {count} run lengths announced, {buf.size} bytes stored")
    lengths = np.empty(count, dtype=np.int64)
    _check(_decode_kernel(buf, count, lengths, lengths[:0].astype(np.uint8), False),
           buf.size, count, name)
    return lengths


def _check(result: tuple[int, int, int], size: int, count: int, name: str) -> None:
    done, used, err = result
    if err == 1:
        raise CorruptFileError(f"{name}: run stream truncated after {done} of {count} runs")
    if err == 2:
        raise CorruptFileError(f"{name}: run {done} has a varint longer than 5 bytes")
    if used != size:
        raise CorruptFileError(f"{name}: {size - used} bytes left over after the {count} runs")
