"""Per-pixel labels to a vertex index grid (the majority vote of each vertex's window).

Vertex ``i`` sits on texel column ``i*N`` (:mod:`core.render.rules`) and takes the most
frequent label of the ``N x M`` texels nearest to it (columns ``i*N - N//2`` on; on
an even ``N`` the half-way texel goes to the later vertex). Pixels outside the photo
vote only where no inside pixel does; ties go to the pixel under the vertex (the texel
the render reproduces exactly), then the lowest label.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from terratheme.core.classify.samples import check_class_image
from terratheme.core.convert.specks import remove_specks
from terratheme.core.errors import TerrathemeError
from terratheme.core.model.grid import IndexGrid, validate_cell

#: pixels voted per band of vertex rows (bounded memory)
_MAX_PIXELS = 1 << 23

ProgressFn = Callable[[int, int], None]


def grid_shape_for(width: int, height: int, cell: tuple[int, int]) -> tuple[int, int]:
    """``(rows, cols)`` of the vertex grid covering a ``width x height`` photo with ``cell``."""
    n, m = validate_cell(cell)
    return -(-height // m) + 1, -(-width // n) + 1


def vote_grid(
    labels: np.ndarray,
    cell: tuple[int, int],
    *,
    progress: ProgressFn | None = None,
    keep_specks: bool = True,
) -> np.ndarray:
    """(ceil(H/M)+1, ceil(W/N)+1) uint8 vertex indices voted from (H, W) uint8 labels.

    ``cell``: (N, M) texel columns and rows per cell; ``progress`` after each band of
    vertex rows; ``keep_specks`` False: lone vertices take their neighbours' label.
    """
    labels = check_class_image(labels, "label image")
    n, m = validate_cell(cell)
    h, w = labels.shape
    rows, cols = grid_shape_for(w, h, (n, m))
    k = int(labels.max()) + 1
    # Bands of vertex rows bound the memory by the pixels of one band.
    band = max(1, min(rows, _MAX_PIXELS // (m * cols * n)))
    out = np.empty((rows, cols), dtype=np.uint8)
    for r0 in range(0, rows, band):
        r1 = min(rows, r0 + band)
        out[r0:r1] = vote_vertices(labels, (0, 0), (w, h), (n, m), (r0, r1), (0, cols), k)
        if progress is not None:
            progress(r1, rows)
    return out if keep_specks else remove_specks(out)


def vertex_window(
    rows: tuple[int, int], cols: tuple[int, int], cell: tuple[int, int], size: tuple[int, int]
) -> tuple[int, int, int, int]:
    """``(x, y, w, h)``: the pixels a block of vertices votes over, clipped to the photo.

    Never empty: vertices past the photo take its border pixels.
    """
    n, m = cell
    width, height = size
    x0 = min(max(cols[0] * n - n // 2, 0), width - 1)
    y0 = min(max(rows[0] * m - m // 2, 0), height - 1)
    x1 = max(min(cols[1] * n - n // 2, width), x0 + 1)
    y1 = max(min(rows[1] * m - m // 2, height), y0 + 1)
    return x0, y0, x1 - x0, y1 - y0


def vote_vertices(
    labels: np.ndarray,
    origin: tuple[int, int],
    size: tuple[int, int],
    cell: tuple[int, int],
    rows: tuple[int, int],
    cols: tuple[int, int],
    k: int = 256,
) -> np.ndarray:
    """(rows, cols) uint8: vote a block of vertices from a window of the labels (a tile job).

    ``labels``: (h, w) uint8 window at ``origin = (x, y)`` holding :func:`vertex_window` of
    the block; ``size``: the whole photo's (W, H); ``rows``, ``cols``: (first, end) vertex
    ranges; labels are below ``k``.
    """
    n, m = cell
    w, h = size
    lx, ly = origin
    ox, oy = n // 2, m // 2
    # Pixel (X, Y) votes for vertex (round-half-up of X/N, of Y/M): shift by N//2, M//2.
    xs = np.arange(cols[0] * n, cols[1] * n) - ox
    ys = np.arange(rows[0] * m, rows[1] * m) - oy
    x_in = (xs >= 0) & (xs < w)
    y_in = (ys >= 0) & (ys < h)
    # Outside the photo, the nearest border pixel stands in (with a negligible weight).
    x_src = np.clip(xs, 0, w - 1) - lx
    y_src = np.clip(ys, 0, h - 1) - ly
    if x_src.min() < 0 or y_src.min() < 0 or x_src.max() >= labels.shape[1] \
            or y_src.max() >= labels.shape[0]:
        raise TerrathemeError(
            f"labels window at {origin} of {labels.shape[1]} x {labels.shape[0]} does not hold "
            f"the pixels of vertices rows {rows} cols {cols}"
        )
    block = labels[y_src[:, None], x_src[None, :]]
    nr, nc = rows[1] - rows[0], cols[1] - cols[0]
    inside = y_in[:, None] & x_in[None, :]
    all_inside = bool(inside.all())
    # The pixel under each vertex (the texel the render reproduces exactly) and whether it is in.
    centre = block[oy::m, ox::n]
    centre_in = inside[oy::m, ox::n]
    # Priority per label: inside votes, then the inside centre pixel, then outside votes (edge
    # pixels standing in), then an outside centre pixel: one integer score per (vertex, label).
    span = n * m + 1
    best = np.full((nr, nc), -1, np.int64)
    out = np.zeros((nr, nc), np.uint8)
    for lab in np.flatnonzero(np.bincount(block.ravel(), minlength=k)):
        hit = block == lab
        count = hit.reshape(nr, m, nc, n).sum(axis=(1, 3), dtype=np.int64)
        if all_inside:
            c_in, c_out = count, 0
        else:
            c_in = (hit & inside).reshape(nr, m, nc, n).sum(axis=(1, 3), dtype=np.int64)
            c_out = count - c_in
        at = centre == lab
        score = ((c_in * 2 + (at & centre_in)) * span + c_out) * 2 + (at & ~centre_in)
        # Labels run upwards and only a strictly better score wins: ties keep the lower label.
        better = score > best
        out[better] = lab
        best[better] = score[better]
    return out


def labels_to_grid(
    labels: np.ndarray,
    cell: tuple[int, int] | int,
    *,
    lut: Sequence[int] | np.ndarray | None = None,
    keep_specks: bool = True,
) -> IndexGrid:
    """An :class:`IndexGrid` voted from (H, W) uint8 class values, through (256,) ``lut`` first."""
    cell = (cell, cell) if isinstance(cell, int | np.integer) else cell
    themes = apply_lut(labels, lut)
    return IndexGrid(vote_grid(themes, cell, keep_specks=keep_specks), validate_cell(cell))


def apply_lut(labels: np.ndarray, lut: Sequence[int] | np.ndarray | None) -> np.ndarray:
    """(H, W) uint8 theme indices: class values through a 256-entry table (None: unchanged)."""
    labels = check_class_image(labels, "label image")
    if lut is None:
        return labels
    table = np.asarray(lut)
    if table.shape != (256,) or table.dtype.kind not in "iu":
        raise TerrathemeError(f"class-to-theme table must be 256 integers, got {table.shape}")
    if int(table.min()) < 0 or int(table.max()) > 255:
        raise TerrathemeError("class-to-theme table holds values outside 0..255")
    return table.astype(np.uint8)[labels]
