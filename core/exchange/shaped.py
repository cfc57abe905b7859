"""Theme weights of shaped boundaries (:mod:`core.render.boundary`) at export-map pixels.

With shaped boundaries the renderer's texel is ``sum(v_t * T_t) / sum(v_t)``
(the boundary module's steps 1-3: barycentric weights, a score per theme
from noise and the themes' luminance, a border of the given width around
the best score). The weights of that blend are ``v_t / sum(v_t)``: an engine
that splats them over the same themes shows the same borders. This module
computes the ``v_t`` in the boundary kernel's own integers, with its own
pieces (:func:`core.render.kernels.cell_corners` and
:func:`~core.render.kernels.merged_weights` for the corners and step 1,
:func:`core.render.boundary.shaped_weight_rows`, which the overview
renderer uses too), so the colours
they give are the renderer's exactly (``tests/test_exchange_shaped.py``).

Where pixels lie: the rule is defined on whole texels, so pixel ``i`` of a
``W``-pixel map takes the texel nearest its position ``i * Wtex / (W - 1)``
(:func:`core.exchange.layout.nearest_texels`): at ``W = Wtex + 1`` pixel ``i``
is texel ``i``. The far edge (texel ``Wtex`` or row ``Htex``, the grid's last
vertices) lies in the last cell at local coordinate 1; the texel on a vertex
carries that vertex's theme alone, as in the renderer.
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
    """The shaped blend's weights at the pixels of a ``size = (W, H)`` map (or a window of it).

    Parameters
    ----------
    grid, size, window, saddle, splits
        As :func:`core.exchange.weights.sample_corners`.
    themes : sequence of (h, w, 3) uint8 ndarrays
        The textures the render blends (their luminance shapes the borders).
    cell : (N, M)
    boundary : BoundaryOptions
        The project's border style (``core.render.project.project_style``).

    Returns
    -------
    CornerSlots
        ``(4, h, w)`` corner themes and their ``v_t``, and the per-pixel
        ``(h, w)`` int64 denominator ``sum(v_t)``.
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
