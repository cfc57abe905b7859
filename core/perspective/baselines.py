"""Baseline filters with the same conventions as the seed's method.

Each kernel takes flat per-pixel arrays (length ``P``): texture coordinates
``u, v`` and the derivatives of eq. 2 in texels of the texture it reads, and a
``valid`` mask (``z > 0``). It writes ``out : (P, C) float32`` and returns
``reads : (P,) int32``, the texels read per pixel.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange
from terratheme.core.perspective.sampling import add_bilinear, add_texel, add_trilinear, wrap_coord

#: ``max_aniso`` of :func:`mip_kernel` that asks for trilinear filtering (one probe)
TRILINEAR = 0


@njit(cache=True, parallel=True)
def texel_kernel(buf, rows, cols, u, v, bilinear, valid, out):
    """Read the input texture itself around ``(u, v)``.

    ``bilinear`` False: the texel that contains ``(u, v)``, ``(floor(u) mod w,
    floor(v) mod h)``; True: bilinear interpolation between the four texel
    centres around it.
    """
    p_count = u.shape[0]
    reads = np.zeros(p_count, np.int32)
    for p in prange(p_count):
        if not valid[p]:
            continue
        if bilinear:
            reads[p] = add_bilinear(buf, 0, rows, cols, u[p], v[p], 1.0, out[p])
        else:
            i = int(wrap_coord(u[p], cols))
            j = int(wrap_coord(v[p], rows))
            add_texel(buf, 0, cols, i, j, 1.0, out[p])
            reads[p] = 1
    return reads


@njit(cache=True, parallel=True)
def mip_kernel(buf, offsets, heights, widths, u, v, dux, dvx, duy, dvy, max_aniso, valid, out):
    """Mip-mapping with trilinear probes, linear between two levels (Williams 1983).

    ``max_aniso`` :data:`TRILINEAR` (0): one probe at level ``log2 max(|dX|,
    |dY|)`` (the seed's table diagonal ``H = L``). ``max_aniso >= 1``:
    GPU-style anisotropic filtering (EXT_texture_filter_anisotropic),
    ``N = min(ceil(Pmax/Pmin), max_aniso)`` probes spread along the major
    axis, each at level ``log2(Pmax/N)``, averaged.
    """
    p_count = u.shape[0]
    reads = np.zeros(p_count, np.int32)
    for p in prange(p_count):
        if not valid[p]:
            continue
        lx = math.hypot(dux[p], dvx[p])
        ly = math.hypot(duy[p], dvy[p])
        if max_aniso == TRILINEAR:
            rho = max(lx, ly)
            nprobe, mu, mv = 1, 0.0, 0.0
            lod = math.log2(rho) if rho > 0.0 else -1.0
        else:
            # major axis of the footprint
            if lx >= ly:
                pmax, pmin, mu, mv = lx, ly, dux[p], dvx[p]
            else:
                pmax, pmin, mu, mv = ly, lx, duy[p], dvy[p]
            # number of probes
            if pmin > 0.0:
                nprobe = min(math.ceil(pmax / pmin), max_aniso)
            else:
                nprobe = max_aniso if pmax > 0.0 else 1
            nprobe = max(1, int(nprobe))
            lod = math.log2(pmax / nprobe) if pmax > 0.0 else -1.0
        w = 1.0 / nprobe
        r = 0
        # probes evenly spaced along the major axis, centred on (u, v)
        for k in range(nprobe):
            t = (k + 0.5) / nprobe - 0.5
            r += add_trilinear(buf, offsets, heights, widths, u[p] + t * mu, v[p] + t * mv, lod,
                               w, out[p])
        reads[p] = r
    return reads
