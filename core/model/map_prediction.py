"""The colour map's prediction from the index grid: each theme's colour between its vertices.

The reader of a project already holds the grid, so a coded colour map may carry only what
the grid does not say: AVIF codes ``stored - prediction + 128``, and a reader adds the
prediction back (docs/formats.md, predicted maps; docs/decisions.md, issue 34). The
prediction is each theme's colour (``class_colours``: the mean stored gain of the map
pixels nearest its vertices) at every vertex, interpolated bilinearly at each map pixel's
centre and blurred by half a cell (a cell-sized step costs the codec more than it saves).
It is computed in float64 from integers and rounded, so writer and reader agree.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter1d
from terratheme.core.model.colour_map import NEUTRAL

#: the prediction's blur, in cells (sigma)
BLUR_CELLS = 0.5
#: Gaussian taps reach this many sigmas
TRUNCATE = 3.0
#: map rows computed at a time (memory bounded on a region's map)
BAND_ROWS = 256


def nearest_vertices(count: int, scale: int, cell: int, vertices: int) -> np.ndarray:
    """(count,) int: along an axis, the vertex nearest each ``scale``-texel map pixel."""
    centre = (np.arange(count) + 0.5) * scale
    return np.clip(np.floor(centre / cell + 0.5).astype(np.int64), 0, vertices - 1)


def class_sums(stored: np.ndarray, indices: np.ndarray, cell: tuple[int, int], scale: int,
               n_themes: int, origin: tuple[int, int] = (0, 0)
               ) -> tuple[np.ndarray, np.ndarray]:
    """``(counts (n_themes,) int64, sums (n_themes, 3) float64)``: per theme, the map
    pixels nearest its vertices and their stored gains, over ``stored``, the block of a
    map at ``scale`` whose first pixel is map pixel ``origin`` ``(row, col)``."""
    mh, mw = stored.shape[:2]
    vh, vw = indices.shape
    rows = nearest_vertices(origin[0] + mh, scale, cell[1], vh)[origin[0]:]
    cols = nearest_vertices(origin[1] + mw, scale, cell[0], vw)[origin[1]:]
    counts = np.zeros(n_themes, np.int64)
    sums = np.zeros((n_themes, 3), np.float64)
    for r0 in range(0, mh, BAND_ROWS):
        # The theme at each map pixel of the band, then per-theme channel sums.
        band = slice(r0, min(r0 + BAND_ROWS, mh))
        theme = indices[rows[band, None], cols[None, :]].ravel().astype(np.int64)
        counts += np.bincount(theme, minlength=n_themes)[:n_themes]
        for c in range(3):
            sums[:, c] += np.bincount(theme, weights=stored[band, :, c].ravel(),
                                      minlength=n_themes)[:n_themes]
    return counts, sums


def mean_colours(counts: np.ndarray, sums: np.ndarray) -> np.ndarray:
    """``(K, 3)`` uint8 means of :func:`class_sums` (:data:`NEUTRAL` for a theme with none)."""
    colours = np.full((len(counts), 3), NEUTRAL, np.uint8)
    seen = counts > 0
    colours[seen] = np.clip(np.rint(sums[seen] / counts[seen, None]), 0, 255)
    return colours


def class_colours(stored: np.ndarray, indices: np.ndarray, cell: tuple[int, int],
                  scale: int, n_themes: int) -> np.ndarray:
    """``(n_themes, 3)`` uint8: each theme's mean stored gain over the map pixels nearest
    its vertices (:data:`NEUTRAL` for a theme with none).

    ``stored`` (mh, mw, 3) uint8: a map at ``scale`` texels per pixel; ``indices``
    (vh, vw) uint8: the grid's vertices, ``cell`` ``(N, M)`` texels a cell.
    """
    return mean_colours(*class_sums(stored, indices, cell, scale, n_themes))


def _axis_weights(count: int, scale: int, cell: int, vertices: int
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Along an axis: the vertex below each map pixel's centre, the one above and the
    weight of the one above (bilinear, clamped at the last vertex)."""
    at = np.clip((np.arange(count) + 0.5) * scale / cell, 0.0, vertices - 1.0)
    low = np.minimum(np.floor(at).astype(np.int64), vertices - 1)
    high = np.minimum(low + 1, vertices - 1)
    return low, high, at - low


def _reach(sigma: float) -> int:
    """Map pixels the blur of ``sigma`` reads on each side (scipy's radius; 0: no blur)."""
    return int(TRUNCATE * sigma + 0.5) if sigma >= 0.5 else 0


def _blurred(plane: np.ndarray, sigma: float, axis: int) -> np.ndarray:
    if sigma < 0.5:
        return plane
    return gaussian_filter1d(plane, sigma, axis=axis, mode="nearest", truncate=TRUNCATE)


def class_prediction(indices: np.ndarray, cell: tuple[int, int], colours: np.ndarray,
                     scale: int, shape: tuple[int, int],
                     window: tuple[int, int, int, int] | None = None) -> np.ndarray:
    """``(mh, mw, 3)`` uint8: the map a grid predicts at ``scale`` texels a map pixel.

    ``indices`` (vh, vw) uint8 theme per vertex (vertex ``(r, c)`` at texel ``(c N, r M)``
    for ``cell`` ``(N, M)``); ``colours`` (K, 3) uint8 per theme; ``shape`` ``(mh, mw)``.
    Map pixel ``(i, j)`` takes the vertex colours bilinearly at its centre ``((j + 0.5)
    scale, (i + 0.5) scale)``, then a Gaussian of sigma :data:`BLUR_CELLS` cells
    (edge pixels replicated, an axis under 0.5 map pixels not blurred), rounded. Made
    :data:`BAND_ROWS` rows at a time with the blur's reach around them: the same pixels.
    ``window`` ``(r0, r1, c0, c1)``: only those map rows and columns (the same values).
    """
    mh, mw = int(shape[0]), int(shape[1])
    r_start, r_stop, c0, c1 = window if window is not None else (0, mh, 0, mw)
    vh, vw = indices.shape
    sigma_y, sigma_x = BLUR_CELLS * cell[1] / scale, BLUR_CELLS * cell[0] / scale
    reach_y, reach_x = _reach(sigma_y), _reach(sigma_x)
    y0, y1, fy = _axis_weights(mh, scale, cell[1], vh)
    # The window's columns and the blur's reach, the map's edge columns repeated beyond.
    cols = np.clip(np.arange(c0 - reach_x, c1 + reach_x), 0, mw - 1)
    x0, x1, fx = (a[cols] for a in _axis_weights(mw, scale, cell[0], vw))
    # The vertex colours of the columns the window reads only (a window of a large grid).
    left, right = int(x0.min()), int(x1.max()) + 1
    x0, x1 = x0 - left, x1 - left
    palette = np.asarray(colours, np.float64)
    out = np.empty((r_stop - r_start, c1 - c0, 3), np.uint8)
    for r0 in range(r_start, r_stop, BAND_ROWS):
        r1 = min(r0 + BAND_ROWS, r_stop)
        # The band and its reach, the map's edge rows repeated beyond it.
        rows = np.clip(np.arange(r0 - reach_y, r1 + reach_y), 0, mh - 1)
        # Step 1: the vertex colours, bilinear at every map pixel (rows, then columns).
        along = (palette[indices[y0[rows], left:right]] * (1.0 - fy[rows])[:, None, None]
                 + palette[indices[y1[rows], left:right]] * fy[rows][:, None, None])
        plane = (along[:, x0] * (1.0 - fx)[None, :, None]
                 + along[:, x1] * fx[None, :, None])
        # Step 2: blurred by half a cell on each axis, the reach cut off again.
        plane = _blurred(plane, sigma_y, 0)[reach_y:reach_y + r1 - r0]
        plane = _blurred(plane, sigma_x, 1)[:, reach_x:reach_x + c1 - c0]
        out[r0 - r_start:r1 - r_start] = np.clip(np.rint(plane), 0, 255)
    return out
