"""Reduced-resolution render for overviews, never rendering full resolution first.

Each output pixel covers an ``fx x fy`` footprint of texels; its colour is

    sum_k  mean_footprint(weight_k) * mean_footprint(T_k)

(the box-filtered render, taking the smooth weights and the fine theme texture as
uncorrelated inside a footprint). ``mean(weight_k)``: the weights of
``core.render.rules`` supersampled ``ceil(2 * fx / N)`` times per axis;
``mean(T_k)``: the theme box-filtered with wrapping (``uniform_filter``) at the
footprint centre. Cost ``O(output pixels x supersamples x themes present)``; the
blend is always linear (the histogram-preserving one matters at texel scale only).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy import ndimage
from terratheme.core.errors import TerrathemeError
from terratheme.core.model.colour_map import ColourMap
from terratheme.core.render.boundary import BoundaryOptions, shaped_weights
from terratheme.core.render.colour_map import gain_image
from terratheme.core.render.inputs import prepare_grid, theme_textures, validate_region
from terratheme.core.render.rules import SaddleRule, cell_splits, corner_weights

_FRAC = 4096  # fixed-point scale of the local coordinates


def _sample_positions(start: int, length: int, out_n: int, ss: int) -> np.ndarray:
    """(out_n, ss) full-resolution texel positions sampled inside each output pixel."""
    f = length / out_n
    u = np.arange(out_n)[:, None] + (np.arange(ss)[None, :] + 0.5) / ss
    return start + u * f - 0.5


def render_overview(
    indices: np.ndarray,
    textures: Sequence[np.ndarray],
    cell: tuple[int, int],
    region: tuple[int, int, int, int] | None = None,
    *,
    scale: float,
    saddle: SaddleRule = SaddleRule.MINORITY,
    colour_map: ColourMap | None = None,
    boundary: BoundaryOptions | None = None,
) -> np.ndarray:
    """Render ``region`` (full-resolution texels) at ``scale`` in (0, 1] output pixels per texel.

    ``colour_map`` is applied as its gain at every output pixel's centre;
    ``boundary`` uses the shaped blend's weights, sampled finely enough to follow
    its noise lattice. Returns ``(max(1, round(h*scale)), max(1, round(w*scale)), 3)``
    uint8.
    """
    texs = theme_textures(textures)
    grid, (n, m) = prepare_grid(indices, cell, len(texs))
    if not (0.0 < scale <= 1.0):
        raise TerrathemeError(f"scale must be in (0, 1], got {scale}")
    gh, gw = grid.shape[0] - 1, grid.shape[1] - 1
    rx, ry, rw, rh = validate_region(region, (gw * n, gh * m))
    ow, oh = max(1, round(rw * scale)), max(1, round(rh * scale))
    fx, fy = rw / ow, rh / oh
    params = None if boundary is None else boundary.parameters(n, m)
    # Samples per axis: two per cell, or two per noise feature with shaped borders.
    px, py = (n, m) if params is None else (params.lattice, params.lattice)
    sx = min(16, max(1, int(np.ceil(2 * fx / px))))
    sy = min(16, max(1, int(np.ceil(2 * fy / py))))
    splits = cell_splits(grid, saddle)
    xs = _sample_positions(rx, rw, ow, sx).reshape(-1)
    ys = _sample_positions(ry, rh, oh, sy).reshape(-1)
    if params is None:
        # Footprint-averaged weight of every theme present (supersampled barycentric weights).
        gx = np.clip(xs / n, 0, gw - 1e-9)
        gy = np.clip(ys / m, 0, gh - 1e-9)
        cx, cy = gx.astype(np.int64), gy.astype(np.int64)
        xi = np.rint((gx - cx) * _FRAC).astype(np.int32)[None, :]
        yi = np.rint((gy - cy) * _FRAC).astype(np.int32)[:, None]
        ws = corner_weights(splits[cy[:, None], cx[None, :]], xi, yi, _FRAC)
        ks = [grid[cy[:, None] + dr, cx[None, :] + dc]
              for dr, dc in ((0, 0), (0, 1), (1, 0), (1, 1))]
        denom = _FRAC
    else:
        # The shaped blend's own weights at the nearest texels of the samples.
        tx = np.clip(np.rint(xs), 0, gw * n - 1).astype(np.int64)
        ty = np.clip(np.rint(ys), 0, gh * m - 1).astype(np.int64)
        ids, weights, denom = shaped_weights(grid, splits, texs, (n, m), tx, ty, params)
        ks, ws = list(ids), list(weights)
        denom = np.maximum(denom, 1)
    present = np.unique(grid)
    out = np.zeros((oh, ow, 3), dtype=np.float32)
    # Footprint centres, for sampling the prefiltered themes.
    cxs = np.floor(rx + (np.arange(ow) + 0.5) * fx).astype(np.int64)
    cys = np.floor(ry + (np.arange(oh) + 0.5) * fy).astype(np.int64)
    for k in present:
        wk = sum(np.where(ks[c] == k, ws[c], 0).astype(np.float32) for c in range(4)) / denom
        wk = wk.reshape(oh, sy, ow, sx).mean(axis=(1, 3))
        if not wk.any():
            continue
        colour = _prefiltered(texs[int(k)], fx, fy)
        th, tw = colour.shape[:2]
        out += wk[:, :, None] * colour[(cys % th)[:, None], (cxs % tw)[None, :]]
    if colour_map is not None:
        colour_map.check_covers((gw * n, gh * m))
        out *= gain_image(colour_map, (rx, ry, rw, rh), (ow, oh))
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)


def _prefiltered(texture: np.ndarray, fx: float, fy: float) -> np.ndarray:
    """(h, w, 3) float32: the theme box-filtered over an ``fx x fy`` footprint, wrapping."""
    h, w = texture.shape[:2]
    bx, by = round(fx), round(fy)
    if bx >= w and by >= h:
        return texture.reshape(-1, 3).mean(axis=0).astype(np.float32)[None, None, :]
    size = (min(max(by, 1), h), min(max(bx, 1), w), 1)
    return ndimage.uniform_filter(texture.astype(np.float32), size=size, mode="wrap")
