"""Gaussianisation of a theme, the first step of the histogram-preserving blend.

Heitz & Neyret, "High-Performance By-Example Noise using a Histogram-Preserving Blending
Operator", HPG 2018: each channel goes through its own CDF and the inverse normal CDF,
so variance-preserving blends keep each theme's histogram.
"""

from __future__ import annotations

import numpy as np
from scipy.special import ndtri


def gaussianise(texture: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-channel Gaussianisation of an (h, w, 3) uint8 texture (Heitz & Neyret 2018).

    Returns
    -------
    g : (h, w, 3) float32 ndarray
        ``Phi^-1((rank + 0.5) / n)``: standard-normal values with the texel order.
    sorted_vals : (3, h*w) float32 ndarray
        Each channel's values sorted; ``sorted_vals[c][rank]`` inverts ``g``.
    """
    h, w, _ = texture.shape
    n = h * w
    flat = texture.reshape(n, 3)
    g = np.empty((n, 3), dtype=np.float32)
    sorted_vals = np.empty((3, n), dtype=np.float32)
    # The Gaussian value of each rank, shared by all channels.
    normal = ndtri((np.arange(n) + 0.5) / n).astype(np.float32)
    for c in range(3):
        order = np.argsort(flat[:, c], kind="stable")
        g[order, c] = normal
        sorted_vals[c] = flat[order, c]
    return g.reshape(h, w, 3), sorted_vals
