"""Exact-coverage reads: the pixel's parallelogram over a copy's cells.

The family's cells tile the plane, so the box filter over the pixel is the sum of the
cells it covers, each weighted by the share of the pixel inside it
(:func:`cover_cells`): the filter's ends are as sharp as the cells are short, where the
seed's eq. 5 blends boxes blind to a pattern whose period divides ``2^e``. Along the
tilted axis the shares come from two uniform spreads (:func:`trapezoid_cdf`); across,
from the pixel's interval at the column's middle, spread by its drift against the
copy's skew. ``b = 0`` rows are lines read as the bilinear texture
(:func:`trapezoid_integral`). Footprints under a few texels integrate the bilinear
texture itself by the midpoint rule (:func:`quadrature_texels`), as the supersampled
reference does.
"""

from __future__ import annotations

import math

from numba import njit

#: most midpoint-rule points per pixel side of a quadrature read
QUAD_POINTS = 4
#: largest window side (texels) of a quadrature read
QUAD_WINDOW = 8


@njit(cache=True, inline="always")
def trapezoid_cdf(x, a, b):
    """CDF of ``U(-a/2, a/2) + U(-b/2, b/2)``, ``a >= b >= 0``: the share of the
    pixel ``{(s a + t b, ...)}`` lying below ``x`` along the tilted axis."""
    h = 0.5 * (a + b)
    if x <= -h:
        return 0.0
    if x >= h:
        return 1.0
    if b <= 1e-7 * a:
        return (x + 0.5 * a) / a
    g = 0.5 * (a - b)
    if x < -g:
        d = x + h
        return d * d / (2.0 * a * b)
    if x <= g:
        return (x + 0.5 * a) / a
    d = h - x
    return 1.0 - d * d / (2.0 * a * b)


@njit(cache=True, inline="always")
def _cube_plus(x):
    return x * x * x if x > 0.0 else 0.0


@njit(cache=True, inline="always")
def _square_plus(x):
    return x * x if x > 0.0 else 0.0


@njit(cache=True, inline="always")
def trapezoid_integral(x, a, b):
    """``E[(x - X)_+]`` for ``X = U(-a/2, a/2) + U(-b/2, b/2)``, ``a >= b >= 0``:
    the integral of :func:`trapezoid_cdf`; its second difference with unit steps is
    the trapezoid against the unit tent (a bilinear row's share)."""
    if b <= 1e-3 * a:
        return (_square_plus(x + 0.5 * a) - _square_plus(x - 0.5 * a)) / (2.0 * a)
    r = (_cube_plus(x + 0.5 * (a + b)) - _cube_plus(x + 0.5 * (a - b))
         - _cube_plus(x - 0.5 * (a - b)) + _cube_plus(x - 0.5 * (a + b)))
    return r / (6.0 * a * b)


@njit(cache=True)
def cover_cells(buf, off, rows, cols, s, t, tent_rows, swap, x0, y0, a, bs, ls, slope, tau,
                out):
    """``out +=`` the mean of one copy over the pixel; returns the cells read.

    The copy is ``rows x cols`` cells of ``s`` x ``t`` texels (along, across) from
    ``buf[off]`` (T, C), row-major (column-major when ``swap``: a mip level read
    transposed); ``tent_rows``: rows are lines through texel centres (``b = 0``),
    read as the bilinear texture. The pixel, centred at ``(x0, y0)`` (wrapped), is
    ``{(s a + t bs, t ls)}`` with the cross axis sheared by ``slope``
    (:func:`core.perspective.footprint.footprint_sides`); ``tau`` is the copy's skew.
    """
    b = abs(bs)
    big, small = max(a, b), min(a, b)
    ext = 0.5 * (a + b)
    x1 = x0 - ext
    x2 = x0 + ext
    nc = out.shape[0]
    reads = 0
    for j in range(int(math.floor(x1 / s)), int(math.ceil(x2 / s))):
        # share of the pixel inside this column of cells
        lo = max(x1, j * s)
        hi = min(x2, (j + 1) * s)
        if hi <= lo:
            continue
        wa = trapezoid_cdf(hi - x0, big, small) - trapezoid_cdf(lo - x0, big, small)
        if wa <= 1e-12:
            continue
        # the pixel's cross interval at the column's middle: |t| <= 1/2, |x - t bs| <= a/2
        xm = 0.5 * (lo + hi)
        xr = xm - x0
        t_lo = -0.5
        t_hi = 0.5
        if b > 1e-12:
            q1 = (xr - 0.5 * a) / bs
            q2 = (xr + 0.5 * a) / bs
            t_lo = max(t_lo, min(q1, q2))
            t_hi = min(t_hi, max(q1, q2))
        if t_hi < t_lo:
            t_lo = t_hi = 0.5 * (t_lo + t_hi)
        # in the cell's unsheared frame; across the column the pixel's band drifts
        # by (slope - tau) per texel against the cell's rows: a trapezoid of spreads
        shift = y0 + slope * xr - tau * (xm - (j + 0.5) * s)
        centre = 0.5 * (t_lo + t_hi) * ls + shift
        span = abs((t_hi - t_lo) * ls)
        drift = abs(slope - tau) * (hi - lo)
        wide, narrow = max(span, drift), min(span, drift)
        reach = 0.5 * (span + drift)
        jj = j % cols
        if tent_rows:
            m_lo = int(math.floor(centre - reach - 0.5))
            m_hi = int(math.floor(centre + reach + 0.5))
        else:
            m_lo = int(math.floor((centre - reach) / t))
            m_hi = int(math.ceil((centre + reach) / t)) - 1
        for m in range(m_lo, m_hi + 1):
            # share of the pixel's cross spread in this row
            if wide < 1e-9:
                # a point across: the row that holds it (tent rows: bilinear)
                d = centre - (m + 0.5) if tent_rows else 0.0
                if tent_rows:
                    wb = max(0.0, 1.0 - abs(d))
                else:
                    wb = 1.0 if m * t <= centre < (m + 1) * t else 0.0
            elif tent_rows:
                d = m + 0.5 - centre
                wb = (trapezoid_integral(d + 1.0, wide, narrow)
                      - 2.0 * trapezoid_integral(d, wide, narrow)
                      + trapezoid_integral(d - 1.0, wide, narrow))
            else:
                wb = (trapezoid_cdf((m + 1) * t - centre, wide, narrow)
                      - trapezoid_cdf(m * t - centre, wide, narrow))
            if wb <= 0.0:
                continue
            mm = m % rows
            idx = off + (jj * rows + mm if swap else mm * cols + jj)
            wt = wa * wb
            for c in range(nc):
                out[c] += wt * buf[idx, c]
            reads += 1
    return reads


@njit(cache=True)
def quadrature_texels(tex, rows, cols, u, v, dux, dvx, duy, dvy, scratch, out):
    """``out +=`` the box over the pixel of the bilinear (wrapping) texture.

    Midpoint-rule points (two per texel of a side, 2 to ``QUAD_POINTS`` per side)
    spread bilinearly into ``scratch`` (QUAD_WINDOW, QUAD_WINDOW) float64, zeroed on
    return; each texel with a weight is read once. ``tex`` (rows * cols, C); ``u, v``
    the centre in texels; ``dux .. dvy`` eq. 2 in texels of ``tex``, the pixel within
    a ``QUAD_WINDOW - 2`` texel window. Returns the texels read.
    """
    nx = min(QUAD_POINTS, max(2, int(math.ceil(2.0 * math.hypot(dux, dvx)))))
    ny = min(QUAD_POINTS, max(2, int(math.ceil(2.0 * math.hypot(duy, dvy)))))
    eu = 0.5 * (abs(dux) + abs(duy))
    ev = 0.5 * (abs(dvx) + abs(dvy))
    i0 = int(math.floor(u - eu - 0.5))
    j0 = int(math.floor(v - ev - 0.5))
    wi = min(QUAD_WINDOW, int(math.floor(u + eu - 0.5)) + 2 - i0)
    wj = min(QUAD_WINDOW, int(math.floor(v + ev - 0.5)) + 2 - j0)
    wq = 1.0 / (nx * ny)
    for p in range(nx):
        sp = (p + 0.5) / nx - 0.5
        for q in range(ny):
            tq = (q + 0.5) / ny - 0.5
            # the point's bilinear weights on its 2 x 2 texels
            uu = u + sp * dux + tq * duy - 0.5
            vv = v + sp * dvx + tq * dvy - 0.5
            fi = math.floor(uu)
            fj = math.floor(vv)
            fx = uu - fi
            fy = vv - fj
            ii = min(max(int(fi) - i0, 0), wi - 2)
            jj = min(max(int(fj) - j0, 0), wj - 2)
            scratch[jj, ii] += wq * (1.0 - fx) * (1.0 - fy)
            scratch[jj, ii + 1] += wq * fx * (1.0 - fy)
            scratch[jj + 1, ii] += wq * (1.0 - fx) * fy
            scratch[jj + 1, ii + 1] += wq * fx * fy
    nc = out.shape[0]
    reads = 0
    for jj in range(wj):
        for ii in range(wi):
            wt = scratch[jj, ii]
            if wt == 0.0:
                continue
            scratch[jj, ii] = 0.0
            idx = ((j0 + jj) % rows) * cols + (i0 + ii) % cols
            for c in range(nc):
                out[c] += wt * tex[idx, c]
            reads += 1
    return reads
