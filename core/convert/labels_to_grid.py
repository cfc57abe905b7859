"""Per-pixel labels to a vertex index grid, and the cell size chosen from an agreement target.

Conventions follow :mod:`core.render.rules`: global texel column ``X`` sits at
grid position ``X / N``, so vertex ``i`` sits on texel column ``i*N`` and a
photo of ``W x H`` pixels needs ``gw = ceil(W / N)`` cells across (the
render is ``gw*N`` texels wide, at least the photo's width, and is cropped to
the photo for comparison).

Each vertex takes the most frequent label in the ``N x M`` window of the
texels nearest to it: columns ``i*N - N//2 .. i*N - N//2 + N - 1`` (on an
even ``N`` the texel half way between two vertices goes to the later one),
rows likewise. Pixels outside the photo do not vote while any pixel inside the
window does (a window entirely outside the photo takes the nearest border
pixels). Ties go to the label of the pixel under the vertex (the texel the
render reproduces exactly), then to the lowest label: deterministic.

The agreement of a grid is the fraction of photo pixels whose label equals
the grid's *label view* (the theme with the largest blend weight at that
texel, :func:`core.render.renderer.render_labels`). :func:`choose_cell_size`
returns the largest cell whose agreement meets the target (design.md §2-3:
"cell size chosen from an error target").
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from core.classify.samples import check_class_image
from core.errors import TerrathemeError
from core.model.grid import IndexGrid, validate_cell
from core.render.renderer import render_labels

#: cell sizes tried by :func:`choose_cell_size` (square cells), filtered to the photo's size
DEFAULT_CELL_CANDIDATES = (1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64, 96, 128, 192, 256)
#: cell sizes ``convert --cell auto`` tries: larger automatic cells broke the structure and
#: the colour layout of some photos (benchmarks/bench_fidelity.py, trial cells<=16)
CONVERT_CELL_CANDIDATES = tuple(c for c in DEFAULT_CELL_CANDIDATES if c <= 16)
#: pixels voted per band of vertex rows (bounded memory)
_MAX_PIXELS = 1 << 23
#: rows per sample strip when the agreement is measured on a sample
_STRIP = 8
#: pixels on which :func:`choose_cell_size` measures each candidate by default
DEFAULT_SAMPLE_PIXELS = 1 << 20
#: classes smaller than this share of the photo do not constrain the cell size
CLASS_MIN_SHARE = 0.005

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
) -> np.ndarray:
    """Vertex indices by a majority vote over each vertex's ``N x M`` window.

    Parameters
    ----------
    labels : (H, W) uint8 ndarray
        Per-pixel theme indices (or class values).
    cell : (N, M)
        Texel columns and rows per cell.
    progress : callable(done, total), optional
        Called after each band of vertex rows.

    Returns
    -------
    indices : (ceil(H/M)+1, ceil(W/N)+1) uint8 ndarray
        The most frequent label of each vertex's window (ties: the pixel
        under the vertex, then the lowest label).
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
    return out


def vertex_window(
    rows: tuple[int, int], cols: tuple[int, int], cell: tuple[int, int], size: tuple[int, int]
) -> tuple[int, int, int, int]:
    """The pixels that vertices ``rows[0]..rows[1]-1`` x ``cols[0]..cols[1]-1`` vote over.

    Returns
    -------
    (x, y, w, h) : the window, clipped to the ``size = (W, H)`` photo
        (never empty: a range of vertices past the photo takes its border pixels).
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
    """Vote a block of vertices from a window of the labels (the tile job of the tiled path).

    Parameters
    ----------
    labels : (h, w) uint8 ndarray
        A window of the photo's labels whose top-left pixel is ``origin = (x, y)``;
        it must hold :func:`vertex_window` of the vertex block.
    size : (W, H)
        The whole photo's size.
    cell : (N, M)
    rows, cols : (first, end) vertex ranges
    k : int
        Labels are below ``k``.

    Returns
    -------
    indices : (rows[1]-rows[0], cols[1]-cols[0]) uint8 ndarray
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
) -> IndexGrid:
    """An :class:`IndexGrid` from per-pixel labels.

    Parameters
    ----------
    labels : (H, W) uint8 ndarray
        Class values.
    cell : (N, M) or int
        Cell size; an int means a square cell.
    lut : (256,) int array-like, optional
        Class value -> theme index, applied before the vote (so two classes
        that share a theme vote together). Default: the labels are theme indices.

    Returns
    -------
    grid : IndexGrid
    """
    cell = (cell, cell) if isinstance(cell, int | np.integer) else cell
    themes = apply_lut(labels, lut)
    return IndexGrid(vote_grid(themes, cell), validate_cell(cell))


def apply_lut(labels: np.ndarray, lut: Sequence[int] | np.ndarray | None) -> np.ndarray:
    """Map class values to theme indices with a 256-entry table (None: unchanged).

    Returns
    -------
    themes : (H, W) uint8 ndarray
    """
    labels = check_class_image(labels, "label image")
    if lut is None:
        return labels
    table = np.asarray(lut)
    if table.shape != (256,) or table.dtype.kind not in "iu":
        raise TerrathemeError(f"class-to-theme table must be 256 integers, got {table.shape}")
    if int(table.min()) < 0 or int(table.max()) > 255:
        raise TerrathemeError("class-to-theme table holds values outside 0..255")
    return table.astype(np.uint8)[labels]


def label_confusion(labels: np.ndarray, grid: IndexGrid, *,
                    max_pixels: int | None = None) -> np.ndarray:
    """Counts of (label, label view) pairs over the photo: ``(K, K)`` int64, rows = labels.

    Parameters
    ----------
    labels : (H, W) uint8 ndarray
        Per-pixel theme indices.
    grid : IndexGrid
        Must cover the photo: ``grid.texture_size >= (W, H)``.
    max_pixels : int, optional
        Above this many pixels, count on evenly spaced full-width strips of
        ``_STRIP`` rows holding about ``max_pixels`` pixels (the renderer's
        regions are exact crops of the full render, so this is an unbiased
        row sample). Default: every pixel.

    Returns
    -------
    (K, K) int64 ndarray, ``K = max(label, index) + 1``
    """
    labels = check_class_image(labels, "label image")
    h, w = labels.shape
    tw, th = grid.texture_size
    if tw < w or th < h:
        raise TerrathemeError(f"grid renders {tw} x {th} texels, smaller than the {w} x {h} labels")
    if max_pixels is None or labels.size <= max_pixels:
        strips = [(0, h)]
    else:
        # Evenly spaced strips (start rows on a fixed lattice, independent of the cell size).
        n_strips = max(1, int(max_pixels) // (w * _STRIP))
        starts = np.linspace(0, h - _STRIP, n_strips).astype(int)
        strips = [(int(y), _STRIP) for y in np.unique(starts)]
    k = int(max(labels.max(initial=0), grid.indices.max(initial=0))) + 1
    counts = np.zeros(k * k, np.int64)
    for y, sh in strips:
        # A region render touches only the vertex rows under it (an exact crop of the full view).
        view = render_labels(grid, region=(0, y, w, sh))
        pairs = labels[y : y + sh].astype(np.int64) * k + view
        counts += np.bincount(pairs.ravel(), minlength=k * k)
    return counts.reshape(k, k)


def agreement(labels: np.ndarray, grid: IndexGrid, *, max_pixels: int | None = None) -> float:
    """Fraction of pixels whose label equals the grid's label view (cropped to the photo).

    See :func:`label_confusion` for the arguments.
    """
    cm = label_confusion(labels, grid, max_pixels=max_pixels)
    return float(np.trace(cm) / max(cm.sum(), 1))


def class_iou(confusion: np.ndarray, min_share: float = 0.0) -> dict[int, float]:
    """IoU of each label with its label view, for labels covering at least ``min_share``."""
    tp = np.diag(confusion).astype(np.float64)
    rows, cols = confusion.sum(axis=1), confusion.sum(axis=0)
    total = max(int(confusion.sum()), 1)
    return {int(k): float(tp[k] / max(rows[k] + cols[k] - tp[k], 1))
            for k in range(confusion.shape[0]) if rows[k] > 0 and rows[k] / total >= min_share}


@dataclass(frozen=True)
class CellPoint:
    """One point of the agreement curve."""

    cell: int
    agreement: float
    #: vertex count of the grid: 1 byte per vertex, uncompressed
    grid_bytes: int
    #: the lowest IoU of a class (covering at least CLASS_MIN_SHARE) with its label view
    worst_class_iou: float = 1.0


@dataclass(frozen=True)
class CellChoice:
    """The chosen cell size and the curve it was chosen from."""

    cell: tuple[int, int]
    agreement: float
    target: float
    curve: tuple[CellPoint, ...]
    #: False when no candidate met the target (then the best-agreeing cell was taken)
    target_met: bool
    #: the per-class IoU target the cell also had to meet (0: none)
    class_target: float = 0.0

    def as_dict(self) -> dict:
        """JSON-ready summary (for the project metadata and the benchmark)."""
        return {
            "cell": list(self.cell),
            "agreement": self.agreement,
            "target": self.target,
            "target_met": self.target_met,
            "class_target": self.class_target,
            "curve": [
                {"cell": p.cell, "agreement": p.agreement, "grid_bytes": p.grid_bytes,
                 "worst_class_iou": p.worst_class_iou}
                for p in self.curve
            ],
        }


def choose_cell_size(
    labels: np.ndarray,
    target_agreement: float = 0.9,
    *,
    candidates: Sequence[int] = DEFAULT_CELL_CANDIDATES,
    sample_pixels: int | None = DEFAULT_SAMPLE_PIXELS,
    progress: ProgressFn | None = None,
    class_target: float = 0.0,
) -> CellChoice:
    """The largest square cell whose label view keeps ``target_agreement`` of the labels.

    Every candidate cell that fits the photo (``cell <= max(W, H)``) is tried:
    vote the grid (:func:`vote_grid`), render its label view and count the
    pixels that keep their label. The answer is the largest candidate whose
    agreement is at least the target and whose every class covering at least
    ``CLASS_MIN_SHARE`` of the photo keeps an IoU with its label view of at
    least ``class_target`` (so a thin class such as roads does not vanish
    while the whole photo's agreement stays high). A higher target never
    gives a larger cell. When none meets them (possible only if cell 1 is
    not a candidate), the candidate with the best agreement is returned with
    ``target_met=False``.

    Parameters
    ----------
    labels : (H, W) uint8 ndarray
        Per-pixel theme indices.
    target_agreement : float in (0, 1]
    candidates : sequence of int
        Square cell sizes to try.
    sample_pixels : int or None
        Measure agreement on about this many pixels (row strips, see
        :func:`agreement`); None: on every pixel.
    progress : callable(done, total), optional

    Returns
    -------
    CellChoice
        With the full curve (cell, agreement, grid bytes) for a chart.
    """
    labels = check_class_image(labels, "label image")
    if not 0.0 < float(target_agreement) <= 1.0:
        raise TerrathemeError(f"target agreement must be in (0, 1], got {target_agreement}")
    h, w = labels.shape
    sizes = sorted({int(c) for c in candidates if 1 <= int(c) <= max(w, h)})
    if not sizes:
        raise TerrathemeError(
            f"no candidate cell size fits the {w} x {h} labels (candidates {list(candidates)})"
        )
    if not 0.0 <= float(class_target) <= 1.0:
        raise TerrathemeError(f"class target must be in [0, 1], got {class_target}")
    curve = []
    for done, c in enumerate(sizes, start=1):
        grid = IndexGrid(vote_grid(labels, (c, c)), (c, c))
        cm = label_confusion(labels, grid, max_pixels=sample_pixels)
        ious = class_iou(cm, CLASS_MIN_SHARE)
        curve.append(CellPoint(c, float(np.trace(cm) / max(cm.sum(), 1)), int(grid.indices.size),
                               min(ious.values(), default=1.0)))
        if progress is not None:
            progress(done, len(sizes))
    meeting = [p for p in curve if p.agreement >= target_agreement
               and p.worst_class_iou >= class_target]
    if meeting:
        best = max(meeting, key=lambda p: p.cell)
    else:
        best = max(curve, key=lambda p: (p.agreement, -p.cell))
    return CellChoice(
        (best.cell, best.cell), best.agreement, float(target_agreement), tuple(curve),
        target_met=bool(meeting), class_target=float(class_target),
    )
