"""Editing tools as pure functions on a vertex index array, each returning a
:class:`VertexSelection` (the scribble layer uses them in photo pixels).

Coordinates are vertex units: ``(x, y)`` = (column, row) floats, vertex
``indices[j, i]`` at ``(i, j)``; a cursor texel ``(X, Y)`` is ``(X / N, Y / M)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from skimage.segmentation import flood
from terratheme.core.errors import TerrathemeError


@dataclass(frozen=True, eq=False)
class VertexSelection:
    """The vertices a tool covers: ``rows, cols`` bound them in the ``(gh+1, gw+1)``
    index array (step 1, in range) and ``mask`` (bool, that slice's shape) marks them."""

    rows: slice
    cols: slice
    mask: np.ndarray

    @property
    def empty(self) -> bool:
        return self.mask.size == 0 or not bool(self.mask.any())


def _empty() -> VertexSelection:
    return VertexSelection(slice(0, 0), slice(0, 0), np.zeros((0, 0), dtype=bool))


def _check_point(shape: tuple[int, int], point: tuple[float, float], what: str) -> None:
    x, y = point
    if not (np.isfinite(x) and np.isfinite(y)):
        raise TerrathemeError(f"{what}: point ({x}, {y}) is not finite")


def capsule_footprint(
    shape: tuple[int, int],
    p0: tuple[float, float],
    p1: tuple[float, float],
    radius: float,
) -> VertexSelection:
    """Vertices within ``radius`` of the segment ``p0``-``p1`` (x, y vertex units) of an array
    of ``shape``: a dab swept along the segment, so a fast mouse move leaves no gaps. The
    vertex nearest each end is always covered; empty when the capsule misses the grid.
    """
    _check_point(shape, p0, "brush")
    _check_point(shape, p1, "brush")
    if not np.isfinite(radius) or radius < 0:
        raise TerrathemeError(f"brush radius must be a finite number >= 0, got {radius}")
    rows_n, cols_n = shape
    a = np.array(p0, dtype=np.float64)
    b = np.array(p1, dtype=np.float64)
    # Bounding box of the capsule, clipped to the grid.
    lo = np.floor(np.minimum(a, b) - radius - 0.5).astype(np.int64)
    hi = np.ceil(np.maximum(a, b) + radius + 0.5).astype(np.int64) + 1
    c0, r0 = max(int(lo[0]), 0), max(int(lo[1]), 0)
    c1, r1 = min(int(hi[0]), cols_n), min(int(hi[1]), rows_n)
    if c0 >= c1 or r0 >= r1:
        return _empty()
    ys, xs = np.mgrid[r0:r1, c0:c1].astype(np.float64)
    # Distance of every vertex to the segment: project onto it, clamp to its ends.
    d = b - a
    length2 = float(d @ d)
    if length2 > 0.0:
        t = np.clip(((xs - a[0]) * d[0] + (ys - a[1]) * d[1]) / length2, 0.0, 1.0)
    else:
        t = np.zeros_like(xs)
    dx = xs - (a[0] + t * d[0])
    dy = ys - (a[1] + t * d[1])
    mask = dx * dx + dy * dy <= (radius + 1e-9) ** 2
    # The vertex nearest each end is always painted.
    for px, py in (a, b):
        ci, ri = int(np.floor(px + 0.5)), int(np.floor(py + 0.5))
        if r0 <= ri < r1 and c0 <= ci < c1:
            mask[ri - r0, ci - c0] = True
    return VertexSelection(slice(r0, r1), slice(c0, c1), mask)


def rect_footprint(
    shape: tuple[int, int], p0: tuple[float, float], p1: tuple[float, float]
) -> VertexSelection:
    """Vertices inside the rectangle spanned by two corners (inclusive, any order).

    Corners are rounded to the nearest vertex, so dragging from one vertex to
    another fills both and everything between.
    """
    _check_point(shape, p0, "rectangle")
    _check_point(shape, p1, "rectangle")
    rows_n, cols_n = shape
    xs = sorted(int(np.floor(v + 0.5)) for v in (p0[0], p1[0]))
    ys = sorted(int(np.floor(v + 0.5)) for v in (p0[1], p1[1]))
    c0, c1 = max(xs[0], 0), min(xs[1] + 1, cols_n)
    r0, r1 = max(ys[0], 0), min(ys[1] + 1, rows_n)
    if c0 >= c1 or r0 >= r1:
        return _empty()
    return VertexSelection(slice(r0, r1), slice(c0, c1), np.ones((r1 - r0, c1 - c0), dtype=bool))


def nearest_vertex(shape: tuple[int, int], point: tuple[float, float]) -> tuple[int, int] | None:
    """``(row, col)`` of the vertex nearest ``point``, or None outside the grid."""
    _check_point(shape, point, "point")
    ci, ri = int(np.floor(point[0] + 0.5)), int(np.floor(point[1] + 0.5))
    if 0 <= ri < shape[0] and 0 <= ci < shape[1]:
        return ri, ci
    return None


def flood_footprint(indices: np.ndarray, point: tuple[float, float]) -> VertexSelection:
    """The region of equal indices 4-connected to the vertex nearest ``point``
    (:func:`skimage.segmentation.flood`)."""
    seed = nearest_vertex(indices.shape, point)
    if seed is None:
        return _empty()
    region = flood(indices, seed, connectivity=1)
    # Crop the whole-grid mask to its bounding box.
    rows = np.flatnonzero(region.any(axis=1))
    cols = np.flatnonzero(region.any(axis=0))
    rs, cs = slice(int(rows[0]), int(rows[-1]) + 1), slice(int(cols[0]), int(cols[-1]) + 1)
    return VertexSelection(rs, cs, np.ascontiguousarray(region[rs, cs]))


def eyedropper(indices: np.ndarray, point: tuple[float, float]) -> int | None:
    """The theme index at the vertex nearest ``point`` (None outside the grid)."""
    v = nearest_vertex(indices.shape, point)
    return None if v is None else int(indices[v])
