"""The undoable changes of an edit document: each applies, reverts and says what changed.

A change holds just what it needs to go both ways, writes
:class:`~core.edit.layers.DocumentData` and returns its events; an undo step is a tuple
of changes, reverted in reverse order.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np
from terratheme.core.edit.atoms import Atom, atom_parts, replace_atoms
from terratheme.core.edit.events import (
    ColourMapChange,
    ConfidenceChange,
    Event,
    GridChange,
    PriorChange,
    ScribbleChange,
    ThemeChange,
)
from terratheme.core.edit.layers import DocumentData, Layer
from terratheme.core.edit.uncertainty import KeptPrior
from terratheme.core.errors import TerrathemeError
from terratheme.core.model.colour_map import NEUTRAL, ColourMap
from terratheme.core.themes.library import Theme, ThemeLibrary


class Change(Protocol):
    """What every undoable change offers."""

    def apply(self, data: DocumentData) -> list[Event]:
        """Make the change (redo); returns the events it causes."""

    def revert(self, data: DocumentData) -> list[Event]:
        """Take the change back (undo); returns the events it causes."""

    @property
    def nbytes(self) -> int:
        """Memory of the arrays the change keeps alive (an upper bound)."""


def _region_event(layer: Layer, rows: slice, cols: slice) -> Event:
    return GridChange(rows, cols) if layer is Layer.GRID else ScribbleChange(rows, cols)


@dataclass(frozen=True, eq=False)
class Paint:
    """Elements of a painted layer (the grid or the scribbles) set by an atom."""

    layer: Layer
    atom: Atom

    @property
    def nbytes(self) -> int:
        return self.atom.nbytes

    def apply(self, data: DocumentData) -> list[Event]:
        array = data.layer(self.layer)
        for part in atom_parts(self.atom):
            # Keep the per-value tally of the scribble layer current, part by part.
            if self.layer is Layer.SCRIBBLES:
                data.scribble_counts -= np.bincount(part.old, minlength=256)
                data.scribble_counts[part.new] += part.count
            part.apply(array)
        return [_region_event(self.layer, self.atom.rows, self.atom.cols)]

    def revert(self, data: DocumentData) -> list[Event]:
        array = data.layer(self.layer)
        for part in reversed(atom_parts(self.atom)):
            part.revert(array)
            if self.layer is Layer.SCRIBBLES:
                data.scribble_counts[part.new] -= part.count
                data.scribble_counts += np.bincount(part.old, minlength=256)
        return [_region_event(self.layer, self.atom.rows, self.atom.cols)]


def _whole_event(layer: Layer, array: np.ndarray | None) -> Event:
    if layer is Layer.CONFIDENCE:
        return ConfidenceChange()
    h, w = (0, 0) if array is None else array.shape[:2]
    return ScribbleChange(slice(0, h), slice(0, w), whole=True)


@dataclass(frozen=True, eq=False)
class SwapLayer:
    """A whole layer (scribbles or confidence) put in place of another, or of none."""

    layer: Layer
    old: np.ndarray | None
    new: np.ndarray | None

    @property
    def nbytes(self) -> int:
        return sum(a.nbytes for a in (self.old, self.new) if a is not None)

    def apply(self, data: DocumentData) -> list[Event]:
        data.set_layer(self.layer, self.new)
        return [_whole_event(self.layer, self.new)]

    def revert(self, data: DocumentData) -> list[Event]:
        data.set_layer(self.layer, self.old)
        return [_whole_event(self.layer, self.old)]


@dataclass(frozen=True, eq=False)
class SetColourMap:
    """The colour map replaced (made neutral under an edit, or dropped with the themes)."""

    old: ColourMap | None
    new: ColourMap | None
    #: texels whose render the swap can change (None: all of them)
    region: tuple[int, int, int, int] | None = None

    @property
    def nbytes(self) -> int:
        return sum(c.pixels.nbytes for c in (self.old, self.new) if c is not None)

    def apply(self, data: DocumentData) -> list[Event]:
        data.texture.colour_map = self.new
        return [ColourMapChange(self.region)]

    def revert(self, data: DocumentData) -> list[Event]:
        data.texture.colour_map = self.old
        return [ColourMapChange(self.region)]


def neutral_under(data: DocumentData, rows: slice, cols: slice) -> SetColourMap | None:
    """The colour map made neutral (gain 1) where it touches cells of vertices ``rows, cols``,
    so a repainted theme shows its own colours, not the old theme's correction; None
    without a colour map.
    """
    cmap = data.texture.colour_map
    if cmap is None:
        return None
    grid = data.texture.grid
    n, m = grid.cell
    s = cmap.scale
    mh, mw = cmap.pixels.shape[:2]
    # Cells the vertices bound, then the map pixels whose texels meet those cells.
    x0, x1 = max(cols.start - 1, 0) * n, min(cols.stop, grid.cells_shape[1]) * n
    y0, y1 = max(rows.start - 1, 0) * m, min(rows.stop, grid.cells_shape[0]) * m
    i0, i1 = x0 // s, min(mw, -(-x1 // s))
    j0, j1 = y0 // s, min(mh, -(-y1 // s))
    if i1 <= i0 or j1 <= j0 or (cmap.pixels[j0:j1, i0:i1] == NEUTRAL).all():
        return None
    pixels = cmap.pixels.copy()
    pixels[j0:j1, i0:i1] = NEUTRAL
    # A map pixel's gain reaches one pixel beyond its own texels (bilinear).
    tw, th = grid.texture_size
    rx0, ry0 = max(0, (i0 - 1) * s), max(0, (j0 - 1) * s)
    rx1, ry1 = min(tw, (i1 + 1) * s), min(th, (j1 + 1) * s)
    return SetColourMap(cmap, ColourMap(pixels, s), (rx0, ry0, rx1 - rx0, ry1 - ry0))


@dataclass(frozen=True, eq=False)
class SetTheme:
    """Theme ``index`` replaced (renamed, recoloured or given a new texture)."""

    index: int
    old: Theme
    new: Theme

    nbytes = 0  # themes are immutable and shared, never copied

    def _event(self) -> ThemeChange:
        return ThemeChange(self.index, self.old.colour != self.new.colour,
                           not np.array_equal(self.old.texture, self.new.texture))

    def apply(self, data: DocumentData) -> list[Event]:
        data.texture.library.replace(self.index, self.new)
        return [self._event()]

    def revert(self, data: DocumentData) -> list[Event]:
        data.texture.library.replace(self.index, self.old)
        return [self._event()]


@dataclass(frozen=True, eq=False)
class AppendTheme:
    """A theme appended to the library (no vertex uses it before the change)."""

    theme: Theme

    nbytes = 0

    def apply(self, data: DocumentData) -> list[Event]:
        k = data.texture.library.append(self.theme)
        return [ThemeChange(k, False, False)]

    def revert(self, data: DocumentData) -> list[Event]:
        data.texture.library.remove_last()
        return [ThemeChange(len(data.texture.library), False, False)]


@dataclass(frozen=True, eq=False)
class SetLibrary:
    """The whole theme library replaced (a classification's own themes)."""

    old: ThemeLibrary
    new: ThemeLibrary

    nbytes = 0

    def apply(self, data: DocumentData) -> list[Event]:
        data.texture.library = self.new
        return [ThemeChange(None, True, True)]

    def revert(self, data: DocumentData) -> list[Event]:
        data.texture.library = self.old
        return [ThemeChange(None, True, True)]


@dataclass(frozen=True, eq=False)
class SetPrior:
    """The class prior kept between scribble classifications replaced."""

    old: KeptPrior | None
    new: KeptPrior | None

    nbytes = 0

    def apply(self, data: DocumentData) -> list[Event]:
        data.kept_prior = self.new
        return [PriorChange()]

    def revert(self, data: DocumentData) -> list[Event]:
        data.kept_prior = self.old
        return [PriorChange()]


def drop_prior_without_classes(data: DocumentData, classes: frozenset[int]) -> list[Change]:
    """The change forgetting the kept prior once no class is left in the scribbles (empty if none).
    """
    if data.kept_prior is None or classes:
        return []
    return [SetPrior(data.kept_prior, None)]


def grid_replacement(data: DocumentData, indices: object, n_themes: int, *,
                     neutral: bool = True) -> list[Change]:
    """The paint that turns the grid into ``indices`` (empty when equal), checked first.

    ``n_themes`` is the library size the new grid will index (after any theme
    change); with ``neutral`` the colour map goes neutral where the grid
    changed (:func:`neutral_under`).
    """
    new = np.asarray(indices)
    grid = data.texture.grid.indices
    if new.shape != grid.shape:
        raise TerrathemeError(f"new grid has shape {new.shape}; the project grid is {grid.shape}")
    if new.dtype.kind not in "iu" or (new.size and not 0 <= int(new.min())
                                      <= int(new.max()) < n_themes):
        raise TerrathemeError(f"new grid must hold theme indices 0..{n_themes - 1}")
    atom = replace_atoms(grid, new)
    if atom is None:
        return []
    swap = neutral_under(data, atom.rows, atom.cols) if neutral else None
    return [Paint(Layer.GRID, atom), *([swap] if swap is not None else [])]

