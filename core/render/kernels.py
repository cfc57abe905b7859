"""The hot per-texel loops of the renderer (numba, GIL released).

The kernels fill output rows ``[r0, r1)`` of a region (``out`` the ``(h, w*3)``
uint8 view) so row bands can run on several threads. Themes are packed in one flat
buffer, theme ``k`` at ``off[k]`` with row stride ``stride[k]``, **pre-tiled
horizontally** to ``w[k] + N`` columns so a cell row is one contiguous slice
(uniform cells are copied, never gathered). Weights are the exact integers of
``corner_weights``; the linear kernel rounds half up with a multiply-shift
reciprocal (``(2v + D) * mag >> sh == (2v + D) // (2D)``, :func:`division_magic`).
"""

from __future__ import annotations

import functools
import math
from typing import NamedTuple

import numba as nb
import numpy as np
from terratheme.core.render.rules import corner_weights

_MAX_SHIFT = 54


class RegionBlock(NamedTuple):
    """The block of the grid under an output region, as the kernels read it.

    ``grid`` (uint8, vertices) and ``splits`` (uint8, cells) start at cell
    ``(ocy, ocx)`` of the whole grid; the output's texel ``(0, 0)`` is global
    texel ``(rx, ry)``; cells are ``n x m`` texels.
    """

    grid: np.ndarray
    splits: np.ndarray
    ocx: int
    ocy: int
    rx: int
    ry: int
    n: int
    m: int


class ThemeRows(NamedTuple):
    """The packed themes (:class:`core.render.theme_pack.PackedThemes`) the kernels read."""

    flat: np.ndarray
    off: np.ndarray
    stride: np.ndarray
    th: np.ndarray
    tw: np.ndarray


class LinearWeights(NamedTuple):
    """Weight tables (:func:`weight_tables`) and the rounding (:func:`division_magic`)."""

    tab: np.ndarray
    trow: np.ndarray
    mag: int
    sh: int


class GaussianThemes(NamedTuple):
    """Gaussianised themes and their inverse tables (histogram-preserving blend)."""

    gflat: np.ndarray
    inv_lut: np.ndarray
    g_range: float


def division_magic(d: int) -> tuple[int, int]:
    """How the linear kernel computes ``(2v + D) // (2D)`` for ``0 <= v <= 255*D``.

    * ``D`` a power of two: ``(-1, log2 D)``, meaning ``(v + D/2) >> log2 D``;
    * otherwise a multiplier and shift with ``(n * mag) >> sh == n // (2D)``
      for ``n <= 511*D`` (Granlund & Montgomery 1994: with ``mag = ceil(2^sh/q)``
      and ``e = mag*q - 2^sh``, exact when ``e * n_max < 2^sh``);
    * ``(0, 0)`` when no shift keeps ``n * mag`` inside int64 (cells above
      about 2^22 texels): the kernel divides.
    """
    if d & (d - 1) == 0 and 255 * d + d < (1 << 31):
        return -1, d.bit_length() - 1
    q = 2 * d
    n_max = 511 * d
    for sh in range(1, _MAX_SHIFT + 1):
        mag = -(-(1 << sh) // q)
        if (mag * q - (1 << sh)) * n_max < (1 << sh) and n_max * mag < (1 << 63):
            return mag, sh
    return 0, 0


@nb.njit(cache=True, nogil=True, inline="always")
def texel_weights(split, xi, yi, d):  # pragma: no cover - numba
    """Barycentric weights (times ``D``) of corners ``ind[0][0], [0][1], [1][0], [1][1]``.

    design.md §1 step 2; ``xi = xs * M``, ``yi = ys * N`` for texel ``(xs, ys)``
    of a cell split along ``split`` (1 main, 2 anti diagonal).
    """
    if split == 1:
        if xi <= yi:
            return d - yi, 0, yi - xi, xi
        return d - xi, xi - yi, 0, yi
    if xi + yi <= d:
        return d - xi - yi, xi, yi, 0
    return 0, d - yi, d - xi, xi + yi - d


@nb.njit(cache=True, nogil=True, inline="always")
def cell_columns(rx, rw, n):  # pragma: no cover - numba
    """First and last cell column of the region row's texels ``rx .. rx + rw - 1``."""
    return rx // n, (rx + rw - 1) // n


@nb.njit(cache=True, nogil=True, inline="always")
def cell_span(cx, n, rx, rw):  # pragma: no cover - numba
    """Texels ``xa .. xb - 1`` of cell column ``cx`` that lie in the region row."""
    return max(cx * n, rx), min(cx * n + n, rx + rw)


@nb.njit(cache=True, nogil=True, inline="always")
def cell_corners(block, themes, cx, gy, xa, ks, bs):  # pragma: no cover - numba
    """Corner themes of cell ``cx`` on texel row ``gy`` into ``ks``, their row offsets into ``bs``.

    ``bs[j]`` is the flat index of corner ``j``'s theme texel at ``(xa, gy)``
    (pre-tiled rows); returns the cell's split.
    """
    grid, splits, ocx, ocy, rx, ry, n, m = block
    flat, off, stride, th, tw = themes
    cy = gy // m
    ks[0] = grid[cy - ocy, cx - ocx]
    ks[1] = grid[cy - ocy, cx - ocx + 1]
    ks[2] = grid[cy - ocy + 1, cx - ocx]
    ks[3] = grid[cy - ocy + 1, cx - ocx + 1]
    for j in range(4):
        k = ks[j]
        bs[j] = off[k] + (gy % th[k]) * stride[k] + (xa % tw[k]) * 3
    return splits[cy - ocy, cx - ocx]


@nb.njit(cache=True, nogil=True, inline="always")
def merged_weights(split, xi, yi, d, ks, ws):  # pragma: no cover - numba
    """Barycentric weights into ``ws``, corners that carry the same theme merged into the first."""
    w00, w01, w10, w11 = texel_weights(split, xi, yi, d)
    ws[0], ws[1], ws[2], ws[3] = w00, w01, w10, w11
    for a in range(4):
        for b in range(a + 1, 4):
            if ws[b] != 0 and ks[b] == ks[a]:
                ws[a] += ws[b]
                ws[b] = 0


_TABLE_CACHE_BYTES = 8 << 20


def weight_tables(n: int, m: int, rows: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Per-byte corner weights of cell rows: ``tab (2, R, 4, 3*N) int32``, ``trow (M,) int32``.

    ``tab[s, trow[ys], c, 3*xs + ch]``: corner ``c``'s weight (times ``D``) at texel
    ``(xs, ys)`` split main (``s = 0``) or anti (1); ``rows`` limits it to those ``ys``.
    """
    if rows is None:
        if 96 * n * m <= _TABLE_CACHE_BYTES:
            return _full_table(n, m)
        rows = np.arange(m)
    return _table(n, m, np.asarray(rows, dtype=np.int64))


@functools.lru_cache(maxsize=32)
def _full_table(n: int, m: int) -> tuple[np.ndarray, np.ndarray]:
    tab, trow = _table(n, m, np.arange(m))
    tab.flags.writeable = False
    return tab, trow


def _table(n: int, m: int, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    xi = (np.arange(n) * m)[None, :]
    yi = (rows * n)[:, None]
    tab = np.empty((2, len(rows), 4, 3 * n), dtype=np.int32)
    for s, split in enumerate((1, 2)):
        ws = corner_weights(np.full((len(rows), n), split), xi, yi, n * m)
        for c in range(4):
            tab[s, :, c, :] = np.repeat(ws[c], 3, axis=1)
    trow = np.full(m, -1, dtype=np.int32)
    trow[rows] = np.arange(len(rows), dtype=np.int32)
    return tab, trow


@nb.njit(cache=True, nogil=True)
def linear_rows(out, r0, r1, block, themes, weights):
    """Fill ``out[r0:r1]`` with the linear three-theme blend.

    ``block`` a :class:`RegionBlock`, ``themes`` :class:`ThemeRows`,
    ``weights`` :class:`LinearWeights`. Rounding: ``mag == 0`` divides;
    ``mag < 0`` means ``D`` is a power of two and the shift ``sh`` is exact
    (``(v + D/2) >> log2 D``, all 32-bit, vectorises); otherwise multiply-shift.
    """
    grid, splits, ocx, ocy, rx, ry, n, m = block
    flat, off, stride, th, tw = themes
    tab, trow, mag, sh = weights
    rw = out.shape[1] // 3
    d = n * m
    half = d >> 1
    q = 2 * d
    cx0, cx1 = cell_columns(rx, rw, n)
    for r in range(r0, r1):
        gy = ry + r
        cy = gy // m
        ys = gy - cy * m
        for cx in range(cx0, cx1 + 1):
            xa, xb = cell_span(cx, n, rx, rw)
            length = (xb - xa) * 3
            dst = (xa - rx) * 3
            k00 = grid[cy - ocy, cx - ocx]
            sp = splits[cy - ocy, cx - ocx]
            if sp == 0:
                # Step 1: uniform cell, one contiguous copy from the pre-tiled theme row.
                src = off[k00] + (gy % th[k00]) * stride[k00] + (xa % tw[k00]) * 3
                out[r, dst : dst + length] = flat[src : src + length]
                continue
            k01 = grid[cy - ocy, cx - ocx + 1]
            k10 = grid[cy - ocy + 1, cx - ocx]
            k11 = grid[cy - ocy + 1, cx - ocx + 1]
            b00 = off[k00] + (gy % th[k00]) * stride[k00] + (xa % tw[k00]) * 3
            b01 = off[k01] + (gy % th[k01]) * stride[k01] + (xa % tw[k01]) * 3
            b10 = off[k10] + (gy % th[k10]) * stride[k10] + (xa % tw[k10]) * 3
            b11 = off[k11] + (gy % th[k11]) * stride[k11] + (xa % tw[k11]) * 3
            # Step 2: barycentric weights of this cell row (tabulated per byte).
            wt = tab[sp - 1, trow[ys]]
            t0 = (xa - cx * n) * 3
            w00 = wt[0, t0 : t0 + length]
            w01 = wt[1, t0 : t0 + length]
            w10 = wt[2, t0 : t0 + length]
            w11 = wt[3, t0 : t0 + length]
            o = out[r, dst : dst + length]
            a = flat[b00 : b00 + length]
            b = flat[b01 : b01 + length]
            c = flat[b10 : b10 + length]
            e = flat[b11 : b11 + length]
            if mag < 0:
                for t in range(length):
                    v = (w00[t] * np.int32(a[t]) + w01[t] * np.int32(b[t])
                         + w10[t] * np.int32(c[t]) + w11[t] * np.int32(e[t]))
                    o[t] = (v + half) >> sh
            elif mag > 0:
                for t in range(length):
                    v = (w00[t] * np.int64(a[t]) + w01[t] * np.int64(b[t])
                         + w10[t] * np.int64(c[t]) + w11[t] * np.int64(e[t]))
                    o[t] = ((2 * v + d) * mag) >> sh
            else:
                for t in range(length):
                    v = (w00[t] * np.int64(a[t]) + w01[t] * np.int64(b[t])
                         + w10[t] * np.int64(c[t]) + w11[t] * np.int64(e[t]))
                    o[t] = (2 * v + d) // q


@nb.njit(cache=True, nogil=True, inline="always")
def _inverse(inv_lut, row, g, g_range):
    # Inverse Gaussianisation by the tabulated transform, linear between entries.
    size = inv_lut.shape[1]
    pos = (g + g_range) * ((size - 1) / (2.0 * g_range))
    if pos <= 0.0:
        return inv_lut[row, 0]
    if pos >= size - 1:
        return inv_lut[row, size - 1]
    i = int(pos)
    f = pos - i
    return inv_lut[row, i] * (1.0 - f) + inv_lut[row, i + 1] * f


@nb.njit(cache=True, nogil=True)
def histogram_rows(out, r0, r1, block, themes, gauss):
    """Fill ``out[r0:r1]`` with the histogram-preserving blend (Heitz & Neyret, HPG 2018).

    Per texel and channel ``g = sum(w_t * G_t) / sqrt(sum(w_t^2))``, then
    ``out = sum(w_t * Q_t(g))`` (docs/design.md §1); a texel of one theme at full
    weight is that theme's texel exactly.
    """
    grid, splits, ocx, ocy, rx, ry, n, m = block
    flat, off, stride, th, tw = themes
    gflat, inv_lut, g_range = gauss
    rw = out.shape[1] // 3
    d = n * m
    cx0, cx1 = cell_columns(rx, rw, n)
    ks = np.zeros(4, dtype=np.int64)
    ws = np.zeros(4, dtype=np.int64)
    bs = np.zeros(4, dtype=np.int64)
    for r in range(r0, r1):
        gy = ry + r
        cy = gy // m
        yi = (gy - cy * m) * n
        for cx in range(cx0, cx1 + 1):
            xa, xb = cell_span(cx, n, rx, rw)
            sp = cell_corners(block, themes, cx, gy, xa, ks, bs)
            for x in range(xa, xb):
                o = (x - xa) * 3
                if sp == 0:
                    for c in range(3):
                        out[r, (x - rx) * 3 + c] = flat[bs[0] + o + c]
                    continue
                # Corners that carry the same theme merged (identical, fully correlated samples).
                merged_weights(sp, (x - cx * n) * m, yi, d, ks, ws)
                full = -1
                for a in range(4):
                    if ws[a] == d:
                        full = a
                if full >= 0:
                    for c in range(3):
                        out[r, (x - rx) * 3 + c] = flat[bs[full] + o + c]
                    continue
                norm = 0.0
                for a in range(4):
                    norm += float(ws[a]) * float(ws[a])
                norm = math.sqrt(norm)
                for c in range(3):
                    g = 0.0
                    for a in range(4):
                        if ws[a] != 0:
                            g += ws[a] * gflat[bs[a] + o + c]
                    g /= norm
                    v = 0.0
                    for a in range(4):
                        if ws[a] != 0:
                            v += ws[a] * _inverse(inv_lut, ks[a] * 3 + c, g, g_range)
                    v = v / d + 0.5
                    out[r, (x - rx) * 3 + c] = min(255, max(0, int(v)))


@nb.njit(cache=True, nogil=True)
def label_rows(out, r0, r1, block, tab, trow):
    """Fill ``out[r0:r1]`` ((h, w) uint8) with the theme of largest total weight per texel.

    Corners carrying the same theme add their weights; ties go to the lower
    theme index. ``block`` a :class:`RegionBlock`; ``tab, trow`` from
    :func:`weight_tables` (every third entry).
    """
    grid, splits, ocx, ocy, rx, ry, n, m = block
    rw = out.shape[1]
    cx0, cx1 = cell_columns(rx, rw, n)
    ks = np.zeros(4, dtype=np.int64)
    ws = np.zeros(4, dtype=np.int64)
    for r in range(r0, r1):
        gy = ry + r
        cy = gy // m
        ys = gy - cy * m
        for cx in range(cx0, cx1 + 1):
            xa, xb = cell_span(cx, n, rx, rw)
            ks[0] = grid[cy - ocy, cx - ocx]
            sp = splits[cy - ocy, cx - ocx]
            if sp == 0:
                out[r, xa - rx : xb - rx] = ks[0]
                continue
            ks[1] = grid[cy - ocy, cx - ocx + 1]
            ks[2] = grid[cy - ocy + 1, cx - ocx]
            ks[3] = grid[cy - ocy + 1, cx - ocx + 1]
            wt = tab[sp - 1, trow[ys]]
            for x in range(xa, xb):
                t = (x - cx * n) * 3
                for j in range(4):
                    ws[j] = wt[j, t]
                best_k = 256
                best_w = -1
                for j in range(4):
                    total = 0
                    for i in range(4):
                        if ks[i] == ks[j]:
                            total += ws[i]
                    if total > best_w or (total == best_w and ks[j] < best_k):
                        best_w = total
                        best_k = ks[j]
                out[r, x - rx] = best_k
