"""Lookup in the prefiltered family, per pixel (Kovalev & Tarasov, eqs. 2-9).

:func:`coverage_kernel` (the default): eqs. 3-4 choose the tilted axis and skew, the
copy is the one where the pixel spans ``cells_along`` to twice that many cells along and
one to two across, and the pixel's parallelogram is summed over them
(:func:`.coverage.cover_cells`; small footprints: :func:`.coverage.quadrature_texels`).
:func:`seed_kernel`: the seed as published, eqs. 5-9. Both take (P,) per-pixel arrays in
texels of the family's grid, write ``out`` (P, C) float32 and return the reads per pixel.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange
from terratheme.core.perspective.coverage import QUAD_WINDOW, cover_cells, quadrature_texels
from terratheme.core.perspective.footprint import TOWARD_U, footprint, footprint_sides
from terratheme.core.perspective.sampling import add_bilinear, add_column_lerp, wrap_coord

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
def skew_choice(tan, i, so, n_skews, blend):
    """``(s0, tau0, s1, tau1, f)``: the skews read for ``tan`` at ``lambda = 2^i``
    and the weight ``f`` of the second (0 unless ``blend``)."""
    if n_skews == 1:
        return 0, 0.0, 0, 0.0, 0.0
    c = so * (1 << (i - 1))
    q = c // 2
    if blend:
        # the two skews around tan, linear in tan
        jf = tan * 0.5 * c
        j = int(math.floor(jf))
        f = jf - j
        if j < -q:
            j, f = -q, 0.0
        if j >= q:
            j, f = q, 0.0
        return j + q, 2.0 * j / c, min(j + 1, q) + q, 2.0 * min(j + 1, q) / c, f
    # nearest skew, ties away from 0 (mirrored footprints pick mirrored copies)
    j = int(math.floor(abs(tan) * 0.5 * c + 0.5))
    if tan < 0.0:
        j = -j
    j = max(-q, min(q, j))
    return j + q, 2.0 * j / c, j + q, 2.0 * j / c, 0.0


@njit(cache=True, parallel=True)
def coverage_kernel(buf, start, count, grid_w, grid_h, k, so, cells_along, tex, tex_w, tex_h,
                    su, sv, u, v, dux, dvx, duy, dvy, blend, valid, out):
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
                                       x0, y0, a_len, bs, ls, tan, 0.0, 1.0, out[p])
                continue
            rows, cols = max(1, across >> b), max(1, along >> a)
            s, t = along / cols, across / rows
            n_skews = count[toward, a, b]
            s0, tau0, s1, tau1, fb = skew_choice(tan, i, so, n_skews, blend)
            off = start[toward, a, b]
            r = cover_cells(buf, off + s0 * rows * cols, rows, cols, s, t, b == 0, False, x0,
                            y0, a_len, bs, ls, tan, tau0, 1.0 - fb, out[p])
            if fb > 0.0:
                r += cover_cells(buf, off + s1 * rows * cols, rows, cols, s, t, b == 0, False,
                                 x0, y0, a_len, bs, ls, tan, tau1, fb, out[p])
            reads[p] = r
    return reads


@njit(cache=True, inline="always")
def _exponent_mantissa(x, lo, hi):
    """``e = floor(log2 x)`` clamped to ``[lo, hi]`` and the mantissa without its
    leading bit, ``M = x / 2^e - 1`` in ``[0, 1)`` (0 when clamped)."""
    if x < 1.0:
        return lo, 0.0
    e = int(math.floor(math.log2(x)))
    if e < lo:
        return lo, 0.0
    if e >= hi:
        return hi, 0.0
    return e, min(max(x / (1 << e) - 1.0, 0.0), 0.999999)


@njit(cache=True)
def _seed_read(buf, start, count, grid_w, grid_h, k, so, a, b, tan, toward, u, v, w, blend,
               out):
    """``out += w * R_i`` for copy ``(a, b)`` (eqs. 6-9); returns texels read."""
    along, across = (grid_w, grid_h) if toward == TOWARD_U else (grid_h, grid_w)
    pa, px = log2_int(along), log2_int(across)
    # keep (a, b) inside the family
    b = min(max(b, 0), px)
    a = max(min(a, pa), b)
    if a - b > k and b < px:
        b = min(a - k, px)
    i = a - b
    if i == 0:
        # lambda = 1: the mip level, bilinear (eqs. 8-9 with tan = 0)
        rows, cols = max(1, grid_h >> b), max(1, grid_w >> b)
        return add_bilinear(buf, start[0, b, b], rows, cols, u * cols / grid_w,
                            v * rows / grid_h, w, out)
    rows, cols = max(1, across >> b), max(1, along >> a)
    s, t = along / cols, across / rows
    x, y = (u / s, v / t) if toward == TOWARD_U else (v / s, u / t)
    s0, _, s1, _, fb = skew_choice(tan, i, so, count[toward, a, b], blend)
    # rows of shift per column along the tilted side (lambda tan)
    lam_tan = s / t * tan if count[toward, a, b] > 1 else 0.0
    # eqs. 6-7: skew-corrected heights in the two neighbouring columns
    xs = wrap_coord(x - 0.5, cols)
    i0 = int(xs)
    fx = xs - i0
    i1 = (i0 + 1) % cols
    y1 = y - fx * lam_tan
    y2 = y + (1.0 - fx) * lam_tan
    r = 0
    # eq. 8 in the chosen skew (and its upper neighbour when blending)
    for sk, ws in ((s0, 1.0 - fb), (s1, fb)):
        if ws <= 0.0:
            continue
        off = start[toward, a, b] + sk * rows * cols
        r += add_column_lerp(buf, off, rows, cols, i0, y1, w * ws * (1.0 - fx), out)
        r += add_column_lerp(buf, off, rows, cols, i1, y2, w * ws * fx, out)
    return r


@njit(cache=True, parallel=True)
def seed_kernel(buf, start, count, grid_w, grid_h, k, so, u, v, dux, dvx, duy, dvy, blend,
                valid, out):
    """The seed's filter per pixel (eqs. 3-9); returns texels read per pixel."""
    p_count = u.shape[0]
    reads = np.zeros(p_count, np.int32)
    for p in prange(p_count):
        if not valid[p]:
            continue
        # eqs. 3-4: footprint parameters
        h, l, tan, toward = footprint(dux[p], dvx[p], duy[p], dvy[p])
        along = grid_w if toward == TOWARD_U else grid_h
        # at most 2^k elongation (widened across), folded into one turn of the texture
        h = max(h, 1.0)
        l = max(l, h / (1 << k), 1.0)
        if h > along:
            l *= h / along
            h = float(along)
        l = min(l, h)
        eh, mh = _exponent_mantissa(h, 0, log2_int(along))
        el, ml = _exponent_mantissa(l, 0, eh)
        # eq. 5: three copies around (log2 H, log2 L), weights from the mantissas
        if mh >= ml:
            w1, w2, w3, a3, b3 = 1.0 - mh, ml, mh - ml, eh + 1, el
        else:
            w1, w2, w3, a3, b3 = 1.0 - ml, mh, ml - mh, eh, el + 1
        r = _seed_read(buf, start, count, grid_w, grid_h, k, so, eh, el, tan, toward, u[p],
                       v[p], w1, blend, out[p])
        if w2 > 0.0:
            r += _seed_read(buf, start, count, grid_w, grid_h, k, so, eh + 1, el + 1, tan,
                            toward, u[p], v[p], w2, blend, out[p])
        if w3 > 0.0:
            r += _seed_read(buf, start, count, grid_w, grid_h, k, so, a3, b3, tan, toward,
                            u[p], v[p], w3, blend, out[p])
        reads[p] = r
    return reads
