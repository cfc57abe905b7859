"""Per-texel reads shared by the numba kernels.

Every image level is stored row-major in a flat ``(T, C)`` buffer: texel
``(i, j)`` (column ``i``, row ``j``) of a ``rows x cols`` level that starts at
``off`` is ``buf[off + j * cols + i]``. Coordinates are continuous and in
texels of that level: texel ``(i, j)`` covers ``[i, i+1) x [j, j+1)``, so its
centre is ``(i + 0.5, j + 0.5)``. All reads wrap.
"""

from __future__ import annotations

import math

from numba import njit


@njit(cache=True, inline="always")
def wrap_coord(x: float, n: int) -> float:
    """``x`` reduced into ``[0, n)`` (also for huge ``|x|``)."""
    r = x - n * math.floor(x / n)
    if r >= n or r < 0.0:
        r = 0.0
    return r


@njit(cache=True, inline="always")
def add_texel(buf, off, cols, i, j, w, out):
    """``out += w * texel(i, j)``; ``i, j`` already wrapped."""
    k = off + j * cols + i
    for c in range(out.shape[0]):
        out[c] += w * buf[k, c]


@njit(cache=True, inline="always")
def add_bilinear(buf, off, rows, cols, x, y, w, out):
    """``out += w * bilinear(x, y)`` over a wrapping level; returns 4 (reads)."""
    xs = wrap_coord(x - 0.5, cols)
    ys = wrap_coord(y - 0.5, rows)
    i0 = int(xs)
    j0 = int(ys)
    fx = xs - i0
    fy = ys - j0
    i1 = i0 + 1
    if i1 == cols:
        i1 = 0
    j1 = j0 + 1
    if j1 == rows:
        j1 = 0
    add_texel(buf, off, cols, i0, j0, w * (1.0 - fx) * (1.0 - fy), out)
    add_texel(buf, off, cols, i1, j0, w * fx * (1.0 - fy), out)
    add_texel(buf, off, cols, i0, j1, w * (1.0 - fx) * fy, out)
    add_texel(buf, off, cols, i1, j1, w * fx * fy, out)
    return 4


@njit(cache=True, inline="always")
def add_mip_bilinear(buf, offsets, heights, widths, level, x, y, w, out):
    """``out += w * `` bilinear read of mip ``level`` at ``(x, y)`` in level-0 texels."""
    rows, cols = heights[level], widths[level]
    return add_bilinear(buf, offsets[level], rows, cols, x * cols / widths[0],
                        y * rows / heights[0], w, out)


@njit(cache=True, inline="always")
def add_trilinear(buf, offsets, heights, widths, x, y, lod, w, out):
    """``out += w * `` trilinear mip lookup at ``(x, y)`` (level-0 texels) and
    level of detail ``lod`` (log2 of the footprint in texels); returns reads."""
    nlev = offsets.shape[0]
    if lod <= 0.0:
        return add_mip_bilinear(buf, offsets, heights, widths, 0, x, y, w, out)
    if lod >= nlev - 1:
        add_texel(buf, offsets[nlev - 1], 1, 0, 0, w, out)
        return 1
    l0 = int(math.floor(lod))
    f = lod - l0
    reads = add_mip_bilinear(buf, offsets, heights, widths, l0, x, y, w * (1.0 - f), out)
    reads += add_mip_bilinear(buf, offsets, heights, widths, l0 + 1, x, y, w * f, out)
    return reads
