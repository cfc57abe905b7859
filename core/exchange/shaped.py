"""Theme weights of shaped boundaries (:mod:`core.render.boundary`) at export-map pixels.

With shaped boundaries the renderer's texel is ``sum(v_t * T_t) / sum(v_t)``
(the boundary module's steps 1-3: barycentric weights, a score per theme
from noise and the themes' luminance, a border of the given width around
the best score). The weights of that blend are ``v_t / sum(v_t)``: an engine
that splats them over the same themes shows the same borders. This module
computes the ``v_t`` in the boundary kernel's own integers, with its own
pieces (:func:`core.render.kernels.cell_corners` and
:func:`~core.render.kernels.merged_weights` for the corners and step 1,
:func:`core.render.boundary.border_weights` and
:class:`~core.render.boundary.BoundaryParams` for step 2), so the colours
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

import numba as nb
import numpy as np

from core.errors import TerrathemeError
from core.exchange.layout import nearest_texels
from core.exchange.weights import CornerSlots, check_window
from core.model.grid import validate_indices
from core.render.boundary import BoundaryOptions, border_weights
from core.render.inputs import theme_textures
from core.render.kernels import RegionBlock, ThemeRows, cell_corners, merged_weights
from core.render.rules import SaddleRule, cell_splits
from core.render.theme_pack import pack_themes


@nb.njit(cache=True, nogil=True)
def shaped_weight_rows(ids, weights, denom, xs, ys, block, edge, themes, params
                       ):  # pragma: no cover - numba
    """Fill the slots of pixels at texel columns ``xs`` and rows ``ys`` with the ``v_t``.

    ``ids`` (4, h, w) uint8 and ``weights`` (4, h, w) int64 get every pixel's
    corner themes and their ``v_t`` (0 for a corner merged into an earlier one
    of its theme or out of the border), ``denom`` (h, w) int64 their sum.
    ``block`` a :class:`core.render.kernels.RegionBlock` of the whole grid,
    ``edge`` the same offset by one cell row (for the far edge row ``Htex``),
    ``themes`` :class:`core.render.kernels.ThemeRows`, ``params``
    :class:`core.render.boundary.BoundaryParams`.
    """
    grid, splits, ocx, ocy, rx, ry, n, m = block
    flat = themes[0]
    gh, gw = splits.shape[0], splits.shape[1]
    d = n * m
    ks = np.zeros(4, np.int64)
    ws = np.zeros(4, np.int64)
    bs = np.zeros(4, np.int64)
    sc = np.zeros(4, np.int64)
    for r in range(ys.size):
        gy = ys[r]
        cy = min(gy // m, gh - 1)
        rows = edge if gy == gh * m else block
        yi = (gy - cy * m) * n
        for c in range(xs.size):
            x = xs[c]
            cx = min(x // n, gw - 1)
            # The cell's corner themes, and each theme's texel at (x, gy).
            sp = cell_corners(rows, themes, cx, gy, x, ks, bs)
            for a in range(4):
                ids[a, r, c] = ks[a]
                weights[a, r, c] = 0
            if sp == 0:
                # A uniform cell: its one theme at full weight.
                weights[0, r, c] = 1
                denom[r, c] = 1
                continue
            # Step 1: the barycentric weights, corners of one theme merged.
            merged_weights(sp, (x - cx * n) * m, yi, d, ks, ws)
            # Steps 2-3 of the boundary blend: the v_t are the weights.
            total = border_weights(ks, ws, bs, 0, flat, x, gy, d, params, sc)
            for a in range(4):
                weights[a, r, c] = sc[a]
            denom[r, c] = total


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
    grid : (gh+1, gw+1) uint8 ndarray
        Vertex theme indices.
    themes : sequence of (h, w, 3) uint8 ndarrays
        The textures the render blends (their luminance shapes the borders).
    cell : (N, M)
    size : (W, H)
        The whole map, spanning the grid corner to corner (both >= 2).
    window : (x, y, w, h), optional
    boundary : BoundaryOptions
        The project's border style (``core.render.project.project_style``).
    saddle : SaddleRule
    splits : (gh, gw) uint8 ndarray, optional
        ``cell_splits(grid, saddle)`` when the caller has it already.

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
    if size[0] < 2 or size[1] < 2:
        raise TerrathemeError(f"an export map needs at least 2 x 2 pixels, got {size}")
    x, y, w, h = check_window(window, size)
    if splits is None:
        splits = cell_splits(indices, saddle)
    splits = np.require(splits, np.uint8, ("C", "W"))
    packed = pack_themes(textures, n)
    rows = ThemeRows(packed.flat, packed.off, packed.stride, packed.th, packed.tw)
    block = RegionBlock(indices, splits, 0, 0, 0, 0, n, m)
    # The far edge row: the same grid one cell row on, so cell_corners finds the last row.
    edge = RegionBlock(indices[gh - 1 :], splits[gh - 1 :], 0, gh, 0, 0, n, m)
    xs = nearest_texels(size[0], gw * n, x, w)
    ys = nearest_texels(size[1], gh * m, y, h)
    ids = np.empty((4, h, w), np.uint8)
    weights = np.empty((4, h, w), np.int64)
    denom = np.empty((h, w), np.int64)
    shaped_weight_rows(ids, weights, denom, xs, ys, block, edge, rows,
                       boundary.parameters(n, m))
    return CornerSlots(ids, weights, denom)
