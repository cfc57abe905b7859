"""Texture preparation: float conversion, power-of-two resampling, mip pyramid.

The seed's prefiltered family needs a ``2^n x 2^n`` tiling texture. Other
sizes are resampled (bicubic, with wrap-around borders so the tiling seam
stays invisible) *up* to the square ``N = 2^ceil(log2(max(w, h)))``; the
mapping is scaled by ``N/w`` along U and ``N/h`` along V so that U, V stay in
texels of the input. The nearest, bilinear and reference filters read the
input itself and need no resampling.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from core.errors import TerrathemeError


def as_float_texture(texture: np.ndarray) -> np.ndarray:
    """The texture as ``(h, w, C) float32``; integer types are scaled to [0, 1].

    Parameters
    ----------
    texture : (h, w) or (h, w, C) ndarray, C in 1..4

    Raises
    ------
    TerrathemeError
        Empty, wrong rank, more than 4 channels or non-finite values.
    """
    arr = np.asarray(texture)
    if arr.ndim == 2:
        arr = arr[:, :, None]
    if arr.ndim != 3 or arr.shape[0] < 1 or arr.shape[1] < 1:
        raise TerrathemeError(f"texture must be a non-empty (h, w, C) array, got {arr.shape}")
    if not 1 <= arr.shape[2] <= 4:
        raise TerrathemeError(f"texture must have 1 to 4 channels, got {arr.shape[2]}")
    if arr.dtype == np.bool_:
        arr = arr.astype(np.float32)
    elif np.issubdtype(arr.dtype, np.integer):
        arr = arr.astype(np.float32) / np.float32(np.iinfo(arr.dtype).max)
    elif np.issubdtype(arr.dtype, np.floating):
        arr = arr.astype(np.float32)
    else:
        raise TerrathemeError(f"texture dtype {arr.dtype} is not a number type")
    if not np.all(np.isfinite(arr)):
        raise TerrathemeError("texture holds NaN or infinite values")
    return np.ascontiguousarray(arr)


def power_of_two_square(tex: np.ndarray) -> tuple[np.ndarray, float, float]:
    """Resample a wrapping texture up to ``N x N``, ``N`` a power of two.

    Parameters
    ----------
    tex : (h, w, C) float32 ndarray

    Returns
    -------
    square : (N, N, C) float32 ndarray
        ``tex`` itself when it already is ``2^n x 2^n``.
    su, sv : float
        ``N / w`` and ``N / h``: multiply U and V by these.
    """
    h, w, c = tex.shape
    n = 1 << int(np.ceil(np.log2(max(h, w))))
    if h == n and w == n:
        return tex, 1.0, 1.0
    # sample the input at the centres of the N x N texels (wrap-around borders)
    xs = ((np.arange(n, dtype=np.float32) + 0.5) * (w / n) - 0.5).astype(np.float32)
    ys = ((np.arange(n, dtype=np.float32) + 0.5) * (h / n) - 0.5).astype(np.float32)
    mx, my = np.meshgrid(xs, ys)
    lo, hi = tex.min(axis=(0, 1)), tex.max(axis=(0, 1))
    planes = []
    for ch in range(c):
        src = np.ascontiguousarray(tex[:, :, ch])
        out = cv2.remap(src, mx, my, interpolation=cv2.INTER_CUBIC, borderMode=cv2.BORDER_WRAP)
        # bicubic overshoots at edges: keep the input's value range
        planes.append(np.clip(out, lo[ch], hi[ch]))
    return np.ascontiguousarray(np.stack(planes, axis=2)), n / w, n / h


@dataclass(frozen=True)
class MipPyramid:
    """Box-filtered mip levels of an ``N x N`` texture, packed for the kernels.

    Attributes
    ----------
    buf : (T, C) float32 ndarray
        All levels, row-major, level after level.
    offsets : (n+1,) int64 ndarray
        Start of level ``l`` in ``buf``; level ``l`` is ``N>>l`` squared.
    size : int
        ``N``.
    """

    buf: np.ndarray
    offsets: np.ndarray
    size: int

    @property
    def levels(self) -> int:
        return len(self.offsets)

    @property
    def nbytes(self) -> int:
        return int(self.buf.nbytes)

    def level(self, i: int) -> np.ndarray:
        """Level ``i`` as a ``(N>>i, N>>i, C)`` view."""
        r = self.size >> i
        return self.buf[self.offsets[i] : self.offsets[i] + r * r].reshape(r, r, -1)


def box_halve(img: np.ndarray, axis0: bool = True, axis1: bool = True) -> np.ndarray:
    """Average 2-texel blocks along the chosen axes of ``(h, w, C)`` (even sizes)."""
    out = img
    if axis0:
        out = 0.5 * (out[0::2] + out[1::2])
    if axis1:
        out = 0.5 * (out[:, 0::2] + out[:, 1::2])
    return out


def build_pyramid(square: np.ndarray) -> MipPyramid:
    """Mip levels ``N, N/2, ..., 1`` by 2 x 2 box averaging.

    Parameters
    ----------
    square : (N, N, C) float32 ndarray, N a power of two
    """
    n = square.shape[0]
    if square.shape[1] != n or n & (n - 1):
        raise TerrathemeError(f"mip pyramid needs a 2^n x 2^n texture, got {square.shape[:2]}")
    levels = [square.astype(np.float32)]
    while levels[-1].shape[0] > 1:
        levels.append(box_halve(levels[-1]).astype(np.float32))
    c = square.shape[2]
    sizes = [lv.shape[0] * lv.shape[1] for lv in levels]
    offsets = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64)
    buf = np.concatenate([lv.reshape(-1, c) for lv in levels], axis=0)
    return MipPyramid(np.ascontiguousarray(buf), offsets, n)
