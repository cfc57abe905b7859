"""Helpers of the exchange tests."""

from __future__ import annotations

import numpy as np
from terratheme.core.exchange.weights import quantised_bands, sample_corners
from terratheme.core.model.grid import validate_indices
from terratheme.core.render.rules import SaddleRule, cell_splits


def theme_weights(grid, size: tuple[int, int], window=None, *, n_themes: int, total: int = 255,
                  saddle: SaddleRule = SaddleRule.MINORITY) -> np.ndarray:
    """Linear weights (K, h, w) of ``grid``'s themes at a ``size = (W, H)`` map's pixels (or a
    ``window``), each theme's share times ``total``: the exports' linear style on a bare grid."""
    indices = validate_indices(grid, n_themes=n_themes)
    splits = cell_splits(indices, saddle)
    return quantised_bands(lambda win: sample_corners(indices, size, win, splits=splits),
                           n_themes, size, window, total=total)
