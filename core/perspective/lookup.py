"""Lookup in the prefiltered family (Kovalev & Tarasov, eqs. 5-9).

Per pixel: the footprint of eqs. 2-4 gives ``H, L, tan`` and the axis it is
tilted toward; the three copies around ``(log2 H, log2 L)`` are read with
skew-corrected bilinear interpolation (eqs. 6-9) and blended by the
mantissas of ``H`` and ``L`` (eq. 5): :func:`parallelogram_kernel`.
:func:`two_probe_kernel` replaces eq. 5's blend along ``H`` by two probes of
one copy (measured closer to the box-filtered reference).

Both kernels first bound the footprint (:func:`_honoured`): the elongation is
clamped on the true footprint, and a footprint longer than the (wrapping)
texture is folded into one texture length, widened across by the same factor.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from core.perspective.footprint import TOWARD_U, footprint
from core.perspective.sampling import add_bilinear, add_column_lerp, wrap_coord


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
    m = x / (1 << e) - 1.0
    if m < 0.0:
        m = 0.0
    if m >= 1.0:
        m = 0.999999
    return e, m


@njit(cache=True, inline="always")
def _honoured(h, l, size, max_ratio):
    """The footprint ``(H, L)`` the family can serve: ``1 <= L <= H <= N``.

    The elongation is clamped to ``max_ratio`` on the footprint itself (as GPUs
    and EWA do), before the length is bounded. A footprint longer than the
    texture (``H > N``, near the horizon) wraps ``H / N`` times; for a slope
    that is not a small fraction its turns lie side by side across the long
    side, so it is read as the ``N``-long footprint ``H / N`` times wider (the
    same area; ``L = N`` is the texture's mean)."""
    h = max(h, 1.0)
    # elongation clamp on the true footprint: widen across
    l = max(l, h / max_ratio, 1.0)
    # fold a footprint longer than the texture into one turn, same area
    if h > size:
        l = l * (h / size)
        h = float(size)
    return h, min(l, h)


@njit(cache=True, inline="always")
def _add_copy_columns(buf, off, rows, cols, i0, i1, fx, y1, y2, w, out):
    """Eqs. 8-9: linear down columns ``i0`` (at ``y1``) and ``i1`` (at ``y2``),
    then across with weight ``fx``; returns texels read (4)."""
    r = add_column_lerp(buf, off, rows, cols, i0, y1, w * (1.0 - fx), out)
    r += add_column_lerp(buf, off, rows, cols, i1, y2, w * fx, out)
    return r


@njit(cache=True, inline="always")
def _read_copy(buf, table, size, k, over, lover, a, b, tan, toward, u, v, w, blend, out):
    """``out += w * R_i`` for copy ``(a, b)`` (eqs. 6-9); returns texels read.

    ``blend``: interpolate between the two prefiltered skews around ``tan``
    (linear in ``tan``, like eq. 5 in ``H`` and ``L``) instead of taking the
    nearest one; twice the reads for ``lambda >= 4``."""
    n = table.shape[1] - 1
    # keep (a, b) inside the family: b <= a <= n, a - b <= k
    if a > n:
        a = n
    if b > a:
        b = a
    if a - b > k:
        b = a - k
    i = a - b
    if i == 0:
        # lambda = 1: the ordinary mip level, plain bilinear
        s = 1.0 / (1 << a)
        r = size >> a
        return add_bilinear(buf, table[0, a, b, 0], r, r, u * s, v * s, w, out)
    # skews at this lambda are tan = 2 j / c, |j| <= q
    c = over * (1 << (i - 1))
    q = c // 2
    if blend:
        # the two skews around tan and the weight of the upper one
        jf = tan * 0.5 * c
        j = int(math.floor(jf))
        ft = jf - j
        if j < -q:
            j, ft = -q, 0.0
        if j >= q:
            j, ft = q, 0.0
    else:
        # nearest skew, ties away from 0 (so mirrored footprints pick mirrored copies)
        j = int(math.floor(abs(tan) * 0.5 * c + 0.5))
        if tan < 0.0:
            j = -j
        if j < -q:
            j = -q
        if j > q:
            j = q
        ft = 0.0
    # the copy's lattice: `cols` samples along the long side, N >> b across
    rows = size >> b
    cols = min(size >> b, (size >> a) * lover)
    step = size / cols
    # coordinates in the copy's frame: X along the long side, Y across
    if toward == TOWARD_U:
        x, y = u / step, v / (1 << b)
    else:
        x, y = v / step, u / (1 << b)
    # rows of shift per column along the tilted side (lambda tan when not oversampled)
    lam_tan = step / (1 << b) * tan
    # eqs. 6-7: skew-corrected heights in the two neighbouring columns
    xs = wrap_coord(x - 0.5, cols)
    i0 = int(xs)
    fx = xs - i0
    i1 = i0 + 1
    if i1 == cols:
        i1 = 0
    y1 = y - fx * lam_tan
    y2 = y + (1.0 - fx) * lam_tan
    # eqs. 8-9 in the chosen copy (and its upper neighbour in skew when blending)
    r = _add_copy_columns(buf, table[toward, a, b, j + q], rows, cols, i0, i1, fx, y1, y2,
                          w * (1.0 - ft), out)
    if ft > 0.0:
        r += _add_copy_columns(buf, table[toward, a, b, j + 1 + q], rows, cols, i0, i1, fx,
                               y1, y2, w * ft, out)
    return r


@njit(cache=True, parallel=True)
def parallelogram_kernel(buf, table, size, k, over, lover, u, v, dux, dvx, duy, dvy, blend,
                         valid, out):
    """The seed's filter per pixel; derivatives in texels of the ``N x N``
    texture (already scaled by the aperture). Returns texels read per pixel."""
    p_count = u.shape[0]
    reads = np.zeros(p_count, np.int32)
    n = table.shape[1] - 1
    for p in prange(p_count):
        if not valid[p]:
            continue
        up = wrap_coord(u[p], size)
        vp = wrap_coord(v[p], size)
        # eqs. 3-4: footprint parameters
        h, l, tan, toward = footprint(dux[p], dvx[p], duy[p], dvy[p])
        # at most 2^k elongation, at most the texture along the long side
        h, l = _honoured(h, l, size, float(1 << k))
        eh, mh = _exponent_mantissa(h, 0, n)
        el, ml = _exponent_mantissa(l, 0, eh)
        # eq. 5: three copies around (log2 H, log2 L), weights from the mantissas
        if mh >= ml:
            w1, w2, w3 = 1.0 - mh, ml, mh - ml
            a3, b3 = eh + 1, el
        else:
            w1, w2, w3 = 1.0 - ml, mh, ml - mh
            a3, b3 = eh, el + 1
        r = _read_copy(buf, table, size, k, over, lover, eh, el, tan, toward, up, vp, w1,
                       blend, out[p])
        if w2 > 0.0:
            r += _read_copy(buf, table, size, k, over, lover, eh + 1, el + 1, tan, toward, up, vp,
                            w2, blend, out[p])
        if w3 > 0.0:
            r += _read_copy(buf, table, size, k, over, lover, a3, b3, tan, toward, up, vp,
                            w3, blend, out[p])
        reads[p] = r
    return reads


@njit(cache=True, parallel=True)
def two_probe_kernel(buf, table, size, k, over, lover, u, v, dux, dvx, duy, dvy, blend,
                     valid, out):
    """Variant of eq. 5 along the long side: instead of blending the copies
    ``H = 2^e`` and ``2^(e+1)`` by the mantissa, read copy ``2^e`` twice,
    centred ``+-(H - 2^e)/2`` along the tilted long side, so the two boxes
    span exactly ``H`` (a trapezoid; exact at both powers of two). Across,
    ``L`` is blended by its mantissa as in eq. 5. When the long side is
    shorter than 2 texels and the footprint is anisotropic, copy ``2^0`` is
    the texture itself (bilinear, no box), so the probes go to ``+-sigma``,
    the spread of the pixel's parallelogram along the long axis. 4 to 16
    texel reads (twice that for ``lambda >= 4`` when ``blend``).
    Selected by ``FilterOptions(long_probes=2)`` (the default)."""
    p_count = u.shape[0]
    reads = np.zeros(p_count, np.int32)
    n = table.shape[1] - 1
    for p in prange(p_count):
        if not valid[p]:
            continue
        up = wrap_coord(u[p], size)
        vp = wrap_coord(v[p], size)
        # eqs. 3-4: footprint parameters
        h0, l0, tan, toward = footprint(dux[p], dvx[p], duy[p], dvy[p])
        # at most 2^(k+1) elongation, at most the texture along the long side
        h, l = _honoured(h0, l0, size, float(2 << k))
        eh, mh = _exponent_mantissa(h, 0, n)
        el, ml = _exponent_mantissa(l, 0, eh)
        if eh - el > k:
            el, ml = eh - k, 0.0
        # probe offset along the long side: the two boxes span H
        d = 0.5 * mh * (1 << eh)
        if eh == 0 and h0 >= 2.0 * l0:
            # magnified along the long side: +-sigma, sigma^2 = (a^2 + b^2) / 12 of the
            # pixel's sides a, b projected on the long axis (the box's variance)
            a_x, b_x = (dux[p], duy[p]) if toward == TOWARD_U else (dvx[p], dvy[p])
            d = math.sqrt((a_x * a_x + b_x * b_x) / 12.0)
        # probe offsets along the long side (1, tan) or (tan, 1)
        if toward == TOWARD_U:
            du, dv = d, d * tan
        else:
            du, dv = d * tan, d
        # one probe when H is a power of two, else two
        nprobe = 1 if d == 0.0 else 2
        wp = 1.0 / nprobe
        # the wider base must stay within the copy's height (L <= H)
        cross_ok = el + 1 <= eh
        r = 0
        for q in range(nprobe):
            sgn = 0.0 if nprobe == 1 else (2.0 * q - 1.0)
            pu = up + sgn * du
            pv = vp + sgn * dv
            r += _read_copy(buf, table, size, k, over, lover, eh, el, tan, toward, pu, pv,
                            wp * (1.0 - ml), blend, out[p])
            if ml > 0.0 and cross_ok:
                r += _read_copy(buf, table, size, k, over, lover, eh, el + 1, tan, toward, pu,
                                pv, wp * ml, blend, out[p])
        if ml > 0.0 and not cross_ok:
            # nearly square footprint: blend toward the next mip level (eq. 5's R2)
            r += _read_copy(buf, table, size, k, over, lover, eh + 1, el + 1, tan, toward, up,
                            vp, ml, blend, out[p])
        reads[p] = r
    return reads
