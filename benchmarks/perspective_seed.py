"""The seed's family lookup as published (Kovalev & Tarasov, eqs. 5-9), a peer of the
default ``COVERAGE`` lookup in ``bench_perspective.py``; it reads the same family of
prefiltered copies (``PreparedTexture.family``) and returns the same ``RenderResult``."""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange
from terratheme.core.perspective import (
    Camera,
    FilterOptions,
    PlaneMapping,
    PreparedTexture,
    view_mapping,
)
from terratheme.core.perspective.footprint import TOWARD_U, footprint_sides
from terratheme.core.perspective.lookup import log2_int, skew_choice
from terratheme.core.perspective.render import RenderResult, sky_vector
from terratheme.core.perspective.sampling import add_bilinear, add_texel, wrap_coord


@njit(cache=True, inline="always")
def footprint(dux, dvx, duy, dvy):
    """Eqs. 3-4 for one pixel: ``h = A + |bs|``, ``l = |Ls|`` of ``footprint_sides``, ``tan``
    and ``toward`` (``TOWARD_U``: long side along (1, tan); ``TOWARD_V``: along (tan, 1))."""
    along, short_along, short_across, tan, toward = footprint_sides(dux, dvx, duy, dvy)
    h = along + abs(short_along)
    # H >= L by definition (guards rounding)
    return h, min(abs(short_across), h), tan, toward


@njit(cache=True, inline="always")
def _add_column_lerp(buf, off, rows, cols, i, y, w, out):
    """``out += w * `` linear interpolation down column ``i`` at height ``y``."""
    ys = wrap_coord(y - 0.5, rows)
    j0 = int(ys)
    fy = ys - j0
    j1 = j0 + 1 if j0 + 1 < rows else 0
    add_texel(buf, off, cols, i, j0, w * (1.0 - fy), out)
    add_texel(buf, off, cols, i, j1, w * fy, out)
    return 2


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
def _seed_read(buf, start, count, grid_w, grid_h, k, so, a, b, tan, toward, u, v, w, out):
    """``out += w * R_i`` for copy ``(a, b)`` (eqs. 6-9); returns texels read."""
    along, across = (grid_w, grid_h) if toward == TOWARD_U else (grid_h, grid_w)
    pa, px = log2_int(along), log2_int(across)
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
    sk = skew_choice(tan, i, so, count[toward, a, b])[0]
    # rows of shift per column along the tilted side (lambda tan)
    lam_tan = s / t * tan if count[toward, a, b] > 1 else 0.0
    # eqs. 6-7: skew-corrected heights in the two neighbouring columns
    xs = wrap_coord(x - 0.5, cols)
    i0 = int(xs)
    fx = xs - i0
    i1 = (i0 + 1) % cols
    off = start[toward, a, b] + sk * rows * cols
    # eq. 8 in the chosen skew
    r = _add_column_lerp(buf, off, rows, cols, i0, y - fx * lam_tan, w * (1.0 - fx), out)
    return r + _add_column_lerp(buf, off, rows, cols, i1, y + (1.0 - fx) * lam_tan, w * fx, out)


@njit(cache=True, parallel=True)
def seed_kernel(buf, start, count, grid_w, grid_h, k, so, u, v, dux, dvx, duy, dvy, valid, out):
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
                       v[p], w1, out[p])
        if w2 > 0.0:
            r += _seed_read(buf, start, count, grid_w, grid_h, k, so, eh + 1, el + 1, tan,
                            toward, u[p], v[p], w2, out[p])
        if w3 > 0.0:
            r += _seed_read(buf, start, count, grid_w, grid_h, k, so, a3, b3, tan, toward,
                            u[p], v[p], w3, out[p])
        reads[p] = r
    return reads


def render_seed(pt: PreparedTexture, view: PlaneMapping | Camera, size: tuple[int, int],
                options: FilterOptions | None = None) -> RenderResult:
    """``pt.render`` with the seed's lookup on ``options``' family (default: ``pt``'s)."""
    opt = options if options is not None else pt.options
    mapping = view_mapping(view, size, pt.texture_size)
    w, h = size
    xx, yy = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    u, v, z = mapping.scaled(pt.su, pt.sv).evaluate(xx.ravel(), yy.ravel())
    dux, dvx, duy, dvy = (d * opt.aperture for d in mapping.scaled(pt.su, pt.sv)
                          .derivatives(u, v, z))
    valid = (z > 0) & np.isfinite(u) & np.isfinite(v)
    fam = pt.family(opt)
    out = np.zeros((w * h, pt.channels), np.float32)
    gw, gh = pt.grid_size
    reads = seed_kernel(fam.buf, fam.start, fam.count, gw, gh, fam.max_lambda_log2,
                        fam.skew_oversampling, u, v, dux, dvx, duy, dvy, valid, out)
    out /= np.float32(pt.stored.top)
    out[~valid] = sky_vector(opt.sky, pt.channels).astype(np.float32)
    return RenderResult(out.reshape(h, w, -1), reads.reshape(h, w), mapping)
