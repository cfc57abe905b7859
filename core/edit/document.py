"""The edit document: everything the editor edits, with one undo history and events.

No Qt; the editor (``app/editor``) is a view of it. As in napari's layer model, data is
edited in place and every change fires a plain-Python event once the document is
consistent. Every change, whatever it touches, is an undo atom on one history; a brush
stroke or a classification result is one step.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import contextmanager

import numpy as np
from terratheme.core.edit import layers
from terratheme.core.edit.atoms import EditAtom
from terratheme.core.edit.changes import (
    AppendTheme,
    Change,
    Paint,
    SetTheme,
    grid_replacement,
    repaint_colour_map,
)
from terratheme.core.edit.classification import ClassificationUpdate, classification_changes
from terratheme.core.edit.events import DocumentEvents, Event, HistoryChange
from terratheme.core.edit.history import History, Step
from terratheme.core.edit.layers import DocumentData, Layer
from terratheme.core.edit.strokes import Stroke
from terratheme.core.edit.tools import (
    VertexSelection,
    eyedropper,
    flood_footprint,
    rect_footprint,
)
from terratheme.core.edit.uncertainty import KeptPrior, uncertain_mask
from terratheme.core.errors import TerrathemeError
from terratheme.core.model.project import ThematicTexture, save_project
from terratheme.core.themes.library import Theme, ThemeLibrary


class EditDocument:
    """A thematic texture open for editing (``texture`` is edited in place).

    ``events``: ``doc.events.grid.connect(callback)`` and so on; ``history``: the one
    undo history (change it through :meth:`undo` / :meth:`redo`).
    """

    def __init__(self, texture: ThematicTexture) -> None:
        self.data = DocumentData(texture)
        self.events = DocumentEvents.new()
        self.history = History()
        self._stroke: Stroke | None = None
        #: what uncertain derived, by name: (source array, derived array)
        self._derived: dict[str, tuple[np.ndarray, np.ndarray]] = {}

    # -- what the document holds ------------------------------------------------
    @property
    def texture(self) -> ThematicTexture:
        return self.data.texture

    @property
    def indices(self) -> np.ndarray:
        """(gh+1, gw+1) uint8 vertex indices (the live array: read, never write)."""
        return self.data.texture.grid.indices

    @property
    def library(self) -> ThemeLibrary:
        return self.data.texture.library

    @property
    def photo(self) -> np.ndarray | None:
        return self.data.texture.photo

    @property
    def scribbles(self) -> np.ndarray | None:
        return self.data.texture.scribbles

    @property
    def confidence(self) -> np.ndarray | None:
        """(H, W) float32 read-only: the last classification's confidence, or None."""
        return self.data.confidence

    @property
    def kept_prior(self) -> KeptPrior | None:
        return self.data.kept_prior

    def photo_extent(self) -> tuple[float, float] | None:
        """``(width, height)`` in texels the photo covers (None without a photo)."""
        if self.photo is None:
            return None
        return layers.photo_extent(self.photo.shape, self.texture.grid)

    def texel_to_vertex(self, x: float, y: float) -> tuple[float, float]:
        """Texel position -> vertex units (texel X sits at grid position X / N)."""
        n, m = self.texture.grid.cell
        return x / n, y / m

    def texel_to_photo(self, x: float, y: float) -> tuple[float, float]:
        """Texel position -> photo pixel units (1:1 unless the photo is stretched)."""
        ew, eh = self.photo_extent()
        return x * self.photo.shape[1] / ew, y * self.photo.shape[0] / eh

    def scribble_classes(self) -> frozenset[int]:
        """Class values painted in the scribble layer (without scanning it)."""
        return self.data.scribble_classes()

    def prior_for_scribbles(self) -> dict[int, float] | None:
        """The kept prior's class weights while the same classes are painted, else None."""
        kept = self.kept_prior
        return dict(kept.weights) if kept and kept.applies_to(self.scribble_classes()) else None

    def uncertain(self) -> np.ndarray | None:
        """(H, W) bool: the least confident share of the photo, as regions (None: no map)."""
        return self._derive("uncertain", self.confidence, uncertain_mask)

    def _derive(self, name: str, source: np.ndarray | None,
                make: Callable[[np.ndarray], np.ndarray]) -> np.ndarray | None:
        """``make(source)``, computed again only when ``source`` is another array (None: None)."""
        if source is None:
            return None
        kept = self._derived.get(name)
        if kept is None or kept[0] is not source:
            kept = self._derived[name] = (source, make(source))
        return kept[1]

    # -- applying changes ---------------------------------------------------------
    def _fire(self, events: Iterable[Event], history: bool = True) -> None:
        for event in events:
            self.events.emit(event)
        if history:
            h = self.history
            self.events.emit(HistoryChange(h.undo_label, h.redo_label, h.clean))

    def _apply(self, changes: Sequence[Change]) -> list[Event]:
        events: list[Event] = []
        for change in changes:
            events += change.apply(self.data)
        return events

    def _commit(self, label: str, changes: Sequence[Change]) -> Step | None:
        """Apply ``changes`` as one undo step, then fire their events."""
        self.end_stroke()
        events = self._apply(changes)
        step = self.history.record(label, changes)
        self._fire(events, history=bool(changes))
        return step

    @contextmanager
    def group(self, label: str) -> Iterator[None]:
        """Every change made inside the ``with`` block is one undo step called ``label``."""
        self.end_stroke()
        try:
            with self.history.group(label):
                yield
        finally:
            self._fire(())

    # -- painting ------------------------------------------------------------------
    def begin_stroke(self, value: int, point: tuple[float, float], radius: float,
                     layer: Layer = Layer.GRID) -> None:
        """Start a brush stroke with a dab at ``point``: GRID, a theme index ``value`` in vertex
        units; SCRIBBLES, a class ``value`` (theme + 1, 0 erases) in photo pixels.
        """
        self.end_stroke()
        stroke = Stroke(self.data, layer, layers.check_value(layer, value, len(self.library)))
        events = stroke.start(point, radius)
        self._stroke = stroke
        self._fire(events, history=False)

    def stroke_to(self, point: tuple[float, float], radius: float) -> EditAtom | None:
        """Extend the stroke to ``point``; applied and announced at once (the view
        follows the mouse), the undo step is made by :meth:`end_stroke`."""
        if self._stroke is None:
            raise TerrathemeError("stroke_to called without begin_stroke")
        atom, events = self._stroke.extend(point, radius)
        self._fire(events, history=False)
        return atom

    def end_stroke(self) -> Step | None:
        """Finish the open stroke as one undo step (None if it changed nothing or none is open)."""
        stroke, self._stroke = self._stroke, None
        if stroke is None:
            return None
        changes, events = stroke.finish()
        step = self.history.record(stroke.label, changes)
        self._fire(events, history=step is not None)
        return step

    @property
    def in_stroke(self) -> bool:
        return self._stroke is not None

    def _paint(self, label: str, fp: VertexSelection, value: int) -> Step | None:
        value = layers.check_value(Layer.GRID, value, len(self.library))
        atom = EditAtom.record(self.indices, fp, value)
        if atom is None:
            return None
        recolour = repaint_colour_map(self.data, atom)
        return self._commit(label, [Paint(Layer.GRID, atom),
                                    *([recolour] if recolour is not None else [])])

    def fill_rect(self, p0: tuple[float, float], p1: tuple[float, float], value: int
                  ) -> Step | None:
        """Set every vertex in the rectangle with corners ``p0``, ``p1`` to ``value``."""
        return self._paint("rectangle fill", rect_footprint(self.indices.shape, p0, p1), value)

    def flood_fill(self, point: tuple[float, float], value: int) -> Step | None:
        """Fill the 4-connected region of equal indices at ``point`` with ``value``."""
        return self._paint("flood fill", flood_footprint(self.indices, point), value)

    def pick(self, point: tuple[float, float]) -> int | None:
        """Eyedropper: the theme index at the vertex nearest ``point`` (vertex units)."""
        return eyedropper(self.indices, point)

    def replace_grid(self, indices: np.ndarray, label: str = "replace grid") -> Step | None:
        """Replace the whole grid as one undo step (None when it is the same grid)."""
        return self._commit(label, grid_replacement(self.data, indices, len(self.library)))

    # -- themes ----------------------------------------------------------------------
    def replace_theme(self, k: int, theme: Theme, label: str | None = None) -> Step | None:
        """Rename / recolour / retexture theme ``k`` (None when ``theme`` equals it)."""
        old = self.library[k]
        k = k % len(self.library)
        layers.check_theme_name(self.library, theme.name, skip=k)
        if theme == old:
            return None
        return self._commit(label or f"change theme {old.name}", [SetTheme(k, old, theme)])

    def add_theme(self, theme: Theme) -> int:
        """Append a theme as one undo step; returns its index."""
        layers.check_theme_name(self.library, theme.name)
        if len(self.library) >= 256:
            raise TerrathemeError("a theme library holds at most 256 themes")
        self._commit(f"add theme {theme.name}", [AppendTheme(theme)])
        return len(self.library) - 1

    # -- photo, confidence, classification results ----------------------------------------
    def apply_classification(self, update: ClassificationUpdate, label: str = "classification"
                             ) -> Step | None:
        """A classification result as one undo step; None if nothing changes."""
        changes = classification_changes(self.data, update)
        return self._commit(label, changes) if changes else None

    # -- history -------------------------------------------------------------------
    def undo(self) -> Step | None:
        """Undo the last step (an open stroke is finished first, then undone)."""
        self.end_stroke()
        step = self.history.pop_undo()
        if step is not None:
            self._fire([e for c in reversed(step.changes) for e in c.revert(self.data)])
        return step

    def redo(self) -> Step | None:
        """Redo the last undone step."""
        self.end_stroke()
        step = self.history.pop_redo()
        if step is not None:
            self._fire(self._apply(step.changes))
        return step

    def save(self, path) -> None:
        """Write the project file (``core.model.project.save_project``); marks it clean."""
        self.end_stroke()
        save_project(path, self.texture)
        self.history.mark_saved()
        self._fire(())

