"""Footprint parallelogram of the seed (Kovalev & Tarasov, eqs. 3-4; docs/design.md §6).

The pixel's footprint, spanned by eq. 2's texel steps ``dX`` and ``dY``, becomes a
parallelogram with one pair of sides parallel to a texture axis: full height ``H`` along
the tilted long side, full base ``L`` across it (``H >= L``), slope ``|tan| <= 1`` toward
U or V. With ``aperture = 1`` they are the pixel's own extents; with the seed's 2 x 2-pixel
filter, the half-height and half-base.
"""

from __future__ import annotations

from numba import njit

#: orientation codes
TOWARD_U = 0
TOWARD_V = 1


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
    # eq. 3: approximate side lengths
    dx = max(aux, avx) + 0.5 * min(aux, avx)
    dy = max(auy, avy) + 0.5 * min(auy, avy)
    # eq. 4: the longer side (the step along y or along x) sets the slope
    if dy >= dx:
        long_u, long_v, short_u, short_v = duy, dvy, dux, dvx
    else:
        long_u, long_v, short_u, short_v = dux, dvx, duy, dvy
    # the axis the long side leans toward is "along", the other "across"
    if abs(long_u) >= abs(long_v):
        along, across, short_along, short_across, toward = (
            long_u, long_v, short_u, short_v, TOWARD_U)
    else:
        along, across, short_along, short_across, toward = (
            long_v, long_u, short_v, short_u, TOWARD_V)
    tan = across / along if along != 0.0 else 0.0
    return abs(along), short_along, short_across - short_along * tan, tan, toward
