"""The cell size of a conversion, chosen from an agreement target.

The agreement of a grid is the fraction of photo pixels whose label equals
the grid's *label view* (the theme with the largest blend weight at that
texel, :func:`core.render.renderer.render_labels`). :func:`choose_cell_size`
returns the largest cell whose agreement meets the target (design.md §2-3:
"cell size chosen from an error target") and whose every class keeps its
IoU target; the grids are voted by :func:`core.convert.labels_to_grid.vote_grid`
(and, unless the specks are kept, cleaned by :func:`core.convert.specks.remove_specks`:
each candidate is measured on the grid the conversion would use).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np
from terratheme.core.classify.samples import check_class_image
from terratheme.core.convert.labels_to_grid import vote_grid
from terratheme.core.errors import TerrathemeError
from terratheme.core.model.grid import IndexGrid
from terratheme.core.packing import pack
from terratheme.core.render.renderer import render_labels

#: cell sizes tried by :func:`choose_cell_size` (square cells), filtered to the photo's size
DEFAULT_CELL_CANDIDATES = (1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64, 96, 128, 192, 256)
#: cell sizes ``convert --cell auto`` tries: larger automatic cells broke the structure and
#: the colour layout of some photos (benchmarks/bench_fidelity.py, trial cells<=16)
CONVERT_CELL_CANDIDATES = tuple(c for c in DEFAULT_CELL_CANDIDATES if c <= 16)
#: rows per sample strip when the agreement is measured on a sample
_STRIP = 8
#: pixels on which :func:`choose_cell_size` measures each candidate by default
DEFAULT_SAMPLE_PIXELS = 1 << 20
#: classes smaller than this share of the photo do not constrain the cell size
CLASS_MIN_SHARE = 0.005

ProgressFn = Callable[[int, int], None]


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
    labels: np.ndarray | Sequence[np.ndarray],
    target_agreement: float = 0.9,
    *,
    candidates: Sequence[int] = DEFAULT_CELL_CANDIDATES,
    sample_pixels: int | None = DEFAULT_SAMPLE_PIXELS,
    progress: ProgressFn | None = None,
    class_target: float = 0.0,
    full_curve: bool = True,
    keep_specks: bool = True,
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
    labels : (H, W) uint8 ndarray, or a list of them
        Per-pixel theme indices; a list: windows of one photo (a region's
        sample), each voted on its own and their pixel counts summed.
    target_agreement : float in (0, 1]
    candidates : sequence of int
        Square cell sizes to try.
    sample_pixels : int or None
        Measure agreement on about this many pixels (row strips, see
        :func:`agreement`); None: on every pixel.
    progress : callable(done, total), optional
    full_curve : bool
        True: measure every candidate (the curve for a chart). False: from the
        largest candidate down, stopping at the first that meets the targets
        (the same cell, found with the fewest and cheapest grids: a small
        cell's grid has the most vertices).
    keep_specks : bool
        False: each candidate's grid is cleaned of lone vertices
        (:func:`core.convert.specks.remove_specks`) before it is measured.

    Returns
    -------
    CellChoice
        With the curve (cell, agreement, grid bytes) of the candidates measured,
        smallest cell first.
    """
    pieces = [labels] if isinstance(labels, np.ndarray) else list(labels)
    pieces = [check_class_image(p, "label image") for p in pieces]
    if not 0.0 < float(target_agreement) <= 1.0:
        raise TerrathemeError(f"target agreement must be in (0, 1], got {target_agreement}")
    h, w = max(p.shape[0] for p in pieces), max(p.shape[1] for p in pieces)
    total = sum(p.size for p in pieces)
    sizes = sorted({int(c) for c in candidates if 1 <= int(c) <= max(w, h)})
    if not sizes:
        raise TerrathemeError(
            f"no candidate cell size fits the {w} x {h} labels (candidates {list(candidates)})"
        )
    if not 0.0 <= float(class_target) <= 1.0:
        raise TerrathemeError(f"class target must be in [0, 1], got {class_target}")
    curve = []
    for done, c in enumerate(sizes if full_curve else sizes[::-1], start=1):
        # Vote the grid, render its label view, count the pixels that keep their label.
        cm, vertices = np.zeros((1, 1), np.int64), 0
        for piece in pieces:
            grid = IndexGrid(vote_grid(piece, (c, c), keep_specks=keep_specks), (c, c))
            share = None if sample_pixels is None else max(1, sample_pixels * piece.size // total)
            cm = _summed(cm, label_confusion(piece, grid, max_pixels=share))
            vertices += int(grid.indices.size)
        ious = class_iou(cm, CLASS_MIN_SHARE)
        curve.append(CellPoint(c, float(np.trace(cm) / max(cm.sum(), 1)), vertices,
                               min(ious.values(), default=1.0)))
        if progress is not None:
            progress(done, len(sizes))
        if not full_curve and _meets(curve[-1], target_agreement, class_target):
            break
    curve.sort(key=lambda p: p.cell)
    meeting = [p for p in curve if _meets(p, target_agreement, class_target)]
    if meeting:
        best = max(meeting, key=lambda p: p.cell)
    else:
        best = max(curve, key=lambda p: (p.agreement, -p.cell))
    return CellChoice(
        (best.cell, best.cell), best.agreement, float(target_agreement), tuple(curve),
        target_met=bool(meeting), class_target=float(class_target),
    )


def _summed(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Two confusion matrices of different sizes added (the larger's shape)."""
    k = max(a.shape[0], b.shape[0])
    out = np.zeros((k, k), np.int64)
    out[:a.shape[0], :a.shape[0]] += a
    out[:b.shape[0], :b.shape[0]] += b
    return out


def _meets(point: CellPoint, target_agreement: float, class_target: float) -> bool:
    return point.agreement >= target_agreement and point.worst_class_iou >= class_target


def packed_bits_per_pixel(grid: IndexGrid, pixels: int) -> float:
    """Bits per photo pixel of a grid packed as ``convert`` ships it (``pack(curve="auto")``)."""
    return len(pack(grid.indices, curve="auto").to_bytes()) * 8 / max(int(pixels), 1)


def cell_within_budget(labels: np.ndarray, choice: CellChoice, candidates: Sequence[int],
                       max_bits_per_pixel: float, *, keep_specks: bool = True) -> CellChoice:
    """``choice``, or the next larger candidate cells until the packed grid fits its budget.

    Under a byte budget (issue 34) the colour map carries the structure and
    a grid only places the themes' detail: a fine cell's grid took a third of
    the bytes of a villa photo at 0.02 bits per pixel, which the map shows
    better (docs/decisions.md). The largest candidate is kept even when it
    does not fit.

    Parameters
    ----------
    labels : (H, W) uint8 ndarray
        The theme labels the choice was made on.
    choice : CellChoice
    candidates : sequence of int
    max_bits_per_pixel : float
        Bits per photo pixel the packed grid may take.
    keep_specks : bool
        As the grid is voted (:func:`core.convert.labels_to_grid.vote_grid`).

    Returns
    -------
    CellChoice
        With ``cell`` and ``agreement`` of the cell taken (its curve unchanged).
    """
    labels = check_class_image(labels, "label image")
    cell = choice.cell[0]
    larger = sorted(int(c) for c in candidates if int(c) > cell)
    grid = None
    for nxt in [cell, *larger]:
        grid = IndexGrid(vote_grid(labels, (nxt, nxt), keep_specks=keep_specks), (nxt, nxt))
        if packed_bits_per_pixel(grid, labels.size) <= max_bits_per_pixel:
            break
    if grid.cell == choice.cell:
        return choice
    return replace(choice, cell=grid.cell, agreement=agreement(labels, grid, max_pixels=1 << 22))
