"""numpy images shown in Qt without copies, with a mip pyramid for zoomed-out views.

A :class:`ZoomPyramid` shares an ``(H, W, 3) uint8`` array's memory as a QImage (edits
show at the next paint) and keeps 2x-downsampled levels for zoomed-out views, so a paint
costs what the screen shows, not what the map holds.
"""

from __future__ import annotations

import cv2
import numpy as np
from PySide6.QtCore import QRectF
from PySide6.QtGui import QImage, QPainter

_MIN_LEVEL_SIZE = 512


def qimage_view(arr: np.ndarray) -> QImage:
    """A QImage sharing the memory of ``arr`` ((H, W, 3|4) C-contiguous uint8), which the
    caller keeps alive while the image is used."""
    if arr.dtype != np.uint8 or arr.ndim != 3 or not arr.flags.c_contiguous:
        raise ValueError(
            f"need a C-contiguous (H, W, 3|4) uint8 array, got {arr.shape} {arr.dtype}")
    h, w, c = arr.shape
    fmt = QImage.Format.Format_RGB888 if c == 3 else QImage.Format.Format_RGBA8888
    return QImage(arr.data, w, h, arr.strides[0], fmt)


class ZoomPyramid:
    """An image and its 2x box-filtered levels, drawn into a texel rectangle.

    ``base`` (H, W, 3) uint8 is level 0, shared; ``extent`` (width, height) and ``origin``
    (x, y, top-left) place it in texels.
    """

    def __init__(self, base: np.ndarray, extent: tuple[float, float] | None = None,
                 origin: tuple[float, float] = (0.0, 0.0)) -> None:
        self.levels: list[np.ndarray] = [np.ascontiguousarray(base)]
        h, w = base.shape[:2]
        self.extent = extent if extent is not None else (float(w), float(h))
        self.origin = origin
        # Halve until the level is small enough.
        while max(self.levels[-1].shape[:2]) > _MIN_LEVEL_SIZE and min(
            self.levels[-1].shape[:2]
        ) >= 4:
            prev = self.levels[-1]
            ph, pw = prev.shape[0] // 2, prev.shape[1] // 2
            self.levels.append(cv2.resize(prev[: 2 * ph, : 2 * pw], (pw, ph),
                                          interpolation=cv2.INTER_AREA))
        self.images = [qimage_view(lv) for lv in self.levels]

    @property
    def base(self) -> np.ndarray:
        return self.levels[0]

    def update_region(self, x: int, y: int, w: int, h: int) -> None:
        """Recompute the downsampled levels over the level-0 rectangle ``(x, y, w, h)``."""
        x0, y0, x1, y1 = x, y, x + w, y + h
        for k in range(1, len(self.levels)):
            prev, cur = self.levels[k - 1], self.levels[k]
            # The rectangle at this level, rounded outward.
            x0, y0 = x0 // 2, y0 // 2
            x1 = min((x1 + 1) // 2, cur.shape[1])
            y1 = min((y1 + 1) // 2, cur.shape[0])
            if x0 >= x1 or y0 >= y1:
                return
            block = prev[2 * y0 : 2 * y1, 2 * x0 : 2 * x1]
            cur[y0:y1, x0:x1] = cv2.resize(block, (x1 - x0, y1 - y0),
                                           interpolation=cv2.INTER_AREA)

    def draw(self, painter: QPainter, visible: QRectF, scale: float, opacity: float = 1.0,
             smooth: bool = True) -> None:
        """Draw the part of the image inside ``visible`` (texels); ``painter`` maps texels to
        the screen already, ``scale`` (screen pixels per texel) picks the level."""
        ox, oy = self.origin
        ew, eh = self.extent
        target = QRectF(ox, oy, ew, eh).intersected(visible)
        if target.isEmpty():
            return
        # Pixels of level 0 per texel, then the coarsest level still >= 1 pixel per screen pixel.
        px_per_texel = self.levels[0].shape[1] / ew
        level = 0
        while level + 1 < len(self.levels) and px_per_texel * scale / 2 ** (level + 1) < 1.0:
            level += 1
        sx = self.levels[0].shape[1] / ew / 2**level
        sy = self.levels[0].shape[0] / eh / 2**level
        src = QRectF((target.x() - ox) * sx, (target.y() - oy) * sy,
                     target.width() * sx, target.height() * sy)
        painter.save()
        painter.setOpacity(opacity)
        painter.setRenderHint(QPainter.RenderHint.SmoothPixmapTransform,
                              smooth and px_per_texel * scale / 2**level < 4)
        painter.drawImage(target, self.images[level], src)
        painter.restore()
