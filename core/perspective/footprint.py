"""Footprint parallelogram of the seed (Kovalev & Tarasov, eqs. 3-4).

The pixel's footprint, spanned by the texel steps ``dX = (dU/dx, dV/dx)`` and
``dY = (dU/dy, dV/dy)`` of eq. 2, is replaced by a parallelogram with one
pair of sides parallel to a texture axis: full height ``H`` along the
tilted long side, full base ``L`` across it (``H >= L``), and the tangent of
the long side's slope, ``|tan| <= 1``, toward U or toward V.

With the pixel's own footprint (``aperture = 1``), ``H`` is the footprint's
extent along the axis it is tilted toward and ``L`` its extent across after
the shear; with the seed's 2 x 2-pixel filter they are the half-height and
half-base.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

#: orientation codes
TOWARD_U = 0
TOWARD_V = 1


@njit(cache=True, inline="always")
def footprint(dux, dvx, duy, dvy):
    """Eqs. 3-4 for one pixel.

    Returns
    -------
    h, l, tan, toward : float, float, float, int
        ``toward`` is ``TOWARD_U`` (long side along ``(1, tan)`` in (U, V),
        short sides parallel to V) or ``TOWARD_V`` (long side along
        ``(tan, 1)``, short sides parallel to U).
    """
    aux, avx, auy, avy = abs(dux), abs(dvx), abs(duy), abs(dvy)
    # eq. 3: approximate side lengths (within about 6 %)
    dx = max(aux, avx) + 0.5 * min(aux, avx)
    dy = max(auy, avy) + 0.5 * min(auy, avy)
    # eq. 4: the longer side sets the slope, the other one the base
    if dy >= dx:
        if auy >= avy:
            toward = TOWARD_U
            tan = dvy / duy if duy != 0.0 else 0.0
            h = aux + auy
            l = abs(dvx - dux * tan)
        else:
            toward = TOWARD_V
            tan = duy / dvy if dvy != 0.0 else 0.0
            h = avx + avy
            l = abs(dux - dvx * tan)
    else:
        if aux >= avx:
            toward = TOWARD_U
            tan = dvx / dux if dux != 0.0 else 0.0
            h = aux + auy
            l = abs(dvy - duy * tan)
        else:
            toward = TOWARD_V
            tan = dux / dvx if dvx != 0.0 else 0.0
            h = avx + avy
            l = abs(duy - dvy * tan)
    # H >= L by definition (guards rounding)
    if l > h:
        l = h
    return h, l, tan, toward


@njit(cache=True)
def _footprint_arrays(dux, dvx, duy, dvy):
    n = dux.shape[0]
    h = np.empty(n)
    l = np.empty(n)
    t = np.empty(n)
    o = np.empty(n, np.int8)
    for p in range(n):
        h[p], l[p], t[p], o[p] = footprint(dux[p], dvx[p], duy[p], dvy[p])
    return h, l, t, o


@dataclass(frozen=True)
class Footprint:
    """Eq. 4 parameters per pixel, all ``(...)``-shaped like the input.

    ``h, l, tan`` are float64; ``toward`` is int8 (0 = toward U, 1 = toward V).
    """

    h: np.ndarray
    l: np.ndarray
    tan: np.ndarray
    toward: np.ndarray


def footprint_parameters(dudx, dvdx, dudy, dvdy) -> Footprint:
    """Eqs. 3-4 on arrays of derivatives (any matching shape, float64)."""
    arrs = [np.ascontiguousarray(np.asarray(a, dtype=np.float64)) for a in (dudx, dvdx, dudy, dvdy)]
    shape = arrs[0].shape
    h, l, t, o = _footprint_arrays(*(a.ravel() for a in arrs))
    return Footprint(h.reshape(shape), l.reshape(shape), t.reshape(shape), o.reshape(shape))


@njit(cache=True, inline="always")
def footprint_sides(dux, dvx, duy, dvy):
    """The pixel's own parallelogram in the sheared frame of eq. 4.

    With the long side ``(1, tan)`` toward U (or ``(tan, 1)`` toward V) chosen as
    in eqs. 3-4, the coordinates ``x`` along the tilted axis and ``y`` across it
    minus ``tan x`` map the pixel's sides to ``(A, 0)`` and ``(bs, Ls)``: the
    pixel is ``{(s A + t bs, t Ls) : |s|, |t| <= 1/2}``. Eq. 4's ``H`` is
    ``A + |bs|`` (the whole extent along) and ``L`` is ``|Ls|``.

    Returns
    -------
    A, bs, Ls, tan, toward : float, float, float, float, int
        ``A >= 0`` is the long side's extent along, ``bs`` and ``Ls`` the short
        side's (signed) extents along and across.
    """
    aux, avx, auy, avy = abs(dux), abs(dvx), abs(duy), abs(dvy)
    # eq. 3: approximate side lengths; eq. 4: the longer one sets the slope
    dx = max(aux, avx) + 0.5 * min(aux, avx)
    dy = max(auy, avy) + 0.5 * min(auy, avy)
    if dy >= dx:
        if auy >= avy:
            tan = dvy / duy if duy != 0.0 else 0.0
            return auy, dux, dvx - dux * tan, tan, TOWARD_U
        tan = duy / dvy if dvy != 0.0 else 0.0
        return avy, dvx, dux - dvx * tan, tan, TOWARD_V
    if aux >= avx:
        tan = dvx / dux if dux != 0.0 else 0.0
        return aux, duy, dvy - duy * tan, tan, TOWARD_U
    tan = dux / dvx if dvx != 0.0 else 0.0
    return avx, dvy, duy - dvy * tan, tan, TOWARD_V
