"""Elliptical weighted average (Heckbert 1989) as pbrt-v4 does it.

Follows ``MIPMap::Filter`` / ``MIPMap::EWA`` of pbrt-v4
(src/pbrt/util/mipmap.cpp): the ellipse axes are the two screen derivatives,
the minor axis is stretched so the eccentricity is at most
``max_anisotropy``, the level of detail is ``log2`` of the minor axis in
texels, two adjacent levels are filtered and blended linearly. Inside a level
texels within the ellipse (with a one-texel minimum added to ``A`` and ``C``)
are weighted by the Gaussian table ``exp(-2 r^2) - exp(-2)`` (128 entries).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange
from terratheme.core.perspective.sampling import add_bilinear, add_texel, wrap_coord

#: pbrt's MIPFilterLUT: exp(-alpha r^2) - exp(-alpha), alpha = 2, 128 entries
EWA_LUT = (np.exp(-2.0 * np.arange(128) / 127.0) - np.exp(-2.0)).astype(np.float64)


@njit(cache=True)
def _ewa_level(buf, offsets, heights, widths, level, u, v, d0u, d0v, d1u, d1v, lut, w, out):
    """``out += w * `` EWA over mip ``level``; returns the texels read."""
    nlev = offsets.shape[0]
    if level >= nlev:
        add_texel(buf, offsets[nlev - 1], 1, 0, 0, w, out)
        return 1
    rows, cols = heights[level], widths[level]
    sx = cols / widths[0]
    sy = rows / heights[0]
    # coordinates in this level's texels, texel centres at integers
    s = u * sx - 0.5
    t = v * sy - 0.5
    a0, a1 = d0u * sx, d0v * sy
    b0, b1 = d1u * sx, d1v * sy
    # ellipse coefficients bounding the filter region
    A = a1 * a1 + b1 * b1 + 1.0
    B = -2.0 * (a0 * a1 + b0 * b1)
    C = a0 * a0 + b0 * b0 + 1.0
    inv_f = 1.0 / (A * C - B * B * 0.25)
    A *= inv_f
    B *= inv_f
    C *= inv_f
    # the ellipse's bounding box
    det = -B * B + 4.0 * A * C
    inv_det = 1.0 / det
    u_sqrt = math.sqrt(max(0.0, det * C))
    v_sqrt = math.sqrt(max(0.0, A * det))
    s0 = int(math.ceil(s - 2.0 * inv_det * u_sqrt))
    s1 = int(math.floor(s + 2.0 * inv_det * u_sqrt))
    t0 = int(math.ceil(t - 2.0 * inv_det * v_sqrt))
    t1 = int(math.floor(t + 2.0 * inv_det * v_sqrt))
    # scan the box, weight texels inside the ellipse
    nc = out.shape[0]
    acc = np.zeros(nc)
    sum_w = 0.0
    reads = 0
    off = offsets[level]
    for it in range(t0, t1 + 1):
        tt = it - t
        jj = it % rows
        for is_ in range(s0, s1 + 1):
            ss = is_ - s
            r2 = A * ss * ss + B * ss * tt + C * tt * tt
            if r2 < 1.0:
                idx = min(int(r2 * 128), 127)
                wt = lut[idx]
                k = off + jj * cols + (is_ % cols)
                for c in range(nc):
                    acc[c] += wt * buf[k, c]
                sum_w += wt
                reads += 1
    if sum_w <= 0.0:
        return add_bilinear(buf, off, rows, cols, u * sx, v * sy, w, out)
    for c in range(nc):
        out[c] += w * acc[c] / sum_w
    return reads


@njit(cache=True, parallel=True)
def ewa_kernel(buf, offsets, heights, widths, u, v, dux, dvx, duy, dvy, max_aniso, lut, valid,
               out):
    """pbrt-v4 ``MIPMap::Filter`` with ``FilterFunction::EWA``, per pixel."""
    p_count = u.shape[0]
    reads = np.zeros(p_count, np.int32)
    for p in prange(p_count):
        if not valid[p]:
            continue
        # wrap first so huge coordinates near the horizon stay exact integers
        up = wrap_coord(u[p], widths[0])
        vp = wrap_coord(v[p], heights[0])
        d0u, d0v, d1u, d1v = dux[p], dvx[p], duy[p], dvy[p]
        # the longer derivative is the major axis
        if d0u * d0u + d0v * d0v < d1u * d1u + d1v * d1v:
            d0u, d0v, d1u, d1v = d1u, d1v, d0u, d0v
        longer = math.hypot(d0u, d0v)
        shorter = math.hypot(d1u, d1v)
        # clamp the eccentricity
        if shorter * max_aniso < longer and shorter > 0.0:
            sc = longer / (shorter * max_aniso)
            d1u *= sc
            d1v *= sc
            shorter *= sc
        if shorter == 0.0:
            reads[p] = add_bilinear(buf, offsets[0], heights[0], widths[0], up, vp, 1.0, out[p])
            continue
        # level of detail from the minor axis, blend of two levels
        lod = max(0.0, math.log2(shorter))
        il = int(math.floor(lod))
        f = lod - il
        r = _ewa_level(buf, offsets, heights, widths, il, up, vp, d0u, d0v, d1u, d1v, lut,
                       1.0 - f, out[p])
        r += _ewa_level(buf, offsets, heights, widths, il + 1, up, vp, d0u, d0v, d1u, d1v,
                        lut, f, out[p])
        reads[p] = r
    return reads
