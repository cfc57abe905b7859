"""How each cell is split and weighted (Vyatkin & Romanyuk, design.md §1).

Texel ``(xs, ys)`` of a cell has local coordinates ``x = xs/N``, ``y = ys/M``; with
``D = N*M`` every barycentric weight times ``D`` is an integer and the blend is rounded
half up, ``out = floor((2 * sum(w_k * T_k) + D) / (2 * D))``. Splits (``cell_splits``):
``UNIFORM``, ``MAIN``, ``ANTI`` along the equal-ended diagonal; saddles (``A B / B A``)
give the diagonal to the theme with fewer vertices in the ring of 12 (docs/design.md §1).
"""

from __future__ import annotations

from enum import Enum

import numpy as np
from terratheme.core.errors import TerrathemeError

UNIFORM, MAIN, ANTI = 0, 1, 2


class SaddleRule(Enum):
    """How a saddle cell ``A B / B A`` is split."""

    #: connect the theme with fewer vertices in the 12-vertex ring (tie: lower index)
    MINORITY = "minority"
    #: always split along ``ind[0][0]``-``ind[1][1]`` (the paper's first branch)
    MAIN = "main"


def _ring_count(grid: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Count, for every cell, the ring vertices (4x4 block minus the 2x2 cell) equal to ``values``.

    ``values`` (gh, gw) uint8 holds the theme to count per cell; returns (gh, gw)
    int32. Vertices outside the grid are not counted.
    """
    gh, gw = grid.shape[0] - 1, grid.shape[1] - 1
    # Pad with a value that matches nothing (256 does not fit uint8: use int16).
    pad = np.full((gh + 3, gw + 3), -1, dtype=np.int16)
    pad[1:-1, 1:-1] = grid
    count = np.zeros((gh, gw), dtype=np.int32)
    for dr in range(4):
        for dc in range(4):
            if dr in (1, 2) and dc in (1, 2):
                continue
            count += pad[dr : dr + gh, dc : dc + gw] == values
    return count


def cell_splits(grid: np.ndarray, rule: SaddleRule = SaddleRule.MINORITY) -> np.ndarray:
    """The ``(gh, gw)`` uint8 split of every cell: ``UNIFORM`` (0), ``MAIN`` (1) or ``ANTI`` (2)."""
    a, b = grid[:-1, :-1], grid[:-1, 1:]
    c, d = grid[1:, :-1], grid[1:, 1:]
    main_eq = a == d
    anti_eq = b == c
    uniform = main_eq & anti_eq & (a == b)
    splits = np.full(a.shape, MAIN, dtype=np.uint8)
    # Only the anti-diagonal has equal ends.
    splits[anti_eq & ~main_eq] = ANTI
    # Saddle: both diagonals equal-ended with different themes.
    saddle = main_eq & anti_eq & ~uniform
    if rule is SaddleRule.MINORITY and saddle.any():
        ca = _ring_count(grid, a)
        cb = _ring_count(grid, b)
        anti_wins = (cb < ca) | ((cb == ca) & (b < a))
        splits[saddle & anti_wins] = ANTI
    splits[uniform] = UNIFORM
    return splits


def corner_weights(
    split: np.ndarray, xi: np.ndarray, yi: np.ndarray, d: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Integer barycentric weights (times ``D``) of the four cell corners (design.md §1 step 2).

    ``split`` is ``UNIFORM``/``MAIN``/``ANTI`` per texel, ``xi, yi`` are ``xs*M`` and
    ``ys*N`` (local coordinates times ``d = N*M``), all broadcastable. Returns int32
    ``w00, w01, w10, w11``, the weights of ``ind[0][0]``, ``ind[0][1]``, ``ind[1][0]``,
    ``ind[1][1]``, summing to ``d``; uniform cells put everything on ``ind[0][0]``.
    """
    xi = np.asarray(xi, dtype=np.int32)
    yi = np.asarray(yi, dtype=np.int32)
    split = np.asarray(split)
    shape = np.broadcast_shapes(split.shape, xi.shape, yi.shape)
    xi, yi, split = (np.broadcast_to(v, shape) for v in (xi, yi, split))
    zero = np.zeros(shape, dtype=np.int32)
    main, anti = split == MAIN, split == ANTI
    lower = xi <= yi  # MAIN: x <= y triangle
    near = xi + yi <= d  # ANTI: x + y <= 1 triangle
    # MAIN, x <= y: T10*(y-x) + T00*(1-y) + T11*x ; x > y: T01*(x-y) + T00*(1-x) + T11*y
    m00 = np.where(lower, d - yi, d - xi)
    m01 = np.where(lower, zero, xi - yi)
    m10 = np.where(lower, yi - xi, zero)
    m11 = np.where(lower, xi, yi)
    # ANTI, x+y <= 1: T00*(1-x-y) + T01*x + T10*y ; else T11*(x+y-1) + T01*(1-y) + T10*(1-x)
    a00 = np.where(near, d - xi - yi, zero)
    a01 = np.where(near, xi, d - yi)
    a10 = np.where(near, yi, d - xi)
    a11 = np.where(near, zero, xi + yi - d)
    w00 = np.where(main, m00, np.where(anti, a00, d)).astype(np.int32)
    w01 = np.where(main, m01, np.where(anti, a01, 0)).astype(np.int32)
    w10 = np.where(main, m10, np.where(anti, a10, 0)).astype(np.int32)
    w11 = np.where(main, m11, np.where(anti, a11, 0)).astype(np.int32)
    return w00, w01, w10, w11


def checked_splits(splits: object, indices: np.ndarray, rule: SaddleRule) -> np.ndarray:
    """The per-cell splits: computed by ``rule``, or the caller's choice where a cell is mixed."""
    auto = cell_splits(indices, rule)
    if splits is None:
        return auto
    arr = np.asarray(splits)
    if arr.shape != auto.shape or arr.dtype.kind not in "iu":
        raise TerrathemeError(
            f"splits must be a {auto.shape} integer array (0 auto, 1 main, 2 anti diagonal), "
            f"got shape {arr.shape} dtype {arr.dtype}"
        )
    if arr.size and (arr.min() < 0 or arr.max() > 2):
        raise TerrathemeError("splits values must be 0 (auto), 1 (main) or 2 (anti diagonal)")
    # Uniform cells stay uniform; 0 elsewhere means "use the rule".
    chosen = np.where((auto == 0) | (arr == 0), auto, arr)
    return np.ascontiguousarray(chosen, dtype=np.uint8)


def region_splits(
    indices: np.ndarray, splits: object, rule: SaddleRule, cells: tuple[int, int, int, int]
) -> np.ndarray:
    """Splits of cells ``cy0..cy1 x cx0..cx1`` only (the ring rule needs one more vertex around).

    ``splits``: the caller's per-cell choice over the whole grid (:func:`checked_splits`),
    or None for ``rule``'s. Returns a ``(cy1-cy0+1, cx1-cx0+1)`` uint8 C-contiguous array.
    """
    cy0, cy1, cx0, cx1 = cells
    if splits is not None:
        return np.ascontiguousarray(checked_splits(splits, indices, rule)[cy0 : cy1 + 1,
                                                                         cx0 : cx1 + 1])
    vy0, vx0 = max(cy0 - 1, 0), max(cx0 - 1, 0)
    block = indices[vy0 : cy1 + 3, vx0 : cx1 + 3]
    # Cells of the block at the grid border see the true border (nothing beyond it).
    part = cell_splits(block, rule)
    return np.ascontiguousarray(part[cy0 - vy0 : cy1 - vy0 + 1, cx0 - vx0 : cx1 - vx0 + 1])
