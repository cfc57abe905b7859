"""Inputs shared by the GPU renderer tests (test_gpu_render.py, test_gpu_style.py).

The renderers themselves come from the ``gpu_renderer`` fixture (conftest.py),
which skips where no OpenGL 3.3 context can be made.
"""

from __future__ import annotations

import numpy as np


def random_themes(seed: int, sizes: list[tuple[int, int]]) -> list[np.ndarray]:
    """Random uint8 RGB themes of ``sizes`` ``(w, h)``, drawn from ``seed``."""
    rng = np.random.default_rng(seed)
    return [rng.integers(0, 256, (h, w, 3), dtype=np.uint8) for w, h in sizes]


#: four themes whose sizes divide neither each other nor the textures rendered
ODD_THEMES = random_themes(1, [(7, 5), (13, 17), (16, 16), (3, 11)])
