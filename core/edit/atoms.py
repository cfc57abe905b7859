"""Undo atoms of a painted 2-D uint8 layer (the index grid, the scribble layer).

As napari's labels layer records a paint (indices, old values, new value): a bounding
slice, a bit-packed mask of the changed elements, their old values and the new value,
so an atom's memory follows the edit, not the layer. A stroke's atoms merge into one
undo step (:func:`merge_atoms`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from terratheme.core.edit.tools import VertexSelection


@dataclass(frozen=True, eq=False)
class EditAtom:
    """One undoable change: elements in a bounding slice set to one new value.

    ``rows, cols`` bound the change in the layer; ``packed_mask`` is ``np.packbits``
    of the ``shape`` (h, w) bool mask of changed elements; ``old`` (k,) uint8 their
    values before (row-major); ``new`` the value written.
    """

    rows: slice
    cols: slice
    packed_mask: np.ndarray
    shape: tuple[int, int]
    old: np.ndarray
    new: int

    @classmethod
    def record(cls, indices: np.ndarray, fp: VertexSelection, new: int) -> EditAtom | None:
        """The atom that writes ``new`` under ``fp`` into the layer ``indices`` (not applied).

        Only elements whose value differs from ``new`` are recorded; returns
        None if nothing would change.
        """
        if fp.empty:
            return None
        block = indices[fp.rows, fp.cols]
        changed = fp.mask & (block != new)
        if not changed.any():
            return None
        # Shrink the box to the changed elements only.
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
        """(h, w) bool mask of the changed elements."""
        n = self.shape[0] * self.shape[1]
        return np.unpackbits(self.packed_mask, count=n).view(bool).reshape(self.shape)

    @property
    def count(self) -> int:
        """Number of changed elements."""
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
    def shape(self) -> tuple[int, int]:
        return self.rows.stop - self.rows.start, self.cols.stop - self.cols.start

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

    Atoms of one value with disjoint masks become one :class:`EditAtom` over the
    union box when it holds at most 64 box vertices per changed element; otherwise
    (a long thin diagonal stroke) a :class:`MultiAtom`, so memory follows the edit.
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


def atom_parts(atom: Atom) -> tuple[EditAtom, ...]:
    """The single-value atoms of ``atom``, in the order they are applied."""
    return atom.parts if isinstance(atom, MultiAtom) else (atom,)


def replace_atoms(layer: np.ndarray, new: np.ndarray) -> Atom | None:
    """The atom that turns ``layer`` (H, W) uint8 into ``new`` (values 0..255), not applied
    yet: one :class:`EditAtom` per value that overwrites something; None when equal.
    """
    full = (slice(0, new.shape[0]), slice(0, new.shape[1]))
    parts = []
    for v in np.unique(new):
        atom = EditAtom.record(layer, VertexSelection(*full, new == v), int(v))
        if atom is not None:
            parts.append(atom)
    if not parts:
        return None
    return parts[0] if len(parts) == 1 else MultiAtom(tuple(parts))
