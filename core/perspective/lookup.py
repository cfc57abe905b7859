"""Lookup in the prefiltered family, per pixel (Kovalev & Tarasov, eqs. 2-9).

:func:`coverage_kernel` (the default): eqs. 3-4 choose the tilted axis and skew, the
copy is the one where the pixel spans ``cells_along`` to twice that many cells along and
one to two across, and the pixel's parallelogram is summed over them
(:func:`.coverage.cover_cells`; small footprints: :func:`.coverage.quadrature_texels`).
It takes (P,) per-pixel arrays in texels of the family's grid, writes ``out`` (P, C)
float32 and returns the reads per pixel. The seed's own lookup (eqs. 5-9 as published) is
a peer in ``benchmarks/perspective_seed.py``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange
from terratheme.core.perspective.coverage import QUAD_WINDOW, cover_cells, quadrature_texels
from terratheme.core.perspective.footprint import TOWARD_U, footprint_sides
from terratheme.core.perspective.sampling import wrap_coord

#: pixels per parallel chunk (scratch is allocated once per chunk)
CHUNK = 256
#: footprints below this many texels along both texture axes are integrated
#: over the texture itself
QUAD_EXTENT = 4.0


@njit(cache=True, inline="always")
def floor_log2(x):
    """``floor(log2 x)`` for ``x >= 1``, else -1."""
    if x < 1.0:
        return -1
    return int(math.floor(math.log2(x)))


@njit(cache=True, inline="always")
def log2_int(n):
    return int(round(math.log2(n)))


@njit(cache=True, inline="always")
def skew_choice(tan, i, so, n_skews):
    """``(s, tau)``: the skew nearest ``tan`` at ``lambda = 2^i``, ties away from 0
    (mirrored footprints pick mirrored copies)."""
    if n_skews == 1:
        return 0, 0.0
    c = so * (1 << (i - 1))
    q = c // 2
    j = int(math.floor(abs(tan) * 0.5 * c + 0.5))
    if tan < 0.0:
        j = -j
    j = max(-q, min(q, j))
    return j + q, 2.0 * j / c


@njit(cache=True, parallel=True)
def coverage_kernel(buf, start, count, grid_w, grid_h, k, so, cells_along, tex, tex_w, tex_h,
                    su, sv, u, v, dux, dvx, duy, dvy, valid, out):
    """The default filter (see the module docstring); returns reads per pixel."""
    p_count = u.shape[0]
    reads = np.zeros(p_count, np.int32)
    for chunk in prange((p_count + CHUNK - 1) // CHUNK):
        scratch = np.zeros((QUAD_WINDOW, QUAD_WINDOW))
        for p in range(chunk * CHUNK, min(p_count, (chunk + 1) * CHUNK)):
            if not valid[p]:
                continue
            # small footprints: the box over the pixel of the texture itself
            iux, ivx, iuy, ivy = dux[p] / su, dvx[p] / sv, duy[p] / su, dvy[p] / sv
            if abs(iux) + abs(iuy) < QUAD_EXTENT and abs(ivx) + abs(ivy) < QUAD_EXTENT:
                reads[p] = quadrature_texels(
                    tex, tex_h, tex_w, wrap_coord(u[p] / su, tex_w), wrap_coord(v[p] / sv, tex_h),
                    iux, ivx, iuy, ivy, scratch, out[p])
                continue
            # eqs. 3-4: the tilted axis, the slope, the pixel in the sheared frame
            a_len, bs, ls, tan, toward = footprint_sides(dux[p], dvx[p], duy[p], dvy[p])
            if toward == TOWARD_U:
                along, across, x0, y0 = grid_w, grid_h, u[p], v[p]
            else:
                along, across, x0, y0 = grid_h, grid_w, v[p], u[p]
            x0 = wrap_coord(x0, along)
            y0 = wrap_coord(y0, across)
            h = a_len + abs(bs)
            # a footprint longer than the texture winds round it: one turn, widened
            if h > along:
                f = h / along
                a_len /= f
                bs /= f
                ls *= f
                h = float(along)
            if abs(ls) > across:
                ls = across if ls > 0 else -across
            a_len = max(a_len, 1e-6)
            pa, px = log2_int(along), log2_int(across)
            # cells: cells_along..2 cells_along along, 1..2 across
            a = min(max(floor_log2(h / cells_along), 1), pa)
            b = min(max(floor_log2(abs(ls)), 0), px)
            if a - b > k and b < px:
                b = min(a - k, px)
            if a < b:
                a = b
            i = a - b
            if i == 0:
                # a mip level, in the texture's frame
                rows, cols = max(1, grid_h >> b), max(1, grid_w >> b)
                if toward == TOWARD_U:
                    s, t, swap = grid_w / cols, grid_h / rows, False
                else:
                    s, t, swap = grid_h / rows, grid_w / cols, True
                reads[p] = cover_cells(buf, start[0, b, b], rows, cols, s, t, b == 0, swap,
                                       x0, y0, a_len, bs, ls, tan, 0.0, out[p])
                continue
            rows, cols = max(1, across >> b), max(1, along >> a)
            s, t = along / cols, across / rows
            n_skews = count[toward, a, b]
            sk, tau = skew_choice(tan, i, so, n_skews)
            reads[p] = cover_cells(buf, start[toward, a, b] + sk * rows * cols, rows, cols, s, t,
                                   b == 0, False, x0, y0, a_len, bs, ls, tan, tau, out[p])
    return reads
