"""Supersampled reference: a box filter over each pixel.

Each pixel ``[px, px+1) x [py, py+1)`` is covered by an ``sx x sy`` grid of
sub-samples (their count follows the footprint: ``density`` sub-samples per
texel along each screen axis, within bounds), each mapped through eq. 1 and
read bilinearly from the input texture (wrapping); sub-samples above the
horizon take the sky colour. The mean is the pixel.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange
from terratheme.core.perspective.sampling import add_bilinear


@njit(cache=True, parallel=True)
def reference_kernel(buf, rows, cols, coef, w, h, y0, dux, dvx, duy, dvy, density, smin, smax,
                     sky, out):
    """Box-filtered pixels of a band of ``h`` rows from row ``y0`` of a ``w``-wide frame, into
    ``out`` (h*w, C) float32; returns the (h*w,) int32 reads.

    ``buf`` is the (rows*cols, C) float32 texture, ``coef`` eq. 1 in its texels, ``dux ..
    dvy`` eq. 2 at the pixel centres (they set the sub-sample counts).
    """
    nc = out.shape[1]
    reads = np.zeros(w * h, np.int32)
    for p in prange(w * h):
        px = p % w
        py = y0 + p // w
        # sub-samples per axis from the footprint
        lx = math.hypot(dux[p], dvx[p]) * density
        ly = math.hypot(duy[p], dvy[p]) * density
        sx = int(min(max(math.ceil(lx), smin), smax))
        sy = int(min(max(math.ceil(ly), smin), smax))
        acc = np.zeros(nc)
        r = 0
        for jy in range(sy):
            y = py + (jy + 0.5) / sy
            for jx in range(sx):
                x = px + (jx + 0.5) / sx
                z = coef[2, 0] * x + coef[2, 1] * y + coef[2, 2]
                if z <= 0.0:
                    for c in range(nc):
                        acc[c] += sky[c]
                    continue
                uu = (coef[0, 0] * x + coef[0, 1] * y + coef[0, 2]) / z
                vv = (coef[1, 0] * x + coef[1, 1] * y + coef[1, 2]) / z
                if not (math.isfinite(uu) and math.isfinite(vv)):
                    for c in range(nc):
                        acc[c] += sky[c]
                    continue
                r += add_bilinear(buf, 0, rows, cols, uu, vv, 1.0, acc)
        inv = 1.0 / (sx * sy)
        for c in range(nc):
            out[p, c] = acc[c] * inv
        reads[p] = r
    return reads
