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
from terratheme.core.model.map_prediction import nearest_vertices
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
    """The colour map replaced (repainted under an edit, or dropped with the themes)."""

    old: ColourMap | None
    new: ColourMap | None
    #: texels whose render the swap can change (None: all of them)
    region: tuple[int, int, int, int] | None = None

    @property
    def nbytes(self) -> int:
        return sum(c.pixels.nbytes for c in (self.old, self.new) if c is not None)

    def apply(self, data: DocumentData) -> list[Event]:
        return self._swap(data, self.new)

    def revert(self, data: DocumentData) -> list[Event]:
        return self._swap(data, self.old)

    def _swap(self, data: DocumentData, cmap: ColourMap | None) -> list[Event]:
        data.texture.colour_map = cmap
        if self.region is None:
            data.theme_gains = None  # a whole new map: its themes' gains taken afresh
        return [ColourMapChange(self.region)]


def repaint_colour_map(data: DocumentData, atom: Atom) -> SetColourMap | None:
    """The colour map under a grid repaint by ``atom`` (applied or not yet): map pixels
    nearest a repainted vertex take the new theme's gain (:meth:`DocumentData.colour_gains`,
    ``NEUTRAL`` if the map never had it), so it looks as it does elsewhere. None without
    a map or when nothing changes."""
    cmap = data.texture.colour_map
    if cmap is None:
        return None
    grid, s = data.texture.grid, cmap.scale
    n, m = grid.cell
    mh, mw = cmap.pixels.shape[:2]
    vh, vw = grid.indices.shape
    # The atom's new theme per vertex of its box, and which vertices it changes.
    r0, c0 = atom.rows.start, atom.cols.start
    changed = np.zeros(atom.shape, bool)
    new = np.zeros(atom.shape, np.uint8)
    for part in atom_parts(atom):
        sub = (slice(part.rows.start - r0, part.rows.stop - r0),
               slice(part.cols.start - c0, part.cols.stop - c0))
        changed[sub] |= part.mask
        new[sub][part.mask] = part.new
    # Map pixels whose nearest vertex lies in the box (a vertex reaches half a cell).
    j0, j1 = max(0, (r0 * m - m) // s), min(mh, -(-(atom.rows.stop * m + m) // s))
    i0, i1 = max(0, (c0 * n - n) // s), min(mw, -(-(atom.cols.stop * n + n) // s))
    rows = nearest_vertices(mh, s, m, vh)[j0:j1] - r0
    cols = nearest_vertices(mw, s, n, vw)[i0:i1] - c0
    inside = ((rows >= 0) & (rows < atom.shape[0]))[:, None] & \
        ((cols >= 0) & (cols < atom.shape[1]))[None, :]
    rr, cc = np.clip(rows, 0, atom.shape[0] - 1), np.clip(cols, 0, atom.shape[1] - 1)
    hit = inside & changed[rr[:, None], cc[None, :]]
    if not hit.any():
        return None
    # Each theme's gain as opened; NEUTRAL where the map never had it.
    gains = data.colour_gains()
    table = np.where(np.isnan(gains), NEUTRAL, np.rint(gains)).astype(np.uint8)
    pixels = cmap.pixels.copy()
    block = pixels[j0:j1, i0:i1]
    block[hit] = table[new[rr[:, None], cc[None, :]][hit]]
    if np.array_equal(block, cmap.pixels[j0:j1, i0:i1]):
        return None
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
                     repaint_map: bool = True) -> list[Change]:
    """The paint that turns the grid into ``indices`` (empty when equal), checked first.

    ``n_themes`` is the library size the new grid will index (after any theme
    change); with ``repaint_map`` the colour map takes the new themes' gains where the
    grid changed (:func:`repaint_colour_map`).
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
    swap = repaint_colour_map(data, atom) if repaint_map else None
    return [Paint(Layer.GRID, atom), *([swap] if swap is not None else [])]

