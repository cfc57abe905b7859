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


def class_colours(stored: np.ndarray, indices: np.ndarray, cell: tuple[int, int],
                  scale: int, n_themes: int) -> np.ndarray:
    """``(n_themes, 3)`` uint8: each theme's mean stored gain over the map pixels nearest
    its vertices (:data:`NEUTRAL` for a theme with none).

    ``stored`` (mh, mw, 3) uint8: a map at ``scale`` texels per pixel; ``indices``
    (vh, vw) uint8: the grid's vertices, ``cell`` ``(N, M)`` texels a cell.
    """
    mh, mw = stored.shape[:2]
    vh, vw = indices.shape
    rows = nearest_vertices(mh, scale, cell[1], vh)
    cols = nearest_vertices(mw, scale, cell[0], vw)
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
    colours = np.full((n_themes, 3), NEUTRAL, np.uint8)
    seen = counts > 0
    colours[seen] = np.clip(np.rint(sums[seen] / counts[seen, None]), 0, 255)
    return colours


def _axis_weights(count: int, scale: int, cell: int, vertices: int
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Along an axis: the vertex below each map pixel's centre, the one above and the
    weight of the one above (bilinear, clamped at the last vertex)."""
    at = np.clip((np.arange(count) + 0.5) * scale / cell, 0.0, vertices - 1.0)
    low = np.minimum(np.floor(at).astype(np.int64), vertices - 1)
    high = np.minimum(low + 1, vertices - 1)
    return low, high, at - low


def class_prediction(indices: np.ndarray, cell: tuple[int, int], colours: np.ndarray,
                     scale: int, shape: tuple[int, int]) -> np.ndarray:
    """``(mh, mw, 3)`` uint8: the map a grid predicts at ``scale`` texels a map pixel.

    ``indices`` (vh, vw) uint8 theme per vertex (vertex ``(r, c)`` at texel ``(c N, r M)``
    for ``cell`` ``(N, M)``); ``colours`` (K, 3) uint8 per theme; ``shape`` ``(mh, mw)``.
    Map pixel ``(i, j)`` takes the vertex colours bilinearly at its centre ``((j + 0.5)
    scale, (i + 0.5) scale)``, then a Gaussian of sigma :data:`BLUR_CELLS` cells
    (edge pixels replicated, an axis under 0.5 map pixels not blurred), rounded. Made
    :data:`BAND_ROWS` rows at a time with the blur's reach around them: the same pixels.
    """
    mh, mw = int(shape[0]), int(shape[1])
    vh, vw = indices.shape
    y0, y1, fy = _axis_weights(mh, scale, cell[1], vh)
    x0, x1, fx = _axis_weights(mw, scale, cell[0], vw)
    sigma_y, sigma_x = BLUR_CELLS * cell[1] / scale, BLUR_CELLS * cell[0] / scale
    # Rows beyond a band the vertical blur reads (scipy's radius for these taps).
    reach = int(TRUNCATE * sigma_y + 0.5) if sigma_y >= 0.5 else 0
    vertex = np.asarray(colours, np.float64)[indices]  # (vh, vw, 3)
    out = np.empty((mh, mw, 3), np.uint8)
    for r0 in range(0, mh, BAND_ROWS):
        r1 = min(r0 + BAND_ROWS, mh)
        # The band and its reach, the map's edge rows repeated beyond it.
        rows = np.clip(np.arange(r0 - reach, r1 + reach), 0, mh - 1)
        # Step 1: the vertex colours, bilinear at every map pixel (rows, then columns).
        along = (vertex[y0[rows]] * (1.0 - fy[rows])[:, None, None]
                 + vertex[y1[rows]] * fy[rows][:, None, None])
        plane = (along[:, x0] * (1.0 - fx)[None, :, None]
                 + along[:, x1] * fx[None, :, None])
        # Step 2: blurred by half a cell on each axis.
        if reach:
            plane = gaussian_filter1d(plane, sigma_y, axis=0, mode="nearest",
                                      truncate=TRUNCATE)[reach:reach + r1 - r0]
        if sigma_x >= 0.5:
            plane = gaussian_filter1d(plane, sigma_x, axis=1, mode="nearest", truncate=TRUNCATE)
        out[r0:r1] = np.clip(np.rint(plane), 0, 255)
    return out
