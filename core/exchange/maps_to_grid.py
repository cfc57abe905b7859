"""The way back: weight maps, splatmaps or control maps from an engine to a vertex grid.

A map spans the grid corner to corner (``core.exchange.layout``), so with
``step`` map pixels per cell the grid vertices are the pixels at multiples of
``step``; each vertex takes the theme with the largest weight there, ties to
the lower theme. A map exported at one pixel per texel (``W = gw * N + 1``)
read back with ``step = N`` gives the exported grid exactly: the texel on a
vertex carries that vertex's theme alone.
"""

from __future__ import annotations

import numpy as np
from terratheme.core.errors import TerrathemeError


def labels_from_weights(weights: np.ndarray, n_themes: int) -> np.ndarray:
    """The strongest theme of every pixel (ties: lower theme) of ``(C, H, W)`` weights.

    Planes ``n_themes..C-1`` (a splatmap's unused channels) must be empty.
    """
    planes = np.asarray(weights)
    if planes.ndim != 3 or planes.shape[0] < n_themes:
        raise TerrathemeError(f"the maps hold {planes.shape[0] if planes.ndim == 3 else 0} "
                              f"weights per pixel, fewer than the {n_themes} themes named")
    extra = planes[n_themes:]
    if extra.size and extra.any():
        c = n_themes + int(np.argmax(extra.reshape(extra.shape[0], -1).any(axis=1)))
        raise TerrathemeError(f"weight channel {c} carries weight but only {n_themes} themes "
                              "were named: name one theme per channel")
    return np.argmax(planes[:n_themes], axis=0).astype(np.uint8)


def grid_from_labels(labels: np.ndarray, step: int) -> np.ndarray:
    """Vertex themes: the labels at every ``step``-th pixel, both ends included.

    Parameters
    ----------
    labels : (H, W) uint8 ndarray
    step : int
        Map pixels per cell; ``W - 1`` and ``H - 1`` must be multiples of it.

    Returns
    -------
    grid : ((H - 1) / step + 1, (W - 1) / step + 1) uint8 ndarray
    """
    h, w = labels.shape
    if step < 1:
        raise TerrathemeError(f"step must be at least 1 map pixel per cell, got {step}")
    if (w - 1) % step or (h - 1) % step:
        raise TerrathemeError(
            f"a {w} x {h} map does not hold whole cells of {step} pixels: width - 1 and "
            f"height - 1 must be multiples of the step (maps span the grid corner to corner)")
    if w < step + 1 or h < step + 1:
        raise TerrathemeError(f"a {w} x {h} map holds no cell of {step} pixels")
    return np.ascontiguousarray(labels[::step, ::step])
