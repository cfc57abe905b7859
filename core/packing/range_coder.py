"""Adaptive binary range coder (LZMA's) and the run models of the compact format (numba).

The models are specified in docs/formats.md (encoding 1). Encoders return ``(bytes
used, overflow)``; decoders an error code (0 fine, 1 read past the end, 2 impossible
symbol or length), so damaged input never crashes.
"""

from __future__ import annotations

import numba
import numpy as np

PROB_BITS = 15
PROB_INIT = 1 << (PROB_BITS - 1)
TOP = 1 << 24
MANTISSA_TREE_BITS = 6
P_RATE = 4
L_RATE = 5

# Encoder state slots: low, range, cache, cache_size, out position, overflow flag.
_LOW, _RANGE, _CACHE, _CSIZE, _POS, _OVER = range(6)


@numba.njit(cache=True, nogil=True, inline="always")
def _shift_low(st, out):  # pragma: no cover - numba
    low = st[_LOW]
    if low < np.uint64(0xFF000000) or low >= np.uint64(1 << 32):
        carry = low >> np.uint64(32)
        temp = st[_CACHE]
        while True:
            pos = st[_POS]
            if pos < out.size:
                out[pos] = np.uint8((temp + carry) & np.uint64(0xFF))
            else:
                st[_OVER] = 1
            st[_POS] = pos + np.uint64(1)
            temp = np.uint64(0xFF)
            st[_CSIZE] -= np.uint64(1)
            if st[_CSIZE] == 0:
                break
        st[_CACHE] = (low >> np.uint64(24)) & np.uint64(0xFF)
    st[_CSIZE] += np.uint64(1)
    st[_LOW] = (low & np.uint64(0x00FFFFFF)) << np.uint64(8)


@numba.njit(cache=True, nogil=True, inline="always")
def put_bit(st, out, p0, bit):  # pragma: no cover - numba
    """Encode ``bit`` with probability ``p0 / 2^15`` of a 0 (``1 <= p0 < 2^15``)."""
    bound = (st[_RANGE] >> np.uint64(PROB_BITS)) * np.uint64(p0)
    if bit == 0:
        st[_RANGE] = bound
    else:
        st[_LOW] += bound
        st[_RANGE] -= bound
    while st[_RANGE] < np.uint64(TOP):
        st[_RANGE] <<= np.uint64(8)
        _shift_low(st, out)


@numba.njit(cache=True, nogil=True, inline="always")
def get_bit(dec, buf, p0):  # pragma: no cover - numba
    """Decode one bit coded by :func:`put_bit` (``dec``: code, range, input position)."""
    bound = (dec[1] >> np.uint64(PROB_BITS)) * np.uint64(p0)
    if dec[0] < bound:
        dec[1] = bound
        bit = 0
    else:
        dec[0] -= bound
        dec[1] -= bound
        bit = 1
    while dec[1] < np.uint64(TOP):
        dec[1] <<= np.uint64(8)
        pos = dec[2]
        byte = np.uint64(buf[pos]) if pos < buf.size else np.uint64(0)
        dec[0] = ((dec[0] << np.uint64(8)) | byte) & np.uint64(0xFFFFFFFF)
        dec[2] = pos + np.uint64(1)
    return bit


@numba.njit(cache=True, nogil=True, inline="always")
def _encode_bit(st, out, probs, k, bit, rate):  # pragma: no cover - numba
    p = probs[k]
    put_bit(st, out, p, bit)
    probs[k] = p + (((1 << PROB_BITS) - p) >> rate) if bit == 0 else p - (p >> rate)


@numba.njit(cache=True, nogil=True, inline="always")
def _decode_bit(dec, buf, probs, k, rate):  # pragma: no cover - numba
    p = probs[k]
    bit = get_bit(dec, buf, p)
    probs[k] = p + (((1 << PROB_BITS) - p) >> rate) if bit == 0 else p - (p >> rate)
    return bit


@numba.njit(cache=True, nogil=True)
def start_encoder():  # pragma: no cover - numba
    """Fresh encoder state: low, range, cache, cache size, output position, overflow."""
    st = np.zeros(6, np.uint64)
    st[_RANGE] = np.uint64(0xFFFFFFFF)
    st[_CSIZE] = 1
    return st


@numba.njit(cache=True, nogil=True)
def finish_encoder(st, out):  # pragma: no cover - numba
    """Flush the encoder; returns (bytes written, overflow flag)."""
    for _ in range(5):
        _shift_low(st, out)
    return st[_POS], st[_OVER]


@numba.njit(cache=True, nogil=True)
def start_decoder(buf):  # pragma: no cover - numba
    """Decoder state (code, range, input position) after the stream's first 5 bytes."""
    dec = np.zeros(3, np.uint64)
    dec[1] = np.uint64(0xFFFFFFFF)
    for i in range(5):
        byte = np.uint64(buf[i]) if i < buf.size else np.uint64(0)
        dec[0] = ((dec[0] << np.uint64(8)) | byte) & np.uint64(0xFFFFFFFF)
    dec[2] = 5
    return dec


@numba.njit(cache=True, nogil=True)
def encode_symbols(sym, n_used, depth, pair_context, out):  # pragma: no cover - numba
    """Code palette-symbol ranks ``sym`` (< n_used) in the context of the previous two."""
    nctx = n_used * n_used if pair_context else n_used
    probs = np.full(nctx << depth, PROB_INIT, np.int64)
    st = start_encoder()
    p1 = 0
    p2 = 0
    for i in range(sym.size):
        base = ((p1 * n_used + p2) if pair_context else p1) << depth
        node = 1
        v = sym[i]
        for b in range(depth - 1, -1, -1):
            bit = (v >> b) & 1
            _encode_bit(st, out, probs, base + node, bit, P_RATE)
            node = node * 2 + bit
        p2 = p1
        p1 = v
    return finish_encoder(st, out)


@numba.njit(cache=True, nogil=True)
def decode_symbols(buf, count, n_used, depth, pair_context, sym):  # pragma: no cover - numba
    """Inverse of :func:`encode_symbols`; returns an error code."""
    nctx = n_used * n_used if pair_context else n_used
    probs = np.full(nctx << depth, PROB_INIT, np.int64)
    dec = start_decoder(buf)
    p1 = 0
    p2 = 0
    for i in range(count):
        base = ((p1 * n_used + p2) if pair_context else p1) << depth
        node = 1
        for _ in range(depth):
            node = node * 2 + _decode_bit(dec, buf, probs, base + node, P_RATE)
        v = node - (1 << depth)
        if v >= n_used:
            return 2
        sym[i] = v
        p2 = p1
        p1 = v
        # Reading past the end: stop now, not after the run count the header claims.
        if dec[2] > buf.size + 4:
            return 1
    return 0


@numba.njit(cache=True, nogil=True)
def _length_models(n_used):  # pragma: no cover - numba
    # The length coder's bit probabilities, the same for the encoder and the decoder: bit
    # length per symbol (6-level tree), prefix tree of the top mantissa bits, the others.
    return (np.full(n_used * 64, PROB_INIT, np.int64),
            np.full(n_used * 34 << (MANTISSA_TREE_BITS + 1), PROB_INIT, np.int64),
            np.full(34 * 34, PROB_INIT, np.int64))


@numba.njit(cache=True, nogil=True)
def encode_lengths(lengths, sym, n_used, out):  # pragma: no cover - numba
    """Code run lengths (>= 1, < 2^33) in the context of each run's symbol rank."""
    tb = MANTISSA_TREE_BITS
    pe, pm, pr = _length_models(n_used)
    st = start_encoder()
    for i in range(lengths.size):
        v = np.int64(lengths[i])
        c = sym[i]
        e = 0
        while (v >> (e + 1)) > 0:
            e += 1
        # Bit length of the run, down a 6-level tree per symbol.
        node = 1
        for b in range(5, -1, -1):
            bit = (e >> b) & 1
            _encode_bit(st, out, pe, c * 64 + node, bit, L_RATE)
            node = node * 2 + bit
        # Bits below the leading one: a prefix tree for the top ones, then per position.
        pref = 1
        for b in range(e - 1, -1, -1):
            bit = (v >> b) & 1
            if e - 1 - b < tb:
                _encode_bit(st, out, pm, ((c * 34 + e) << (tb + 1)) + pref, bit, L_RATE)
                pref = pref * 2 + bit
            else:
                _encode_bit(st, out, pr, e * 34 + b, bit, L_RATE)
    return finish_encoder(st, out)


@numba.njit(cache=True, nogil=True)
def decode_lengths(buf, sym, n_used, lengths):  # pragma: no cover - numba
    """Inverse of :func:`encode_lengths`; returns an error code."""
    tb = MANTISSA_TREE_BITS
    pe, pm, pr = _length_models(n_used)
    dec = start_decoder(buf)
    for i in range(sym.size):
        c = sym[i]
        node = 1
        for _ in range(6):
            node = node * 2 + _decode_bit(dec, buf, pe, c * 64 + node, L_RATE)
        e = node - 64
        if e > 32:
            return 2
        v = np.int64(1)
        pref = 1
        for b in range(e - 1, -1, -1):
            if e - 1 - b < tb:
                bit = _decode_bit(dec, buf, pm, ((c * 34 + e) << (tb + 1)) + pref, L_RATE)
                pref = pref * 2 + bit
            else:
                bit = _decode_bit(dec, buf, pr, e * 34 + b, L_RATE)
            v = (v << 1) | bit
        lengths[i] = v
        if dec[2] > buf.size + 4:
            return 1
    return 0
