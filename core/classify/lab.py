"""The photo in CIE Lab, per pixel and per block: what every feature family starts from.

OpenCV's 8-bit conversion rescaled to L 0..100, a and b about -128..127; block means
and the block std of L on the coarse grid (edge-replicated to whole blocks).
"""

from __future__ import annotations

import cv2
import numpy as np
from terratheme.core.classify.texture import block_mean

#: (1, 256, 3) float32: each 8-bit Lab code as L* (x 100/255) and a*, b* (- 128), as full_lab
_LAB8_TABLE = (np.repeat(np.arange(256, dtype=np.float32)[None, :, None], 3, axis=2)
               * np.array([100.0 / 255.0, 1.0, 1.0], np.float32)
               - np.array([0.0, 128.0, 128.0], np.float32))


def full_lab(rgb: np.ndarray) -> np.ndarray:
    """CIE Lab of every pixel, float32: OpenCV's 8-bit conversion through ``_LAB8_TABLE``."""
    return cv2.LUT(cv2.cvtColor(np.ascontiguousarray(rgb), cv2.COLOR_RGB2Lab), _LAB8_TABLE)


def block_lab(lab8: np.ndarray, scale: int) -> tuple[np.ndarray, np.ndarray]:
    """Block means of a :func:`full_lab` image and the std of L inside each block (float32)."""
    h, w = lab8.shape[:2]
    if scale == 1:
        return lab8, np.zeros((h, w), np.float32)
    # Block means of Lab and of L^2 (edge-replicated to whole blocks).
    lab = block_mean(lab8, scale)
    l_sq = block_mean(np.ascontiguousarray(lab8[:, :, 0] * lab8[:, :, 0]), scale)
    block_std = np.sqrt(np.maximum(l_sq - lab[:, :, 0] ** 2, 0.0))
    return lab, block_std.astype(np.float32)
