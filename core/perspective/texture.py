"""Texture preparation: storage type, power-of-two resampling, mip pyramid.

The prefiltered structures need a wrapping texture with power-of-two sides: each side
is resampled on its own to a power of two near it (:func:`power_of_two_side`), the
mapping scaled so U, V stay in input texels. Texels keep the input's storage type
(uint8, uint16 or float32, read as ``value / top``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from skimage.transform import resize
from terratheme.core.errors import TerrathemeError


@dataclass(frozen=True)
class StoredTexture:
    """A texture in its storage type: ``texels`` (h, w, C) uint8, uint16 or float32, and
    ``top``, stored units per 1.0 (255, 65535 or 1)."""

    texels: np.ndarray
    top: float

    @property
    def size(self) -> tuple[int, int]:
        """``(width, height)`` in texels."""
        return int(self.texels.shape[1]), int(self.texels.shape[0])

    @property
    def channels(self) -> int:
        return int(self.texels.shape[2])


def stored_texture(texture: np.ndarray) -> StoredTexture:
    """The texture as ``(h, w, C)`` in a storage type (other integer types and booleans
    become float32 [0, 1]); TerrathemeError when empty, of the wrong rank, over 4
    channels or not finite.
    """
    arr = np.asarray(texture)
    if arr.ndim == 2:
        arr = arr[:, :, None]
    if arr.ndim != 3 or arr.shape[0] < 1 or arr.shape[1] < 1:
        raise TerrathemeError(f"texture must be a non-empty (h, w, C) array, got {arr.shape}")
    if not 1 <= arr.shape[2] <= 4:
        raise TerrathemeError(f"texture must have 1 to 4 channels, got {arr.shape[2]}")
    if arr.dtype in (np.dtype(np.uint8), np.dtype(np.uint16)):
        return StoredTexture(np.ascontiguousarray(arr), float(np.iinfo(arr.dtype).max))
    if arr.dtype == np.bool_:
        arr = arr.astype(np.float32)
    elif np.issubdtype(arr.dtype, np.integer):
        arr = arr.astype(np.float32) / np.float32(np.iinfo(arr.dtype).max)
    elif np.issubdtype(arr.dtype, np.floating):
        # Values past float32's range become infinite here and are refused below.
        with np.errstate(over="ignore", invalid="ignore"):
            arr = arr.astype(np.float32)
    else:
        raise TerrathemeError(f"texture dtype {arr.dtype} is not a number type")
    if not np.all(np.isfinite(arr)):
        raise TerrathemeError("texture holds NaN, infinite or out-of-float32-range values")
    return StoredTexture(np.ascontiguousarray(arr), 1.0)


#: a side grows to the next power of two only past this share of the octave (in log2):
#: at most 2^0.45 = 1.37 up per side, 1.87 in area, so the family (23.5 bytes per RGB
#: texel of the grid) plus the input stays within 48 bytes per input texel
ROUND_UP_FROM = 0.55


def power_of_two_side(n: int) -> int:
    """The power of two for a side of ``n`` texels: ``2^floor(log2 n + 1 - ROUND_UP_FROM)``."""
    return 1 << max(0, int(np.floor(np.log2(n) + 1.0 - ROUND_UP_FROM)))


def power_of_two_grid(tex: StoredTexture) -> tuple[np.ndarray, float, float]:
    """Resample a wrapping texture to (H', W', C), powers of two, in its storage type, and
    ``su = W'/w``, ``sv = H'/h`` to multiply U and V by.

    Linear with wrap-around and Gaussian anti-aliasing where a side shrinks (scikit-image's
    ``resize``); the texels themselves when the sides already are powers of two.
    """
    h, w, c = tex.texels.shape
    wp, hp = power_of_two_side(w), power_of_two_side(h)
    if (hp, wp) == (h, w):
        return tex.texels, 1.0, 1.0
    src = tex.texels.astype(np.float32)
    # anti-aliasing only along the sides that shrink (sigma 0 keeps the others sharp)
    sigma = [max(0.0, (h / hp - 1) / 2), max(0.0, (w / wp - 1) / 2), 0.0]
    out = resize(src, (hp, wp, c), order=1, mode="wrap", anti_aliasing=max(sigma) > 0,
                 anti_aliasing_sigma=sigma, preserve_range=True)
    return np.ascontiguousarray(to_storage(out, tex.texels.dtype)), wp / w, hp / h


def to_storage(values: np.ndarray, dtype: np.dtype) -> np.ndarray:
    """Float values in stored units rounded into ``dtype`` (kept for float32)."""
    dt = np.dtype(dtype)
    if dt.kind != "u":
        return values.astype(dt, copy=False)
    top = np.iinfo(dt).max
    return np.clip(np.rint(values), 0, top).astype(dt)


def level_shape(height: int, width: int, level: int) -> tuple[int, int]:
    """``(rows, cols)`` of mip ``level`` of an ``H' x W'`` grid: each side halves down to 1."""
    return max(1, height >> level), max(1, width >> level)


def box_halve(img: np.ndarray) -> np.ndarray:
    """Average 2-texel blocks along every side longer than one texel of ``(h, w, C)``."""
    out = img
    if out.shape[0] > 1:
        out = 0.5 * (out[0::2] + out[1::2])
    if out.shape[1] > 1:
        out = 0.5 * (out[:, 0::2] + out[:, 1::2])
    return out


@dataclass(frozen=True)
class MipPyramid:
    """Box-filtered mip levels of an ``H' x W'`` texture, packed for the kernels.

    ``buf`` (T, C): all levels row-major, one after the other, in the storage type;
    ``offsets``, ``heights``, ``widths`` (L,) int64: each level's start and shape
    (the last is 1 x 1).
    """

    buf: np.ndarray
    offsets: np.ndarray
    heights: np.ndarray
    widths: np.ndarray

    @property
    def levels(self) -> int:
        return len(self.offsets)

    @property
    def nbytes(self) -> int:
        return int(self.buf.nbytes)

    def level(self, i: int) -> np.ndarray:
        """Level ``i`` as a ``(rows, cols, C)`` view."""
        r, c = int(self.heights[i]), int(self.widths[i])
        return self.buf[self.offsets[i] : self.offsets[i] + r * c].reshape(r, c, -1)


def build_pyramid(grid: np.ndarray, dtype: np.dtype | type = np.float32) -> MipPyramid:
    """Mip levels down to 1 x 1 by 2 x 2 (or 2 x 1) box averaging of ``grid`` (H', W', C),
    sides powers of two, stored as ``dtype`` (rounded for integer types)."""
    h, w = grid.shape[:2]
    if h & (h - 1) or w & (w - 1):
        raise TerrathemeError(f"mip pyramid needs power-of-two sides, got {grid.shape[:2]}")
    levels = [grid.astype(np.float32)]
    while levels[-1].shape[0] > 1 or levels[-1].shape[1] > 1:
        levels.append(box_halve(levels[-1]).astype(np.float32))
    c = grid.shape[2]
    heights = np.array([lv.shape[0] for lv in levels], np.int64)
    widths = np.array([lv.shape[1] for lv in levels], np.int64)
    offsets = np.concatenate([[0], np.cumsum(heights * widths)[:-1]]).astype(np.int64)
    buf = to_storage(np.concatenate([lv.reshape(-1, c) for lv in levels], axis=0), dtype)
    return MipPyramid(np.ascontiguousarray(buf), offsets, heights, widths)
