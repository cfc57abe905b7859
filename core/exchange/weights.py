"""Theme weights at an export map's pixels, by the renderer's rule (design.md §1).

Pixel ``(i, j)`` of a ``W x H`` map sits at grid position
``(i * gw / (W - 1), j * gh / (H - 1))`` (``core.exchange.layout``). Its cell
is split by :func:`~core.render.rules.cell_splits` (saddle rule included) and
its four corners get the barycentric weights of
:func:`~core.render.rules.corner_weights`, computed exactly: the local
coordinates are the integer fractions ``(i * gw mod (W - 1)) / (W - 1)``
(reduced), so the weights are integers over a common denominator ``D``. At
``W = gw * N + 1`` the pixels are the renderer's texels and the weights are
the renderer's own. (Were ``D`` above ``2**28``, the local coordinates are
rounded to ``1/16384`` of a cell first.)

Corners carrying the same theme add up. :func:`quantise_weights` turns the
exact weights (these, or the shaped blend's of :mod:`core.exchange.shaped`,
whose denominator differs per pixel) into 8-bit (or 16-bit) weights that
sum to exactly 255 (65535) per pixel by largest-remainder rounding: every
theme gets the floor of its share, and the units still missing go to the
largest remainders, ties to the lower theme index (deterministic, and no
theme moves by a whole unit).
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
        Theme of corner slot ``ind[0][0], ind[0][1], ind[1][0], ind[1][1]``.
    weights : (4, h, w) int64 ndarray
        Weight times ``denominator``; a slot whose theme an earlier slot of
        the same pixel carries holds 0 (its weight moved there), so the
        non-zero slots of a pixel have distinct themes. Sums to ``denominator``.
    denominator : int, or (h, w) int64 ndarray
        One for the whole map (the barycentric weights), or one per pixel
        (the shaped blend's ``sum(v_t)``, :mod:`core.exchange.shaped`).
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
    """The checked window of a ``size = (W, H)`` export map and the grid's cell splits.

    Parameters
    ----------
    indices : (gh+1, gw+1) uint8 ndarray
        Checked vertex theme indices.
    size : (W, H)
        Both at least 2.
    window : (x, y, w, h) or None
        None: the whole map.
    saddle : SaddleRule
    splits : (gh, gw) uint8 ndarray or None
        ``cell_splits(indices, saddle)`` when the caller has it already.

    Returns
    -------
    window : (x, y, w, h)
    splits : (gh, gw) uint8 ndarray
    """
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

    Parameters
    ----------
    grid : (gh+1, gw+1) uint8 ndarray
        Vertex theme indices.
    size : (W, H)
        The whole map, spanning the grid corner to corner (both >= 2).
    window : (x, y, w, h), optional
        Only these pixels of the map (a tile or a band).
    saddle : SaddleRule
    splits : (gh, gw) uint8 ndarray, optional
        ``cell_splits(grid, saddle)`` when the caller has it already.

    Returns
    -------
    CornerSlots
        Arrays of shape ``(4, h, w)``.
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
    """Rank of every slot per pixel: larger ``keys`` first, ties to the lower theme, then slot.

    Parameters
    ----------
    keys, ids : (S, h, w) ndarrays

    Returns
    -------
    rank : (S, h, w) int8 ndarray, 0 for the first slot
    """
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
    """Per-theme weights summing to exactly ``total`` per pixel (largest remainder).

    Parameters
    ----------
    slots : CornerSlots
    n_themes : int
        ``K``: the output has one plane per theme of the library.
    total : int
        255 for 8-bit maps, 65535 for 16-bit ones.

    Returns
    -------
    weights : (K, h, w) uint8 ndarray (uint16 when ``total > 255``)
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


def theme_weights(
    grid: np.ndarray,
    size: tuple[int, int],
    window: tuple[int, int, int, int] | None = None,
    *,
    n_themes: int,
    total: int = 255,
    saddle: SaddleRule = SaddleRule.MINORITY,
) -> np.ndarray:
    """8-bit theme weights of a ``size = (W, H)`` map (or a window of it), summing to 255.

    Parameters
    ----------
    grid : (gh+1, gw+1) uint8 ndarray
    size : (W, H)
    window : (x, y, w, h), optional
    n_themes : int
    total : int
        255 (uint8 output) or up to 65535 (uint16 output).
    saddle : SaddleRule

    Returns
    -------
    weights : (K, h, w) uint8 (or uint16) ndarray
        ``weights[k]`` is theme ``k``'s weight times ``total`` at every pixel.

    Examples
    --------
    A one-cell grid of themes 0 and 1 split along its anti-diagonal, sampled
    at its four corners and centre (a 3 x 3 map):

    >>> theme_weights(np.array([[0, 1], [1, 1]], np.uint8), (3, 3), n_themes=2)[0]
    array([[255, 128,   0],
           [128,   0,   0],
           [  0,   0,   0]], dtype=uint8)
    """
    indices = validate_indices(grid, n_themes=n_themes)
    splits = cell_splits(indices, saddle)
    return quantised_bands(lambda win: sample_corners(indices, size, win, splits=splits),
                           n_themes, size, window, total=total)


def quantised_bands(slots_of: Callable[[tuple[int, int, int, int]], CornerSlots],
                    n_themes: int, size: tuple[int, int],
                    window: tuple[int, int, int, int] | None, *, total: int = 255) -> np.ndarray:
    """:func:`quantise_weights` of ``slots_of(band)`` over row bands of a window of a map.

    Parameters
    ----------
    slots_of : callable((x, y, w, h)) -> CornerSlots
        The exact weights of a window of the ``size = (W, H)`` map.
    n_themes, total : int
    size : (W, H)
    window : (x, y, w, h), optional

    Returns
    -------
    weights : (K, h, w) uint8 (or uint16) ndarray
    """
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
    """The two strongest themes of every pixel and the second one's share of the pair.

    Ties go to the lower theme. A pixel with one theme has it twice, share 0.

    Returns
    -------
    first, second : (h, w) uint8 ndarrays
    share : (h, w) uint8 ndarray
        ``round(255 * w2 / (w1 + w2))`` (half up): the weight of ``second``
        once the pair is renormalised (a third theme's weight is dropped).
    """
    rank = slot_ranks(slots.weights, slots.ids)
    pick = [np.argmax(rank == r, axis=0)[None] for r in (0, 1)]
    first, second = (np.take_along_axis(slots.ids, p, axis=0)[0] for p in pick)
    w1, w2 = (np.take_along_axis(slots.weights, p, axis=0)[0] for p in pick)
    second = np.where(w2 > 0, second, first)
    pair = w1 + w2
    share = (2 * 255 * w2 + pair) // (2 * pair)
    return first, second, share.astype(np.uint8)
