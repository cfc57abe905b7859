"""Small synthetic cases shared by the classifier tests: training pairs, tiled features."""

from __future__ import annotations

import numpy as np
from terratheme.core.classify.features import FeatureOptions, image_features
from terratheme.core.classify.tiled import feature_windows


def block_pairs(n: int = 3, seed: int = 0) -> list[tuple[np.ndarray, np.ndarray]]:
    """``n`` photos of coloured 16-pixel blocks (96 x 112, 3 classes) with their full
    label masks (classes 1..3): (photo (96, 112, 3) uint8, mask (96, 112) uint8) each."""
    rng = np.random.default_rng(seed)
    colours = np.array([(40, 110, 40), (60, 80, 170), (200, 185, 150)], np.float64)
    out = []
    for _ in range(n):
        classes = np.kron(rng.integers(0, 3, (6, 7)), np.ones((16, 16), int))
        photo = np.clip(colours[classes] + rng.normal(0, 6, classes.shape + (3,)), 0, 255)
        out.append((photo.astype(np.uint8), (classes + 1).astype(np.uint8)))
    return out


def assert_tiles_match_whole(photo: np.ndarray, options: FeatureOptions, tile: int,
                             channels: slice = slice(None)) -> None:
    """Features of every tile (with ``options.halo`` of overlap) equal the whole photo's
    in its core, to 1e-3 (``options.scale`` 8; ``channels`` picks the features compared)."""
    h, w = photo.shape[:2]
    whole = image_features(photo, options)[2]
    for win in feature_windows(h, w, tile, 8, options.halo):
        _lab, _std, part = image_features(photo[win.ry:win.ry1, win.rx:win.rx1], options)
        oy, ox = (win.y - win.ry) // 8, (win.x - win.rx) // 8
        core = part[oy:oy + (win.y1 - win.y) // 8, ox:ox + (win.x1 - win.x) // 8, channels]
        np.testing.assert_allclose(
            core, whole[win.y // 8:win.y1 // 8, win.x // 8:win.x1 // 8, channels], atol=1e-3)
