"""The cell size of a conversion, chosen from an agreement target (design.md §2-3).

Agreement: the share of photo pixels whose label equals the grid's label view (the
theme of largest blend weight, :func:`render_labels`), measured on the grid the
conversion would use (:func:`vote_grid`, specks removed unless kept).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from terratheme.core.classify.samples import check_class_image
from terratheme.core.convert.labels_to_grid import vote_grid
from terratheme.core.errors import TerrathemeError
from terratheme.core.model.grid import IndexGrid
from terratheme.core.packing import pack
from terratheme.core.render.renderer import render_labels

#: cell sizes tried by :func:`choose_cell_size` (square cells), filtered to the photo's size
DEFAULT_CELL_CANDIDATES = (1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64, 96, 128, 192, 256)
#: cell sizes ``convert --cell auto`` tries (larger cells broke some photos' structure)
CONVERT_CELL_CANDIDATES = tuple(c for c in DEFAULT_CELL_CANDIDATES if c <= 16)
#: the largest automatic cell when a theme is a road (thin lines keep their course)
ROAD_MAX_CELL = 8
#: cells past ``CONVERT_CELL_CANDIDATES`` a byte budget may grow the grid to
#: (:func:`cell_within_budget`)
BUDGET_CELLS = (24, 32)
#: label agreement under its target that a byte budget's larger cell may give up
#: (:func:`cell_within_budget`)
BUDGET_AGREEMENT_LOSS = 0.05


def road_candidates(candidates: Sequence[int], names: Iterable[str] | None) -> tuple[int, ...]:
    """``candidates`` up to :data:`ROAD_MAX_CELL` (if any is) when a ``names`` is ``road``.

    Coarser cells break the roads (docs/decisions.md).
    """
    if not any(str(n).strip().lower() == "road" for n in (names or ())):
        return tuple(candidates)
    capped = tuple(c for c in candidates if c <= ROAD_MAX_CELL)
    return capped or tuple(candidates)


#: rows per sample strip when the agreement is measured on a sample
_STRIP = 8
#: pixels on which :func:`choose_cell_size` measures each candidate by default
DEFAULT_SAMPLE_PIXELS = 1 << 20
#: classes smaller than this share of the photo do not constrain the cell size
CLASS_MIN_SHARE = 0.005

ProgressFn = Callable[[int, int], None]


def label_confusion(labels: np.ndarray, grid: IndexGrid, *,
                    max_pixels: int | None = None) -> np.ndarray:
    """``(K, K)`` int64 counts of (label, label view) pairs, rows = labels, ``K = max + 1``.

    ``labels``: (H, W) uint8 theme indices; ``grid`` covers them. ``max_pixels``: count on
    evenly spaced full-width strips of ``_STRIP`` rows holding about that many pixels (an
    unbiased row sample: region renders are exact crops); default every pixel.
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
    """Share of pixels whose label equals the grid's label view (as :func:`label_confusion`)."""
    return confusion_agreement(label_confusion(labels, grid, max_pixels=max_pixels))


def confusion_agreement(confusion: np.ndarray) -> float:
    """The share of a (label, label view) confusion matrix's counts on its diagonal."""
    return float(np.trace(confusion) / max(confusion.sum(), 1))


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
    #: the grid voted at ``cell`` (None when chosen on a list of windows)
    grid: IndexGrid | None = field(default=None, compare=False, repr=False)
    #: bytes of ``grid`` packed as ``convert`` ships it, when measured (:func:`cell_within_budget`)
    packed_bytes: int | None = field(default=None, compare=False, repr=False)

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

    The largest candidate meeting the target with every class over ``CLASS_MIN_SHARE``
    keeping IoU ``class_target`` (a thin road class does not vanish) wins; otherwise the
    best-agreeing cell, ``target_met=False``. ``labels``: (H, W) uint8 theme indices, or a
    list of one photo's windows (voted apart, counts summed). ``sample_pixels``: measure on
    about that many pixels (row strips; None: all). ``full_curve`` False: stop at the first
    from the largest down. ``keep_specks`` False: grids lose lone vertices first.
    """
    pieces = [labels] if isinstance(labels, np.ndarray) else list(labels)
    pieces = [check_class_image(p, "label image") for p in pieces]
    if not 0.0 < float(target_agreement) <= 1.0:
        raise TerrathemeError(f"target agreement must be in (0, 1], got {target_agreement}")
    h, w = max(p.shape[0] for p in pieces), max(p.shape[1] for p in pieces)
    sizes = sorted({int(c) for c in candidates if 1 <= int(c) <= max(w, h)})
    if not sizes:
        raise TerrathemeError(
            f"no candidate cell size fits the {w} x {h} labels (candidates {list(candidates)})"
        )
    if not 0.0 <= float(class_target) <= 1.0:
        raise TerrathemeError(f"class target must be in [0, 1], got {class_target}")
    curve = []
    grids: dict[int, IndexGrid] = {}
    for done, c in enumerate(sizes if full_curve else sizes[::-1], start=1):
        # Vote the grid, render its label view, count the pixels that keep their label.
        cm, vertices, grid = windows_confusion(pieces, c, sample_pixels, keep_specks=keep_specks)
        if len(pieces) == 1:
            grids[c] = grid
        ious = class_iou(cm, CLASS_MIN_SHARE)
        curve.append(CellPoint(c, confusion_agreement(cm), vertices,
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
        target_met=bool(meeting), class_target=float(class_target), grid=grids.get(best.cell),
    )


def windows_confusion(pieces: Sequence[np.ndarray], cell: int, max_pixels: int | None = None,
                      *, keep_specks: bool = True) -> tuple[np.ndarray, int, IndexGrid]:
    """``(confusion, vertices, grid)``: :func:`label_confusion` of windows of one photo, each
    voted apart at square ``cell`` and the counts summed; their vertex count; the last's grid.

    ``max_pixels``: about that many pixels counted in all, shared by size (None: all).
    """
    total = sum(p.size for p in pieces)
    cm, vertices = np.zeros((1, 1), np.int64), 0
    for piece in pieces:
        grid = IndexGrid(vote_grid(piece, (cell, cell), keep_specks=keep_specks), (cell, cell))
        share = None if max_pixels is None else max(1, max_pixels * piece.size // total)
        cm = _summed(cm, label_confusion(piece, grid, max_pixels=share))
        vertices += int(grid.indices.size)
    return cm, vertices, grid


def _summed(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Two confusion matrices of different sizes added (the larger's shape)."""
    k = max(a.shape[0], b.shape[0])
    out = np.zeros((k, k), np.int64)
    out[:a.shape[0], :a.shape[0]] += a
    out[:b.shape[0], :b.shape[0]] += b
    return out


def _meets(point: CellPoint, target_agreement: float, class_target: float) -> bool:
    return point.agreement >= target_agreement and point.worst_class_iou >= class_target


def packed_bytes(grid: IndexGrid) -> int:
    """Bytes of a grid packed as ``convert`` ships it (``pack(curve="auto")``)."""
    return len(pack(grid.indices, curve="auto").to_bytes())


def cell_within_budget(labels: np.ndarray, choice: CellChoice, candidates: Sequence[int],
                       max_bits_per_pixel: float, *, keep_specks: bool = True,
                       windows: Sequence[np.ndarray] | None = None) -> CellChoice:
    """``choice``, or the next larger candidate cell until the packed grid fits its budget,
    while its label agreement stays within :data:`BUDGET_AGREEMENT_LOSS` of the choice's
    target.

    Under a byte budget the map carries the structure and the grid only places detail, so
    candidates reaching ``convert``'s largest automatic cell go on to :data:`BUDGET_CELLS`
    (a list capped lower, a road theme's, stays). The largest is kept even if it does not
    fit (``max_bits_per_pixel`` per photo pixel; its curve unchanged). ``choice.grid``,
    when set, is the grid of these labels at its cell. The result carries its grid and
    packed size.

    ``windows``: when ``labels`` are a region sample's windows side by side, the same
    windows apart, on which the agreement is measured (as :func:`choose_cell_size` on a
    list: the seams between them are no borders of the photo, and would favour small cells);
    the bytes stay those of the grid of ``labels``.
    """
    labels = check_class_image(labels, "label image")
    cell = choice.cell[0]
    ladder = {int(c) for c in candidates}
    if max(ladder) >= max(CONVERT_CELL_CANDIDATES):
        ladder |= set(BUDGET_CELLS)
    larger = sorted(c for c in ladder if c > cell)
    grid = choice.grid if choice.grid is not None else IndexGrid(
        vote_grid(labels, choice.cell, keep_specks=keep_specks), choice.cell)
    nbytes, score = packed_bytes(grid), choice.agreement
    floor = choice.target - BUDGET_AGREEMENT_LOSS
    for nxt in larger:
        if nbytes * 8 / max(labels.size, 1) <= max_bits_per_pixel:
            break
        # A larger cell while the grid is over its share, unless it gives up more label
        # agreement than the budget may take (the texture's classes stay the photo's).
        bigger = IndexGrid(vote_grid(labels, (nxt, nxt), keep_specks=keep_specks), (nxt, nxt))
        kept = (agreement(labels, bigger, max_pixels=1 << 22) if windows is None else
                confusion_agreement(windows_confusion(windows, nxt, 1 << 22,
                                                      keep_specks=keep_specks)[0]))
        if kept < floor:
            break
        grid, nbytes, score = bigger, packed_bytes(bigger), kept
    if grid.cell == choice.cell:
        return replace(choice, grid=grid, packed_bytes=nbytes)
    return replace(choice, cell=grid.cell, agreement=score, grid=grid, packed_bytes=nbytes)
