"""Theme weights at an export map's pixels, by the renderer's rule (design.md §1).

Pixel ``(i, j)`` of a ``W x H`` map sits at grid position
``(i * gw / (W - 1), j * gh / (H - 1))``; its corners get the barycentric weights
of :func:`~core.render.rules.corner_weights` exactly, as integers over a common
denominator (local coordinates rounded to 1/16384 of a cell when it passes 2^28).
At ``W = gw * N + 1`` they are the renderer's own. :func:`quantise_weights` rounds
them to 8 or 16 bits summing to exactly 255 (65535) by largest remainder, ties to
the lower theme.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from terratheme.core.errors import TerrathemeError
from terratheme.core.model.grid import validate_indices
from terratheme.core.render.rules import SaddleRule, cell_splits, corner_weights

_EXACT_LIMIT = 1 << 28
_QUANT = 1 << 14
#: pixels per band of the row loop (bounds the int64 temporaries to ~100 MB)
BAND_PIXELS = 1 << 20


@dataclass(frozen=True)
class CornerSlots:
    """The themes of a pixel's four cell corners and their exact weights.

    Attributes
    ----------
    ids : (4, h, w) uint8 ndarray
        Theme of corner slots ``(0, 0), (0, 1), (1, 0), (1, 1)``.
    weights : (4, h, w) int64 ndarray
        Weight times ``denominator``, summing to it; a slot whose theme an earlier
        slot carries holds 0, so a pixel's non-zero slots have distinct themes.
    denominator : int, or (h, w) int64 ndarray
        One for the map, or one per pixel (the shaped blend's, :mod:`.shaped`).
    """

    ids: np.ndarray
    weights: np.ndarray
    denominator: int | np.ndarray


def _axis(n_pixels: int, cells: int, start: int, count: int) -> tuple[np.ndarray, np.ndarray, int]:
    """Cell index, local numerator and denominator of pixels ``start..start+count`` on one axis."""
    den = n_pixels - 1
    g = math.gcd(cells, den)
    step, den = cells // g, den // g
    num = (start + np.arange(count, dtype=np.int64)) * step
    cell = np.minimum(num // den, cells - 1)
    return cell, num - cell * den, den


def check_window(window: tuple[int, int, int, int] | None, size: tuple[int, int]
                 ) -> tuple[int, int, int, int]:
    """``(x, y, w, h)`` of ``window`` (None: the whole ``size = (W, H)`` map), checked inside it."""
    full_w, full_h = size
    if window is None:
        return 0, 0, full_w, full_h
    x, y, w, h = (int(v) for v in window)
    if w < 1 or h < 1 or x < 0 or y < 0 or x + w > full_w or y + h > full_h:
        raise TerrathemeError(f"window {window} is outside the {full_w} x {full_h} map")
    return x, y, w, h


def map_cells(indices: np.ndarray, size: tuple[int, int],
              window: tuple[int, int, int, int] | None, saddle: SaddleRule,
              splits: np.ndarray | None) -> tuple[tuple[int, int, int, int], np.ndarray]:
    """The checked ``(x, y, w, h)`` window (None: whole) of a ``size = (W, H)`` export map
    and the grid's cell splits (``splits`` when the caller has them)."""
    if size[0] < 2 or size[1] < 2:
        raise TerrathemeError(f"an export map needs at least 2 x 2 pixels, got {size}")
    window = check_window(window, size)
    return window, cell_splits(indices, saddle) if splits is None else splits


def sample_corners(
    grid: np.ndarray,
    size: tuple[int, int],
    window: tuple[int, int, int, int] | None = None,
    *,
    saddle: SaddleRule = SaddleRule.MINORITY,
    splits: np.ndarray | None = None,
) -> CornerSlots:
    """Corner themes and exact weights at the pixels of a ``size = (W, H)`` map.

    ``grid`` (gh+1, gw+1) uint8 spans the whole map corner to corner; ``window``
    ``(x, y, w, h)`` picks a tile or band of it; ``splits`` are
    ``cell_splits(grid, saddle)`` when the caller has them.
    """
    indices = validate_indices(grid)
    gh, gw = indices.shape[0] - 1, indices.shape[1] - 1
    (x, y, w, h), splits = map_cells(indices, size, window, saddle, splits)
    cx, lx, dx = _axis(size[0], gw, x, w)
    cy, ly, dy = _axis(size[1], gh, y, h)
    # Denominators too large for corner_weights' int32: round local coordinates to 1/16384.
    if dx * dy > _EXACT_LIMIT:
        lx, dx = (lx * _QUANT + dx // 2) // dx, _QUANT
        ly, dy = (ly * _QUANT + dy // 2) // dy, _QUANT
    cell_split = splits[cy[:, None], cx[None, :]]
    # Barycentric weights of the four corners, times D = dx * dy.
    ws = corner_weights(cell_split, (lx * dy)[None, :], (ly * dx)[:, None], dx * dy)
    ids = np.stack([indices[cy[:, None] + dr, cx[None, :] + dc]
                    for dr, dc in ((0, 0), (0, 1), (1, 0), (1, 1))])
    weights = np.stack(ws).astype(np.int64)
    # Corners with the same theme add up: each weight moves to the first slot of its theme.
    for c in range(1, 4):
        merged = np.zeros((h, w), dtype=bool)
        for p in range(c):
            same = (ids[c] == ids[p]) & ~merged
            weights[p] += np.where(same, weights[c], 0)
            merged |= same
        weights[c][merged] = 0
    return CornerSlots(ids, weights, dx * dy)


def slot_ranks(keys: np.ndarray, ids: np.ndarray) -> np.ndarray:
    """Rank (S, h, w) int8 of every slot per pixel of ``keys``, ``ids`` (S, h, w): larger
    keys first, ties to the lower theme, then slot."""
    n = keys.shape[0]
    rank = np.zeros(keys.shape, dtype=np.int8)
    for c in range(n):
        for o in range(n):
            if o == c:
                continue
            tie = keys[o] == keys[c]
            before = (keys[o] > keys[c]) | (tie & (ids[o] < ids[c]))
            if o < c:
                before |= tie & (ids[o] == ids[c])
            rank[c] += before
    return rank


def quantise_weights(slots: CornerSlots, n_themes: int, *, total: int = 255) -> np.ndarray:
    """Weights (K, h, w) summing to exactly ``total`` per pixel (largest remainder).

    One plane per theme of the library (``K = n_themes``); uint8 for ``total`` 255,
    uint16 above.
    """
    if int(slots.ids.max(initial=0)) >= n_themes:
        raise TerrathemeError(f"grid uses theme {int(slots.ids.max())} of only {n_themes}")
    d = slots.denominator
    share, remainder = np.divmod(slots.weights * total, d)
    # The units the floors miss go to the largest remainders (ties: lower theme).
    missing = total - share.sum(axis=0)
    share += slot_ranks(remainder, slots.ids) < missing[None]
    dtype = np.uint8 if total <= 255 else np.uint16
    h, w = slots.ids.shape[1:]
    out = np.zeros(n_themes * h * w, dtype=dtype)
    pixel = np.arange(h * w)
    # Scatter each slot into its theme's plane (the non-zero slots of a pixel differ in theme).
    for c in range(4):
        plane = slots.ids[c].ravel().astype(np.intp) * (h * w)
        out[plane + pixel] += share[c].ravel().astype(dtype)
    return out.reshape(n_themes, h, w)


def quantised_bands(slots_of: Callable[[tuple[int, int, int, int]], CornerSlots],
                    n_themes: int, size: tuple[int, int],
                    window: tuple[int, int, int, int] | None, *, total: int = 255) -> np.ndarray:
    """:func:`quantise_weights` of ``slots_of((x, y, w, h))`` over row bands of
    ``window`` of a ``size = (W, H)`` map (bounded temporaries)."""
    x, y, w, h = check_window(window, size)
    out = np.zeros((n_themes, h, w), dtype=np.uint8 if total <= 255 else np.uint16)
    rows = max(1, BAND_PIXELS // w)
    # Row bands bound the temporaries; every pixel is computed on its own, so bands agree.
    for r0 in range(0, h, rows):
        r1 = min(h, r0 + rows)
        out[:, r0:r1] = quantise_weights(slots_of((x, y + r0, w, r1 - r0)), n_themes,
                                         total=total)
    return out


def strongest_two(slots: CornerSlots) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The two strongest themes (h, w) uint8 of every pixel and ``share``
    ``= round(255 * w2 / (w1 + w2))`` (half up), the second's weight in the pair.

    Ties go to the lower theme; a pixel with one theme has it twice, share 0.
    """
    rank = slot_ranks(slots.weights, slots.ids)
    pick = [np.argmax(rank == r, axis=0)[None] for r in (0, 1)]
    first, second = (np.take_along_axis(slots.ids, p, axis=0)[0] for p in pick)
    w1, w2 = (np.take_along_axis(slots.weights, p, axis=0)[0] for p in pick)
    second = np.where(w2 > 0, second, first)
    pair = w1 + w2
    share = (2 * 255 * w2 + pair) // (2 * pair)
    return first, second, share.astype(np.uint8)
