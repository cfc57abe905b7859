"""What a theme cut keeps of its photo window, and how the rest is filled.

A window chosen for a class (:mod:`core.themes.patch_search`) holds pixels
that must not repeat once per tile: other classes', the class's own rim
along its border (blends of the two sides), and lone high-contrast objects
(a building in water, a dark rim wider than the rim). :func:`cut_window`
fills them from shifted copies of the class's own pixels
(:func:`fill_from_class`) before the patch is made tileable.
"""

from __future__ import annotations

import cv2
import numpy as np

from core.themes.patch_search import INTERIOR
from core.themes.quality import LANDMARK_CONTRAST, LANDMARK_SIZE, landmark_mask


def fill_from_class(patch: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """Fill the pixels of ``patch`` outside ``keep`` from shifted copies of its kept pixels.

    Parameters
    ----------
    patch : (s, s, 3) uint8 ndarray
    keep : (s, s) bool ndarray
        The class's own pixels (at least one).

    Returns
    -------
    (s, s, 3) uint8 ndarray
        Every pixel a pixel of the class: holes take the texel at the smallest
        circular shift (of a fixed list, nearest first) that lands on a kept one.
    """
    out = patch.copy()
    have = keep.copy()
    s = patch.shape[0]
    steps = sorted({(dy, dx) for dy in range(-s // 2, s // 2 + 1, max(1, s // 16))
                    for dx in range(-s // 2, s // 2 + 1, max(1, s // 16)) if (dy, dx) != (0, 0)},
                   key=lambda d: (d[0] ** 2 + d[1] ** 2, d))
    for dy, dx in steps:
        if have.all():
            break
        # Holes take this shift's texel where the shifted pixel is the class's own.
        src_keep = np.roll(keep, (dy, dx), axis=(0, 1))
        take = ~have & src_keep
        if take.any():
            out[take] = np.roll(patch, (dy, dx), axis=(0, 1))[take]
            have |= take
    if not have.all():
        out[~have] = patch[keep].reshape(-1, 3).mean(axis=0).astype(np.uint8)
    return out


#: an object stands out of its texture when it passes this many luma spreads (and 20 levels)
OBJECT_SPREADS = 4.0


def lone_objects(window: np.ndarray) -> np.ndarray:
    """Pixels of objects that stand out of a patch's texture (a lone building in water).

    Dark or bright features narrower than
    :data:`core.themes.quality.LANDMARK_SIZE` whose contrast passes
    ``OBJECT_SPREADS`` times the patch's own luma spread
    (:func:`core.themes.quality.landmark_mask`), grown by two pixels. Tiled,
    such an object repeats on a grid the eye picks out at once; in a busy
    texture (town) the threshold rises with the spread, so its streets stay.

    Returns
    -------
    (s, s) bool ndarray
    """
    lum = window.astype(np.float32) @ np.array([0.299, 0.587, 0.114], np.float32)
    spread = float(np.std(lum - cv2.GaussianBlur(lum, (0, 0), LANDMARK_SIZE / 4)))
    dark, bright = landmark_mask(window, periodic=False,
                                 contrast=max(LANDMARK_CONTRAST, OBJECT_SPREADS * spread))
    grown = cv2.dilate((dark | bright).astype(np.uint8), np.ones((5, 5), np.uint8))
    return grown.astype(bool)


def class_interior(mask: np.ndarray, x: int, y: int, s: int) -> np.ndarray:
    """The class's pixels of an ``s x s`` window at least ``INTERIOR`` pixels from its border.

    Pixels along a class border are blends of the two sides (the dark rim of a
    shore on sand); cut into a theme they repeat as a line once per tile, and
    the render draws the border itself. The border is the class region's own,
    not the window's: the mask is read ``INTERIOR`` pixels beyond the window.

    Parameters
    ----------
    mask : (H, W) bool ndarray
        The class region in the photo.
    x, y, s : the window

    Returns
    -------
    (s, s) bool ndarray
    """
    h, w = mask.shape
    r = INTERIOR
    x0, y0, x1, y1 = max(0, x - r), max(0, y - r), min(w, x + s + r), min(h, y + s + r)
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
    # Outside the photo the class goes on (replicated border): the photo's edge is no border.
    inner = cv2.erode(mask[y0:y1, x0:x1].astype(np.uint8), kernel,
                      borderType=cv2.BORDER_REPLICATE)
    return inner[y - y0 : y - y0 + s, x - x0 : x - x0 + s].astype(bool)


def cut_window(rgb: np.ndarray, mask: np.ndarray, x: int, y: int, s: int) -> np.ndarray:
    """The ``s x s`` window at ``(x, y)`` with all but the class's plain texture filled in.

    Other classes' pixels, the class's border rim (:func:`class_interior`) and
    lone objects (:func:`lone_objects`) are filled from the class's own pixels
    of the window (:func:`fill_from_class`).

    Parameters
    ----------
    rgb : (H, W, 3) uint8 ndarray
    mask : (H, W) bool ndarray
        The class region (some pixel of the window in it).
    x, y, s : the window

    Returns
    -------
    (s, s, 3) uint8 ndarray
    """
    window = rgb[y : y + s, x : x + s]
    inner = class_interior(mask, x, y, s)
    if not inner.any():
        inner = mask[y : y + s, x : x + s]
    # Objects are found with the other classes painted in the class's median colour:
    # a dark rim left along a shore is then a line on sand, not the edge of the water.
    seen = window.copy()
    seen[~inner] = np.median(window[inner], axis=0).astype(np.uint8)
    keep = inner & ~lone_objects(seen)
    return window if keep.all() else fill_from_class(window, keep if keep.any() else inner)
