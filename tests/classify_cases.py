"""Small synthetic training pairs shared by the classifier cache tests."""

from __future__ import annotations

import numpy as np


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
