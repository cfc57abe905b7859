"""Theme weights of shaped boundaries (:mod:`core.render.boundary`) at export-map pixels.

With shaped boundaries the renderer's texel is ``sum(v_t * T_t) / sum(v_t)``, so
weights ``v_t / sum(v_t)`` splatted over the same themes show the same borders. The
``v_t`` come from the boundary kernel itself, in its integers. The rule is defined on
whole texels: pixel ``i`` of a ``W``-pixel map takes the texel nearest
``i * Wtex / (W - 1)``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from terratheme.core.exchange.layout import nearest_texels
from terratheme.core.exchange.weights import CornerSlots, map_cells
from terratheme.core.model.grid import validate_indices
from terratheme.core.render.boundary import BoundaryOptions, shaped_weights
from terratheme.core.render.inputs import theme_textures
from terratheme.core.render.rules import SaddleRule


def shaped_slots(
    grid: np.ndarray,
    themes: Sequence[np.ndarray],
    cell: tuple[int, int],
    size: tuple[int, int],
    window: tuple[int, int, int, int] | None = None,
    *,
    boundary: BoundaryOptions,
    saddle: SaddleRule = SaddleRule.MINORITY,
    splits: np.ndarray | None = None,
) -> CornerSlots:
    """The shaped blend's ``v_t`` at the pixels of a ``size = (W, H)`` map (or a window).

    Arguments as :func:`core.exchange.weights.sample_corners`, plus the ``themes``
    (their luminance shapes the borders); the denominator is ``sum(v_t)`` per pixel.
    """
    textures = theme_textures(themes)
    # Writeable C arrays: one kernel signature (numba types read-only arrays apart).
    indices = np.require(validate_indices(grid, n_themes=len(textures)), np.uint8, ("C", "W"))
    n, m = (int(v) for v in cell)
    gh, gw = indices.shape[0] - 1, indices.shape[1] - 1
    (x, y, w, h), splits = map_cells(indices, size, window, saddle, splits)
    xs = nearest_texels(size[0], gw * n, x, w)
    ys = nearest_texels(size[1], gh * m, y, h)
    ids, weights, denom = shaped_weights(indices, splits, textures, (n, m), xs, ys,
                                         boundary.parameters(n, m))
    return CornerSlots(ids, weights, denom)
