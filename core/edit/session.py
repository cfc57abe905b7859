"""The pure edit model behind the editor: undo atoms, strokes and change events.

No Qt here (the app binds to it). The model follows napari's labels layer:
the data is edited in place, listeners get a plain-Python event with the
changed vertex bounding box, and an edit is an *undo atom* — a bounding slice,
a mask of the vertices that actually changed, their old values and the one new
value. A whole brush stroke (many mouse moves) merges into one atom, so one
stroke is one undo step, and an atom's memory grows with the edit, never with
the map (the mask is bit-packed, old values are stored only under it).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from core.edit.tools import (
    Connectivity,
    VertexSelection,
    capsule_footprint,
    eyedropper,
    flood_footprint,
    rect_footprint,
)
from core.errors import TerrathemeError
from core.model.project import ThematicTexture


@dataclass(frozen=True, eq=False)
class EditAtom:
    """One undoable change: vertices in a bounding slice set to one new value.

    Attributes
    ----------
    rows, cols : slice
        Bounding slice into the index array.
    packed_mask : (ceil(h*w/8),) uint8 ndarray
        ``np.packbits`` of the ``(h, w)`` bool mask of changed vertices.
    shape : (h, w)
        Shape of the bounding slice.
    old : (k,) uint8 ndarray
        Values before the edit at the k masked vertices (row-major order).
    new : int
        The value written (0..255).
    """

    rows: slice
    cols: slice
    packed_mask: np.ndarray
    shape: tuple[int, int]
    old: np.ndarray
    new: int

    @classmethod
    def record(cls, indices: np.ndarray, fp: VertexSelection, new: int) -> EditAtom | None:
        """The atom that writes ``new`` under ``fp`` into ``indices`` (not applied yet).

        Only vertices whose value differs from ``new`` are recorded; returns
        None if nothing would change.
        """
        if fp.empty:
            return None
        block = indices[fp.rows, fp.cols]
        changed = fp.mask & (block != new)
        if not changed.any():
            return None
        # Shrink the box to the changed vertices only.
        rr = np.flatnonzero(changed.any(axis=1))
        cc = np.flatnonzero(changed.any(axis=0))
        r0, r1, c0, c1 = int(rr[0]), int(rr[-1]) + 1, int(cc[0]), int(cc[-1]) + 1
        changed = changed[r0:r1, c0:c1]
        rows = slice(fp.rows.start + r0, fp.rows.start + r1)
        cols = slice(fp.cols.start + c0, fp.cols.start + c1)
        return cls(rows, cols, np.packbits(changed, axis=None), changed.shape,
                   indices[rows, cols][changed].copy(), int(new))

    @property
    def mask(self) -> np.ndarray:
        """(h, w) bool mask of the changed vertices."""
        n = self.shape[0] * self.shape[1]
        return np.unpackbits(self.packed_mask, count=n).view(bool).reshape(self.shape)

    @property
    def count(self) -> int:
        """Number of changed vertices."""
        return int(self.old.size)

    @property
    def nbytes(self) -> int:
        """Memory held by the atom's arrays."""
        return int(self.packed_mask.nbytes + self.old.nbytes)

    def apply(self, indices: np.ndarray) -> None:
        """Write the new value (redo)."""
        block = indices[self.rows, self.cols]
        block[self.mask] = self.new

    def revert(self, indices: np.ndarray) -> None:
        """Restore the old values (undo)."""
        block = indices[self.rows, self.cols]
        block[self.mask] = self.old


@dataclass(frozen=True, eq=False)
class MultiAtom:
    """Several atoms undone and redone together (a stroke over many mouse moves)."""

    parts: tuple[EditAtom, ...]

    @property
    def rows(self) -> slice:
        return slice(min(p.rows.start for p in self.parts), max(p.rows.stop for p in self.parts))

    @property
    def cols(self) -> slice:
        return slice(min(p.cols.start for p in self.parts), max(p.cols.stop for p in self.parts))

    @property
    def count(self) -> int:
        return sum(p.count for p in self.parts)

    @property
    def nbytes(self) -> int:
        return sum(p.nbytes for p in self.parts)

    def apply(self, indices: np.ndarray) -> None:
        for p in self.parts:
            p.apply(indices)

    def revert(self, indices: np.ndarray) -> None:
        for p in reversed(self.parts):
            p.revert(indices)


def merge_atoms(parts: list[EditAtom]) -> EditAtom | MultiAtom | None:
    """Merge the atoms of one stroke into one undo step.

    Atoms of one value with disjoint masks (a stroke records each vertex once,
    when it first changes) become a single :class:`EditAtom` over the union
    box when that box is small relative to the edit (at most 64 box vertices
    per changed vertex); otherwise (a long thin diagonal stroke) they are kept
    as a :class:`MultiAtom` so memory stays proportional to the edit.
    """
    if not parts:
        return None
    if len(parts) == 1:
        return parts[0]
    new = parts[0].new
    r0 = min(p.rows.start for p in parts)
    r1 = max(p.rows.stop for p in parts)
    c0 = min(p.cols.start for p in parts)
    c1 = max(p.cols.stop for p in parts)
    count = sum(p.count for p in parts)
    if any(p.new != new for p in parts) or (r1 - r0) * (c1 - c0) > 64 * count:
        return MultiAtom(tuple(parts))
    # Paint every part's mask and old values into the union box.
    mask = np.zeros((r1 - r0, c1 - c0), dtype=bool)
    old = np.zeros((r1 - r0, c1 - c0), dtype=np.uint8)
    for p in parts:
        sub = (slice(p.rows.start - r0, p.rows.stop - r0),
               slice(p.cols.start - c0, p.cols.stop - c0))
        pm = p.mask
        mask[sub] |= pm
        old[sub][pm] = p.old
    return EditAtom(slice(r0, r1), slice(c0, c1), np.packbits(mask, axis=None), mask.shape,
                    old[mask].copy(), new)


Atom = EditAtom | MultiAtom


@dataclass(frozen=True)
class GridChange:
    """Event: vertices in ``indices[rows, cols]`` may have changed."""

    rows: slice
    cols: slice


def dirty_cells(change: GridChange, cells_shape: tuple[int, int], margin: int = 1
                ) -> tuple[slice, slice]:
    """Cells whose render a vertex change can alter: touched cells plus ``margin`` cells.

    Vertex row ``j`` bounds cell rows ``j-1`` and ``j``; the extra margin
    covers a renderer whose saddle rule (DESIGN.md §1, case 3) looks at the
    neighbouring cells.
    """
    gh, gw = cells_shape
    rows = slice(max(change.rows.start - 1 - margin, 0), min(change.rows.stop + margin, gh))
    cols = slice(max(change.cols.start - 1 - margin, 0), min(change.cols.stop + margin, gw))
    return rows, cols


def dirty_region(change: GridChange, cells_shape: tuple[int, int], cell: tuple[int, int],
                 margin: int = 1) -> tuple[int, int, int, int]:
    """The dirty texel region ``(x, y, w, h)`` to re-render after ``change``."""
    rows, cols = dirty_cells(change, cells_shape, margin)
    n, m = cell
    return (cols.start * n, rows.start * m, max(cols.stop - cols.start, 0) * n,
            max(rows.stop - rows.start, 0) * m)


Listener = Callable[[GridChange], None]


class EditSession:
    """Edits a :class:`ThematicTexture`'s index grid in place, with undo and events.

    Parameters
    ----------
    texture : ThematicTexture
        Its ``grid.indices`` array is edited in place.
    keep_history : bool
        Keep an undo/redo history here (the Qt app passes False and keeps
        the atoms in a QUndoStack instead, calling :meth:`apply` / :meth:`revert`).
    """

    def __init__(self, texture: ThematicTexture, *, keep_history: bool = True) -> None:
        self.texture = texture
        self.keep_history = keep_history
        self._listeners: list[Listener] = []
        self._undo: list[Atom] = []
        self._redo: list[Atom] = []
        self._stroke: list[EditAtom] | None = None
        self._stroke_value = 0
        self._last: tuple[float, float] | None = None

    @property
    def indices(self) -> np.ndarray:
        """(gh+1, gw+1) uint8 vertex indices (the live array)."""
        return self.texture.grid.indices

    # -- events --------------------------------------------------------------
    def subscribe(self, listener: Listener) -> Callable[[], None]:
        """Call ``listener(GridChange)`` after every change; returns an unsubscribe function."""
        self._listeners.append(listener)
        return lambda: self._listeners.remove(listener)

    def _emit(self, rows: slice, cols: slice) -> None:
        change = GridChange(rows, cols)
        for listener in list(self._listeners):
            listener(change)

    def _check_value(self, value: int) -> int:
        n = len(self.texture.library)
        if not 0 <= int(value) < n:
            raise TerrathemeError(f"theme index {value} is out of range; the library has {n}")
        return int(value)

    # -- applying atoms ------------------------------------------------------
    def apply(self, atom: Atom) -> None:
        """Apply (redo) ``atom`` and fire a change event."""
        atom.apply(self.indices)
        self._emit(atom.rows, atom.cols)

    def revert(self, atom: Atom) -> None:
        """Revert (undo) ``atom`` and fire a change event."""
        atom.revert(self.indices)
        self._emit(atom.rows, atom.cols)

    def _commit(self, atom: Atom | None) -> Atom | None:
        if atom is not None and self.keep_history:
            self._undo.append(atom)
            self._redo.clear()
        return atom

    def _paint(self, fp: VertexSelection, value: int) -> EditAtom | None:
        atom = EditAtom.record(self.indices, fp, value)
        if atom is not None:
            self.apply(atom)
        return atom

    # -- tools ---------------------------------------------------------------
    def begin_stroke(self, value: int, point: tuple[float, float], radius: float) -> None:
        """Start a brush stroke of theme ``value`` with a dab at ``point`` (vertex units)."""
        if self._stroke is not None:
            self.end_stroke()
        self._stroke_value = self._check_value(value)
        if not np.isfinite(radius) or radius < 0:
            raise TerrathemeError(f"brush radius must be a finite number >= 0, got {radius}")
        self._stroke = []
        self._last = point
        self.stroke_to(point, radius)

    def stroke_to(self, point: tuple[float, float], radius: float) -> EditAtom | None:
        """Extend the stroke to ``point``: paints the capsule from the last point."""
        if self._stroke is None or self._last is None:
            raise TerrathemeError("stroke_to called without begin_stroke")
        fp = capsule_footprint(self.indices.shape, self._last, point, radius)
        self._last = point
        atom = self._paint(fp, self._stroke_value)
        if atom is not None:
            self._stroke.append(atom)
        return atom

    def end_stroke(self) -> Atom | None:
        """Finish the stroke: its atoms merge into one undo step (None if nothing changed)."""
        parts, self._stroke, self._last = self._stroke or [], None, None
        return self._commit(merge_atoms(parts))

    @property
    def in_stroke(self) -> bool:
        return self._stroke is not None

    def fill_rect(self, p0: tuple[float, float], p1: tuple[float, float], value: int
                  ) -> Atom | None:
        """Set every vertex in the rectangle with corners ``p0``, ``p1`` to ``value``."""
        fp = rect_footprint(self.indices.shape, p0, p1)
        return self._commit(self._paint(fp, self._check_value(value)))

    def flood_fill(self, point: tuple[float, float], value: int,
                   connectivity: Connectivity = Connectivity.FOUR) -> Atom | None:
        """Fill the connected region of equal indices at ``point`` with ``value``."""
        fp = flood_footprint(self.indices, point, connectivity)
        return self._commit(self._paint(fp, self._check_value(value)))

    def pick(self, point: tuple[float, float]) -> int | None:
        """Eyedropper: the theme index at the vertex nearest ``point``."""
        return eyedropper(self.indices, point)

    def replace_all(self, indices: np.ndarray) -> Atom | None:
        """Replace the whole grid (classification result) as one undoable step.

        ``indices`` must have the grid's shape. Stored as one atom per new value.
        """
        new = np.asarray(indices)
        if new.shape != self.indices.shape:
            raise TerrathemeError(
                f"new grid has shape {new.shape}; the project grid is {self.indices.shape}")
        full = (slice(0, new.shape[0]), slice(0, new.shape[1]))
        parts = []
        for v in np.unique(new):
            atom = EditAtom.record(self.indices, VertexSelection(*full, new == v), int(v))
            if atom is not None:
                parts.append(atom)
        # Record every part against the original grid, then apply them all.
        for p in parts:
            p.apply(self.indices)
        # No part: the grid is unchanged and nothing is recorded.
        atom = MultiAtom(tuple(parts)) if len(parts) > 1 else (parts[0] if parts else None)
        if atom is not None:
            self._emit(atom.rows, atom.cols)
        return self._commit(atom)

    # -- history -------------------------------------------------------------
    @property
    def can_undo(self) -> bool:
        return bool(self._undo)

    @property
    def can_redo(self) -> bool:
        return bool(self._redo)

    def undo(self) -> Atom | None:
        """Undo the last step (None if there is none)."""
        if not self._undo:
            return None
        atom = self._undo.pop()
        self.revert(atom)
        self._redo.append(atom)
        return atom

    def redo(self) -> Atom | None:
        """Redo the last undone step (None if there is none)."""
        if not self._redo:
            return None
        atom = self._redo.pop()
        self.apply(atom)
        self._undo.append(atom)
        return atom

    @property
    def history_nbytes(self) -> int:
        """Memory held by the undo and redo history."""
        return sum(a.nbytes for a in self._undo) + sum(a.nbytes for a in self._redo)
