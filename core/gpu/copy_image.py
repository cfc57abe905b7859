"""Uniform cells as image copies: ``glCopyImageSubData`` from pre-tiled theme textures.

A run of uniform cells shows one theme's texels, wrapped: a copy, no
sampling (the CPU renderer copies theme rows the same way). Each rectangle
is cut into pieces of at most one theme period, each copied from a texture
holding the theme tiled 2 x 2, so a piece starting anywhere in the period
fits. On Mesa's llvmpipe a copy is a memcpy; a rectangle drawn with a
texture-sampling shader costs several times more (bench_gpu.py).

``glCopyImageSubData`` (OpenGL 4.3 / ARB_copy_image) is not wrapped by
moderngl: it is looked up with ``eglGetProcAddress`` (the context is EGL's)
and called through ctypes on the objects' GL names.
"""

from __future__ import annotations

import ctypes
import ctypes.util
from collections.abc import Callable

import moderngl
import numpy as np

GL_TEXTURE_2D = 0x0DE1
GL_RENDERBUFFER = 0x8D41
_SIGNATURE = ctypes.CFUNCTYPE(None, ctypes.c_uint, ctypes.c_uint, *[ctypes.c_int] * 4,
                              ctypes.c_uint, ctypes.c_uint, *[ctypes.c_int] * 7)

CopyImage = Callable[..., None]


def copy_image_function(ctx: moderngl.Context) -> CopyImage | None:
    """``glCopyImageSubData`` of the current EGL context, or None where the driver lacks it."""
    if ctx.version_code < 430 and "GL_ARB_copy_image" not in ctx.extensions:
        return None
    name = ctypes.util.find_library("EGL") or "libEGL.so.1"
    try:
        egl = ctypes.CDLL(name)
    except OSError:
        return None
    egl.eglGetProcAddress.restype = ctypes.c_void_p
    egl.eglGetProcAddress.argtypes = [ctypes.c_char_p]
    address = egl.eglGetProcAddress(b"glCopyImageSubData")
    return _SIGNATURE(address) if address else None


def copy_pieces(rects: np.ndarray, themes: np.ndarray, sizes: np.ndarray,
                origin: tuple[int, int]) -> np.ndarray:
    """Cut rectangles of one theme each into copies of at most one theme period.

    Parameters
    ----------
    rects : (R, 4) int ndarray
        ``x0, y0, x1, y1``: global texels (half-open), inside the framebuffer.
    themes : (R,) int ndarray
    sizes : (K, 4) ndarray
        ``w, h, ...`` of every theme.
    origin : (x, y)
        Global texel of framebuffer pixel (0, 0).

    Returns
    -------
    pieces : (P, 7) int64 ndarray
        ``theme, src_x, src_y, dst_x, dst_y, w, h``: copy ``w x h`` texels
        from ``(src_x, src_y)`` of the 2 x 2 tiled theme to framebuffer pixel
        ``(dst_x, dst_y)``; together they fill every rectangle once.
    """
    rects = np.asarray(rects, dtype=np.int64).reshape(-1, 4)
    themes = np.asarray(themes, dtype=np.int64)
    period = np.asarray(sizes, dtype=np.float64)[themes, :2].astype(np.int64)
    extent = rects[:, 2:] - rects[:, :2]
    # Pieces per rectangle along x and y: one per theme period covered.
    count = -(-extent // period)
    total = count[:, 0] * count[:, 1]
    which = np.repeat(np.arange(len(rects)), total)
    # The piece's (i, j) inside its rectangle, row by row.
    start = np.cumsum(total) - total
    k = np.arange(int(total.sum())) - start[which]
    i, j = k % count[which, 0], k // count[which, 0]
    step = np.stack([i, j], axis=1) * period[which]
    corner = rects[which, :2] + step
    size = np.minimum(period[which], extent[which] - step)
    src = np.mod(rects[which, :2], period[which])
    dst = corner - np.asarray(origin, dtype=np.int64)
    return np.column_stack([themes[which], src, dst, size])


def copy_into(copy: CopyImage, sources: dict[int, int], target: int,
              pieces: np.ndarray) -> None:
    """Run the copies: ``sources[theme]`` (2D texture names) into renderbuffer ``target``."""
    for theme, sx, sy, dx, dy, w, h in pieces.tolist():
        copy(sources[theme], GL_TEXTURE_2D, 0, sx, sy, 0,
             target, GL_RENDERBUFFER, 0, dx, dy, 0, w, h, 1)
