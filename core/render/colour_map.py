"""Applying a colour map (:class:`core.model.colour_map.ColourMap`) to rendered texels.

At texel ``X`` (column; rows alike) the map coordinate is
``u = (X + 0.5) / s - 0.5``; in units of ``1 / (2s)`` map pixels that is the
integer ``t = 2X + 1 - s``, so ``i0 = floor(t / 2s)`` and the weights
``2s - (t - 2s*i0)`` and ``t - 2s*i0`` of map columns ``i0`` and ``i0 + 1``
are exact integers (clamped to the first and last column at the edges).
The texel value ``v`` becomes ``round(v * G / (128 * (2s)^2))`` with ``G`` the
integer bilinear sum, rounded half up and capped at 255: the same on every
region of the texture, so a region render equals the crop of a full one.
"""

from __future__ import annotations

import numba as nb
import numpy as np
from terratheme.core.model.colour_map import NEUTRAL, ColourMap


def axis_weights(start: int, length: int, scale: int, size: int) -> tuple[np.ndarray, ...]:
    """Map indices ``i0, i1`` and integer weights ``w0, w1`` (summing to ``2 * scale``),
    all ``(length,)`` int64, of texels ``start .. start+length-1`` along one axis."""
    t = 2 * (start + np.arange(length, dtype=np.int64)) + 1 - scale
    two = 2 * scale
    i0 = np.floor_divide(t, two)
    frac = t - i0 * two
    # Clamp: before the first pixel centre and after the last one the edge pixel holds.
    low = i0 < 0
    i0[low], frac[low] = 0, 0
    high = i0 >= size - 1
    i0[high], frac[high] = size - 1, 0
    return i0, np.minimum(i0 + 1, size - 1), two - frac, frac


@nb.njit(cache=True, nogil=True)
def _apply_rows(out, r0, r1, pixels, yi0, yi1, yw0, yw1, xi0, xi1, xw0, xw1, denom):
    # out: (h, w*3) uint8 rows of the region; weights per region row and column.
    w = xi0.size
    half = denom // 2
    for r in range(r0, r1):
        a, b = yi0[r], yi1[r]
        wa, wb = yw0[r], yw1[r]
        for x in range(w):
            c0, c1 = xi0[x], xi1[x]
            v0, v1 = xw0[x], xw1[x]
            for ch in range(3):
                g = (wa * (v0 * np.int64(pixels[a, c0, ch]) + v1 * np.int64(pixels[a, c1, ch]))
                     + wb * (v0 * np.int64(pixels[b, c0, ch]) + v1 * np.int64(pixels[b, c1, ch])))
                v = (np.int64(out[r, 3 * x + ch]) * g + half) // denom
                out[r, 3 * x + ch] = min(v, 255)


class RegionGain:
    """The colour map's integer weights for one output region, applied band by band."""

    def __init__(self, colour_map: ColourMap, region: tuple[int, int, int, int]) -> None:
        x, y, w, h = region
        mh, mw = colour_map.pixels.shape[:2]
        s = colour_map.scale
        self.pixels = colour_map.pixels
        self.x = axis_weights(x, w, s, mw)
        self.y = axis_weights(y, h, s, mh)
        self.denom = np.int64(NEUTRAL * (2 * s) ** 2)

    def apply(self, out: np.ndarray, r0: int, r1: int) -> None:
        """Multiply rows ``r0 .. r1-1`` of ``out`` ((h, w, 3) or (h, w*3) uint8) in place."""
        rows = out.reshape(out.shape[0], -1)
        _apply_rows(rows, r0, r1, self.pixels, *self.y, *self.x, self.denom)


def apply_colour_map(image: np.ndarray, colour_map: ColourMap,
                     region: tuple[int, int, int, int]) -> np.ndarray:
    """Multiply ``image`` (h, w, 3) uint8, the render of global ``region``, by the map in place."""
    RegionGain(colour_map, region).apply(image, 0, image.shape[0])
    return image


def gain_image(colour_map: ColourMap, region: tuple[int, int, int, int],
               out_size: tuple[int, int]) -> np.ndarray:
    """(oh, ow, 3) float32 gain at the centres of ``out_size`` pixels covering ``region``.

    For reduced-resolution renders (overviews): output pixel ``(i, j)`` sits
    at texel ``x + (i + 0.5) * w / ow - 0.5``; the map is interpolated there.
    """
    x, y, w, h = region
    ow, oh = out_size
    s = colour_map.scale
    mh, mw = colour_map.pixels.shape[:2]

    def coords(start: float, length: int, n: int, size: int) -> tuple[np.ndarray, ...]:
        u = (start + (np.arange(n) + 0.5) * length / n) / s - 0.5
        u = np.clip(u, 0.0, size - 1.0)
        i0 = np.minimum(np.floor(u).astype(np.int64), size - 1)
        return i0, np.minimum(i0 + 1, size - 1), (u - i0).astype(np.float32)

    y0, y1, fy = coords(y, h, oh, mh)
    x0, x1, fx = coords(x, w, ow, mw)
    p = colour_map.pixels.astype(np.float32) / NEUTRAL
    # Along x on the map's own rows (small), then along y: the same products, a third the work.
    across = p[:, x0] * (1 - fx)[None, :, None] + p[:, x1] * fx[None, :, None]
    return across[y0] * (1 - fy)[:, None, None] + across[y1] * fy[:, None, None]
