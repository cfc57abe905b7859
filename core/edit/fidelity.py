"""Per-cell fidelity: how far the render's colour is from the photo's, cell by cell.

Both images are reduced to a mean colour per cell (``cv2.INTER_AREA``) and compared by
CIEDE2000, so detail inside a theme does not count, only a wrong theme does (about 2
is barely visible, above 10 clearly another colour).
"""

from __future__ import annotations

import cv2
import numpy as np
from skimage.color import deltaE_ciede2000, rgb2lab
from terratheme.core.errors import TerrathemeError


def cell_means(image: np.ndarray, cells_shape: tuple[int, int]) -> np.ndarray:
    """(gh, gw, 3) float32 mean colour in [0, 1] per cell, the (H, W, 3) uint8 image stretched over
    them.
    """
    gh, gw = cells_shape
    img = np.ascontiguousarray(image[..., :3])
    small = cv2.resize(img, (gw, gh), interpolation=cv2.INTER_AREA)
    return small.astype(np.float32) / 255.0


def fidelity_map(render: np.ndarray, photo: np.ndarray, cells_shape: tuple[int, int]
                 ) -> np.ndarray:
    """(gh, gw) float32 CIEDE2000 difference per cell of ``cells_shape`` between ``render``
    (H, W, 3) uint8 and ``photo`` (any resolution over the same area).
    """
    for name, arr in (("render", render), ("photo", photo)):
        if arr.ndim != 3 or arr.shape[2] < 3 or arr.dtype != np.uint8:
            raise TerrathemeError(
                f"{name} must be an (H, W, 3) uint8 image, got {arr.shape} {arr.dtype}")
    a = rgb2lab(cell_means(render, cells_shape))
    b = rgb2lab(cell_means(photo, cells_shape))
    return deltaE_ciede2000(a, b).astype(np.float32)


def heat_colours(delta_e: np.ndarray, vmax: float = 25.0) -> np.ndarray:
    """Colour a ``(gh, gw)`` difference map with matplotlib's ``inferno``: (gh, gw, 3) uint8."""
    from matplotlib import colormaps

    t = np.clip(np.asarray(delta_e, dtype=np.float32) / vmax, 0.0, 1.0)
    rgba = colormaps["inferno"](t, bytes=True)
    return np.ascontiguousarray(rgba[..., :3])
