"""The seed's family of prefiltered copies (Kovalev & Tarasov, section
"filtering of the source texture" and its table).

For a tiling ``N x N`` texture (``N = 2^n``) and every pair ``(a, b)``,
``0 <= b <= a <= n``, ``a - b <= k``, the family holds copies box-filtered
over a parallelogram of full height ``H = 2^a`` along its long side and full
base ``L = 2^b`` across it, sampled every ``H`` texels along the long axis
(``max(H / long_oversampling, L)``: the lattice is never denser along the long
side than across, so ``lambda = 1`` copies stay plain mip levels) and every
``L`` texels along the short one. With
``lambda = H/L = 2^i`` there are about ``lambda`` copies, half tilted toward
U and half toward V, one per skew ``tan`` spaced ``2^(2-i)`` apart as in the
seed (``skew_oversampling`` divides the spacing; see :func:`skew_values` for
the grid through 0). ``lambda = 1`` is the ordinary mip level (the seed's
"diagonal").

With the seed's settings each ``(a, b)`` cell costs ``N^2 / 4^b`` texels
whatever ``a`` is, so the family costs about ``(k + 1) * 4/3 * N^2`` texels
(the seed's ``n * 4/3 * 4^n`` when ``k = n``); the oversampling factors
multiply that (``long_oversampling`` only for ``lambda > 1``, up to ``lambda``).
The defaults (one skew grid, ``long_oversampling = 2``, ``k = 4``) cost about
``14.4 N^2`` texels: 43 bytes per RGB uint8 texel.
:attr:`ParallelogramFamily.nbytes` is the exact figure.

Copies tilted toward V are built from, and stored in the frame of, the
transposed texture, so one lookup routine serves both orientations.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from core.perspective.texture import box_halve


def skew_half(i: int, oversampling: int = 1) -> int:
    """``q``: skews at ``lambda = 2^i`` are ``tan = 2 j / c`` for ``|j| <= q``,
    ``c = oversampling * 2^(i-1)`` (``q = 0``: only ``tan = 0``)."""
    return 0 if i == 0 else (oversampling * (1 << (i - 1))) // 2


def skew_count(i: int, oversampling: int = 1) -> int:
    """Copies per orientation at ``lambda = 2^i``."""
    return 2 * skew_half(i, oversampling) + 1


def skew_values(i: int, oversampling: int = 1) -> np.ndarray:
    """The skews ``tan`` prefiltered at ``lambda = 2^i``: ``(count,) float64``.

    The seed's spacing ``2^(2-i)`` (divided by ``oversampling``), but on a grid
    through 0 (the seed's grid is offset by half a step and misses the
    axis-aligned footprint, the commonest one): ``i = 1``: ``[0]``; ``i = 2``:
    ``[-1, 0, 1]``; ``i = 3``: ``[-1, -0.5, 0, 0.5, 1]``.
    """
    if i == 0:
        return np.zeros(1)
    c = oversampling * (1 << (i - 1))
    q = skew_half(i, oversampling)
    return 2.0 * np.arange(-q, q + 1) / c


@njit(cache=True, parallel=True)
def skewed_box(g, a, b, tan, cols):
    """One copy: the box average along the skewed long side.

    Parameters
    ----------
    g : (N >> b, N, C) float32 ndarray
        The texture box-averaged over ``2^b`` rows (across the long side).
    a, b : int
        ``H = 2^a``, ``L = 2^b``.
    tan : float
        Slope of the long side: ``tan`` texels along V per texel along U.
    cols : int
        Samples along the long side (``N >> a`` in the seed, more when
        oversampled).

    Returns
    -------
    (N >> b, cols, C) float32 ndarray
        Sample ``(m, k)`` is centred at ``u = (k + 0.5) N / cols``,
        ``v = (m + 0.5) 2^b``.
    """
    rows, n, nc = g.shape
    half = 0.5 * (1 << a)
    step = n / cols
    slope = tan / (1 << b)
    out = np.zeros((rows, cols, nc), np.float32)
    inv = 1.0 / (2.0 * half)
    for m in prange(rows):
        acc = np.zeros(nc)
        for k in range(cols):
            acc[:] = 0.0
            uc = (k + 0.5) * step
            lo = uc - half
            hi = uc + half
            # texel columns under the long side, weighted by their overlap and
            # read where the tilted centre line crosses them (linear between rows)
            for col in range(int(np.floor(lo)), int(np.ceil(hi))):
                wt = min(col + 1.0, hi) - max(float(col), lo)
                if wt <= 0.0:
                    continue
                y = m + slope * (col + 0.5 - uc)
                fl = np.floor(y)
                fy = y - fl
                j0 = int(fl) % rows
                j1 = (j0 + 1) % rows
                cc = col % n
                for c in range(nc):
                    acc[c] += wt * ((1.0 - fy) * g[j0, cc, c] + fy * g[j1, cc, c])
            for c in range(nc):
                out[m, k, c] = acc[c] * inv
    return out


def copy_columns(n_size: int, a: int, b: int, long_oversampling: int) -> int:
    """Samples along the long side of a copy with ``H = 2^a``, ``L = 2^b``:
    ``long_oversampling`` per ``H``, but never closer than ``L`` apart (so the
    ``lambda = 1`` copies are the plain mip levels)."""
    return min(n_size >> b, (n_size >> a) * long_oversampling)


@dataclass(frozen=True)
class ParallelogramFamily:
    """All prefiltered copies, packed for the lookup kernel.

    Attributes
    ----------
    buf : (T, C) float32 ndarray
        Every copy, row-major, one after another.
    table : (2, n+1, n+1, S) int64 ndarray
        ``table[o, a, b, s]``: start in ``buf`` of the copy tilted toward U
        (``o = 0``) or V (``o = 1``) with ``H = 2^a, L = 2^b`` and skew index
        ``s``; -1 where no such copy. Copy ``(o, a, b)`` is
        ``(N >> b) x (N >> a)`` in its own frame (transposed for ``o = 1``).
    size : int
        ``N``.
    max_lambda_log2 : int
        ``k``: copies exist for ``a - b <= k``.
    skew_oversampling, long_oversampling : int
    """

    buf: np.ndarray
    table: np.ndarray
    size: int
    max_lambda_log2: int
    skew_oversampling: int
    long_oversampling: int

    @property
    def nbytes(self) -> int:
        """Memory of the prefiltered texels (the table is negligible)."""
        return int(self.buf.nbytes)

    @property
    def texel_count(self) -> int:
        return int(self.buf.shape[0])

    def copy(self, toward: int, a: int, b: int, s: int) -> np.ndarray:
        """One copy as a ``(N >> b, cols, C)`` view (in its own frame)."""
        off = int(self.table[toward, a, b, s])
        if off < 0:
            raise KeyError(f"no copy toward={toward} a={a} b={b} s={s}")
        rows, cols = self.size >> b, copy_columns(self.size, a, b, self.long_oversampling)
        return self.buf[off : off + rows * cols].reshape(rows, cols, -1)


def _layout(nsz: int, k: int, skew_oversampling: int, long_oversampling: int):
    """Where every copy goes: ``(table, total_texels, jobs)``, jobs being
    ``(toward, a, b, s, tan, offset)`` in build order."""
    n = int(nsz).bit_length() - 1
    smax = skew_count(k, skew_oversampling) if k > 0 else 1
    table = np.full((2, n + 1, n + 1, smax), -1, np.int64)
    jobs = []
    offset = 0
    for toward in (0, 1):
        for b in range(n + 1):
            for a in range(b, min(n, b + k) + 1):
                if a == b and toward == 1:
                    continue
                for s, tan in enumerate(skew_values(a - b, skew_oversampling)):
                    table[toward, a, b, s] = offset
                    jobs.append((toward, a, b, s, float(tan), offset))
                    offset += (nsz >> b) * copy_columns(nsz, a, b, long_oversampling)
    return table, offset, jobs


def build_family(square: np.ndarray, max_lambda_log2: int, skew_oversampling: int = 1,
                 long_oversampling: int = 1, progress=None,
                 dtype: np.dtype | type = np.float32) -> ParallelogramFamily:
    """Prefilter the family of copies.

    Parameters
    ----------
    square : (N, N, C) float32 ndarray, N = 2^n
    max_lambda_log2 : int
        ``k``: largest ``log2(H/L)`` prefiltered.
    skew_oversampling : int
        Power of two multiplying the seed's number of skews.
    long_oversampling : int
        Power of two multiplying the seed's resolution along the long side.
    progress : callable(done, total) or None
    dtype : float32, uint8 or uint16
        Storage type; integer types hold ``round(value * max)`` (values in [0, 1]).
        Copies are filtered in floating point and written straight into one
        preallocated buffer, so the peak memory is the family plus one copy.
    """
    nsz = square.shape[0]
    n = int(nsz).bit_length() - 1
    k = max(0, min(int(max_lambda_log2), n))
    dt = np.dtype(dtype)
    top = float(np.iinfo(dt).max) if dt.kind == "u" else None
    table, total_texels, jobs = _layout(nsz, k, skew_oversampling, long_oversampling)
    buf = np.empty((total_texels, square.shape[2]), dt)
    g = None
    current = (-1, -1)
    for done, (toward, a, b, _s, tan, offset) in enumerate(jobs, start=1):
        if current != (toward, b):
            # copies tilted toward V are copies tilted toward U of the transpose
            g = square if toward == 0 else np.ascontiguousarray(square.transpose(1, 0, 2))
            # box across the long side: average 2^b rows
            for _ in range(b):
                g = box_halve(g, axis0=True, axis1=False)
            g = np.ascontiguousarray(g, dtype=np.float32)
            current = (toward, b)
        # one copy: the box along the tilted long side
        copy = skewed_box(g, a, b, tan, copy_columns(nsz, a, b, long_oversampling))
        flat = copy.reshape(-1, copy.shape[2])
        if top is not None:
            flat = np.clip(np.rint(flat * top), 0, top)
        buf[offset : offset + flat.shape[0]] = flat
        if progress is not None:
            progress(done, len(jobs))
    return ParallelogramFamily(buf, table, nsz, k, skew_oversampling, long_oversampling)
