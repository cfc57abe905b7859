"""Context-mixing primitives: adaptive bit counters and a logistic mixer (numba).

As PAQ-family coders do (Mahoney, "Adaptive weighing of context models for lossless
data compression", 2005; lpaq1). Fixed point throughout, so encoder and decoder compute
the same numbers bit for bit; the arithmetic is specified in docs/formats.md (encoding 2).
"""

from __future__ import annotations

import numba
import numpy as np

_X = np.arange(-2047, 2048)
#: squash(x) for x = -2047 .. 2047 (logit * 256) -> P(1) in 1/4096, 1 .. 4095.
SQUASH = np.clip(np.round(4096.0 / (1.0 + np.exp(-_X / 256.0))), 1, 4095).astype(np.int32)
_P = (np.arange(4096) + 0.5) / 4096.0
#: stretch(p) for p = 0 .. 4095 (P(1) in 1/4096) -> logit * 256 in -2047 .. 2047.
STRETCH = np.clip(np.round(256.0 * np.log(_P / (1.0 - _P))), -2047, 2047).astype(np.int32)
#: Counter step 65536 / (n + 1.6) after n updates.
RATE = np.array([int(65536 / (n + 1.6)) for n in range(256)], np.int32)
#: Counters start at P(1) = 1/2.
COUNTER_INIT = 32768
for _table in (SQUASH, STRETCH, RATE):
    _table.setflags(write=False)


@numba.njit(cache=True, nogil=True, inline="always")
def squash(x):  # pragma: no cover - numba
    """12-bit probability of a logit scaled by 256 (clamped to +-2047)."""
    if x > 2047:
        x = 2047
    if x < -2047:
        x = -2047
    return np.int64(SQUASH[x + 2047])


@numba.njit(cache=True, nogil=True, inline="always")
def counter_p12(pr, i):  # pragma: no cover - numba
    """Counter ``i``'s ``P(1)`` in 1/4096 (1 .. 4095)."""
    p = np.int64(pr[i]) >> 4
    return 1 if p < 1 else (4095 if p > 4095 else p)


@numba.njit(cache=True, nogil=True, inline="always")
def counter_x(pr, i):  # pragma: no cover - numba
    """Counter ``i``'s prediction as a mixer input (stretched)."""
    return np.int64(STRETCH[np.int64(pr[i]) >> 4])


@numba.njit(cache=True, nogil=True, inline="always")
def counter_update(pr, cn, i, bit, limit):  # pragma: no cover - numba
    """Move counter ``i`` towards ``bit`` and count the update (up to ``limit``)."""
    n = cn[i]
    p = np.int64(pr[i])
    if bit:
        p += ((65536 - p) * RATE[n]) >> 16
    else:
        p -= (p * RATE[n]) >> 16
    pr[i] = 32 if p < 32 else (65504 if p > 65504 else p)
    if n < limit:
        cn[i] = n + 1


@numba.njit(cache=True, nogil=True, inline="always")
def mix(w, row, x, n):  # pragma: no cover - numba
    """The mixer's 12-bit ``P(1)``: weights ``w[row, :n]`` over inputs ``x[:n]``."""
    dot = np.int64(0)
    for i in range(n):
        dot += w[row, i] * x[i]
    return squash(dot >> 16)


@numba.njit(cache=True, nogil=True, inline="always")
def mix_update(w, row, x, n, p12, bit, rate):  # pragma: no cover - numba
    """Train weight set ``row`` after coding ``bit`` that the mixer gave ``p12``."""
    err = ((np.int64(bit) << 12) - p12) * rate
    for i in range(n):
        w[row, i] += (x[i] * err) >> 14
