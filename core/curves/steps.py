"""The curves themselves: point <-> curve step on the ``2^n`` square, y up (seed
sfc_packing.txt, section 1; orientation in design.md §4, ``vectors/sfc_8x8.json``).
"""

from __future__ import annotations

import numba
import numpy as np

# One implementation of each curve, as scalar numba functions: the packed layer's
# lookups call them per texel (core.packing.lookup); the array functions loop over them.

# Hilbert state machine (2 bits: swap, flip-both): entry [state*4 + (x_bit*2 + y_bit)]
# holds (digit << 2) | next_state, the table form of Hacker's Delight's xy2d.
_TABLE = np.zeros(16, dtype=np.uint8)
for _state in range(4):
    for _xb in range(2):
        for _yb in range(2):
            _rx, _ry = (_xb ^ 1, _yb ^ 1) if _state & 2 else (_xb, _yb)
            if _state & 1:
                _rx, _ry = _ry, _rx
            _digit = (3 * _rx) ^ _ry
            _next = _state
            if _ry == 0:
                _next ^= 1 | (2 if _rx == 1 else 0)
            _TABLE[_state * 4 + _xb * 2 + _yb] = (_digit << 2) | _next
# Four levels at once: [state*256 + (x 4 bits)*16 + (y 4 bits)] -> (8-bit digits << 2) | state.
_TABLE4 = np.zeros(1024, dtype=np.uint16)
for _state in range(4):
    for _x4 in range(16):
        for _y4 in range(16):
            _s, _d = _state, 0
            for _lv in range(3, -1, -1):
                _e = int(_TABLE[_s * 4 + ((_x4 >> _lv) & 1) * 2 + ((_y4 >> _lv) & 1)])
                _d, _s = (_d << 2) | (_e >> 2), _e & 3
            _TABLE4[_state * 256 + _x4 * 16 + _y4] = (_d << 2) | _s
#: One-level table (16 entries) then four-level table (1024) of the Hilbert state machine.
HILBERT_TABLES = np.concatenate([_TABLE.astype(np.uint16), _TABLE4])
HILBERT_TABLES.setflags(write=False)


@numba.njit(cache=True, nogil=True, inline="always")
def hilbert_walk(x, y, n, tables, start=0):  # pragma: no cover - numba
    """0-based Hilbert step of ``(x, y)`` (y up) on the ``2^n`` square, and the final state.

    ``tables`` is :data:`HILBERT_TABLES` (any integer dtype). The state's
    bit 0 = swap x/y, bit 1 = flip both (the transforms of Hacker's Delight /
    Wikipedia's ``rot``, which commute, so two bits describe their composition).
    ``start`` is the state the walk begins in: the local step of a texel in a
    block whose pattern is that state (:func:`core.curves.plan._patterns`).
    """
    d = np.uint64(0)
    state = start
    level = n
    # Leading levels one at a time until a multiple of four remain.
    while level % 4 != 0:
        level -= 1
        e = tables[state * 4 + ((x >> level) & 1) * 2 + ((y >> level) & 1)]
        d = (d << np.uint64(2)) | np.uint64(e >> 2)
        state = e & 3
    # Then four levels per table lookup.
    while level > 0:
        level -= 4
        e = tables[16 + state * 256 + ((x >> level) & 15) * 16 + ((y >> level) & 15)]
        d = (d << np.uint64(8)) | np.uint64(e >> 2)
        state = e & 3
    return d, state


@numba.njit(cache=True, nogil=True, inline="always")
def hilbert_point(d, n):  # pragma: no cover - numba
    """``(x, y)`` (y up) of 0-based Hilbert step ``d`` on the ``2^n`` square."""
    t = np.int64(d)
    x = np.int64(0)
    y = np.int64(0)
    for level in range(n):
        s = np.int64(1) << level
        # The two step bits of this level give the quadrant.
        rx = 1 & (t >> 1)
        ry = 1 & (t ^ rx)
        # Undo the rotation of the lower levels (Hacker's Delight, p. 284).
        if ry == 0:
            if rx == 1:
                x = s - 1 - x
                y = s - 1 - y
            x, y = y, x
        x += s * rx
        y += s * ry
        t >>= 2
    return x, y


@numba.njit(cache=True, nogil=True, inline="always")
def _spread(v):  # pragma: no cover - numba
    # Insert a zero bit above each of the low 32 bits (magic-number bit spreading).
    v = v & np.uint64(0xFFFFFFFF)
    v = (v | (v << np.uint64(16))) & np.uint64(0x0000FFFF0000FFFF)
    v = (v | (v << np.uint64(8))) & np.uint64(0x00FF00FF00FF00FF)
    v = (v | (v << np.uint64(4))) & np.uint64(0x0F0F0F0F0F0F0F0F)
    v = (v | (v << np.uint64(2))) & np.uint64(0x3333333333333333)
    return (v | (v << np.uint64(1))) & np.uint64(0x5555555555555555)


@numba.njit(cache=True, nogil=True, inline="always")
def _compact(v):  # pragma: no cover - numba
    # Inverse of _spread: keep every second bit.
    v = v & np.uint64(0x5555555555555555)
    v = (v | (v >> np.uint64(1))) & np.uint64(0x3333333333333333)
    v = (v | (v >> np.uint64(2))) & np.uint64(0x0F0F0F0F0F0F0F0F)
    v = (v | (v >> np.uint64(4))) & np.uint64(0x00FF00FF00FF00FF)
    v = (v | (v >> np.uint64(8))) & np.uint64(0x0000FFFF0000FFFF)
    return (v | (v >> np.uint64(16))) & np.uint64(0x00000000FFFFFFFF)


@numba.njit(cache=True, nogil=True, inline="always")
def morton_step(x, y):  # pragma: no cover - numba
    """0-based Morton step ``Z = sum((x_i + 2*y_i) * 4^i)`` (seed section 1) of ``(x, y)``."""
    return _spread(np.uint64(x)) | (_spread(np.uint64(y)) << np.uint64(1))


@numba.njit(cache=True, nogil=True, inline="always")
def morton_point(d):  # pragma: no cover - numba
    """``(x, y)`` (y up) of 0-based Morton step ``d``."""
    d = np.uint64(d)
    return np.int64(_compact(d)), np.int64(_compact(d >> np.uint64(1)))


@numba.njit(cache=True, nogil=True)
def _hilbert_many(xs, ys, n, tables, d, state):  # pragma: no cover - numba
    for k in range(xs.size):
        d[k], state[k] = hilbert_walk(xs[k], ys[k], n, tables)


@numba.njit(cache=True, nogil=True)
def _hilbert_points(ds, n, xs, ys):  # pragma: no cover - numba
    for k in range(ds.size):
        xs[k], ys[k] = hilbert_point(ds[k], n)


@numba.njit(cache=True, nogil=True)
def _morton_many(xs, ys, d):  # pragma: no cover - numba
    for k in range(xs.size):
        d[k] = morton_step(xs[k], ys[k])


@numba.njit(cache=True, nogil=True)
def _morton_points(ds, xs, ys):  # pragma: no cover - numba
    for k in range(ds.size):
        xs[k], ys[k] = morton_point(ds[k])


def _flat_pair(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, tuple]:
    x, y = np.broadcast_arrays(np.asarray(x, dtype=np.int64), np.asarray(y, dtype=np.int64))
    return np.ascontiguousarray(x).reshape(-1), np.ascontiguousarray(y).reshape(-1), x.shape


def hilbert_xy2d(x: np.ndarray, y: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Hilbert step ``d`` (uint64) and final state (uint8, :func:`hilbert_walk`) of ``(x, y)``.

    ``x, y`` are integer arrays in ``[0, 2^n)``, origin bottom-left, y up; the first
    move from (0, 0) is to (0, 1).
    """
    xs, ys, shape = _flat_pair(x, y)
    d = np.empty(xs.size, np.uint64)
    state = np.empty(xs.size, np.uint8)
    _hilbert_many(xs, ys, int(n), HILBERT_TABLES, d, state)
    return d.reshape(shape), state.reshape(shape)


def hilbert_d2xy(d: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of :func:`hilbert_xy2d`: int64 ``(x, y)`` (y up) of 0-based steps ``d``."""
    d = np.asarray(d, dtype=np.uint64)
    flat = np.ascontiguousarray(d).reshape(-1).astype(np.int64)
    xs, ys = np.empty(flat.size, np.int64), np.empty(flat.size, np.int64)
    _hilbert_points(flat, int(n), xs, ys)
    return xs.reshape(d.shape), ys.reshape(d.shape)


def morton_xy2d(x: np.ndarray, y: np.ndarray, n: int) -> np.ndarray:
    """Morton (Z) step ``Z = sum((x_i + 2*y_i) * 4^i)`` (seed section 1), ``y`` up."""
    xs, ys, shape = _flat_pair(x, y)
    d = np.empty(xs.size, np.uint64)
    _morton_many(xs, ys, d)
    return d.reshape(shape)


def morton_d2xy(d: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of :func:`morton_xy2d`: ``(x, y)`` int64 ndarrays, ``y`` up."""
    d = np.asarray(d, dtype=np.uint64)
    flat = np.ascontiguousarray(d).reshape(-1)
    xs, ys = np.empty(flat.size, np.int64), np.empty(flat.size, np.int64)
    _morton_points(flat, xs, ys)
    return xs.reshape(d.shape), ys.reshape(d.shape)
