"""Change events of the edit document: frozen dataclasses handed to plain callables.

One emitter per kind of change (:class:`DocumentEvents`, as napari's
``layer.events.data.connect``), fired after every change, undo and redo once the
document is consistent; a view connects and never polls.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, fields
from typing import Generic, TypeVar


@dataclass(frozen=True)
class GridChange:
    """Vertices in ``indices[rows, cols]`` may have changed."""

    rows: slice
    cols: slice


@dataclass(frozen=True)
class ScribbleChange:
    """Pixels ``scribbles[rows, cols]`` of the scribble layer may have changed.

    ``whole`` is True when the layer was created, removed or replaced (its
    shape may differ; ``rows``/``cols`` then span the new layer, empty if none).
    """

    rows: slice
    cols: slice
    whole: bool = False


@dataclass(frozen=True)
class ThemeChange:
    """The theme library changed.

    ``index``: the theme added, removed or replaced (None: the whole library);
    ``colours`` / ``textures``: display colours / textures of themes the grid may
    use changed (recolour the index map / re-render everything).
    """

    index: int | None
    colours: bool
    textures: bool


@dataclass(frozen=True)
class ColourMapChange:
    """The colour map changed over the texels ``(x, y, w, h)`` (the whole texture if None)."""

    region: tuple[int, int, int, int] | None = None


@dataclass(frozen=True)
class ConfidenceChange:
    """The classifier's confidence map was set, replaced or cleared."""


@dataclass(frozen=True)
class PriorChange:
    """The class prior kept between scribble classifications changed."""


@dataclass(frozen=True)
class HistoryChange:
    """The undo history moved: the labels of the steps Undo and Redo would take now
    (None: nothing), and ``clean``: the document equals its last saved state."""

    undo_label: str | None
    redo_label: str | None
    clean: bool


Event = (GridChange | ScribbleChange | ThemeChange | ColourMapChange | ConfidenceChange
         | PriorChange | HistoryChange)
E = TypeVar("E")


class Emitter(Generic[E]):
    """Calls every connected callable with each event, in connection order."""

    def __init__(self) -> None:
        self._callbacks: list[Callable[[E], None]] = []

    def connect(self, callback: Callable[[E], None]) -> Callable[[], None]:
        """Call ``callback(event)`` after every change; returns the disconnect function."""
        self._callbacks.append(callback)
        return lambda: self.disconnect(callback)

    def disconnect(self, callback: Callable[[E], None]) -> None:
        """Stop calling ``callback`` (no error if it was not connected)."""
        if callback in self._callbacks:
            self._callbacks.remove(callback)

    def emit(self, event: E) -> None:
        for callback in list(self._callbacks):
            callback(event)


@dataclass(frozen=True, eq=False)
class DocumentEvents:
    """One emitter per kind of change (``doc.events.grid.connect(callback)``)."""

    grid: Emitter[GridChange]
    scribbles: Emitter[ScribbleChange]
    themes: Emitter[ThemeChange]
    colour_map: Emitter[ColourMapChange]
    confidence: Emitter[ConfidenceChange]
    prior: Emitter[PriorChange]
    history: Emitter[HistoryChange]

    @classmethod
    def new(cls) -> DocumentEvents:
        return cls(*(Emitter() for _ in fields(cls)))

    def emit(self, event: Event) -> None:
        """Hand ``event`` to the emitter of its kind."""
        emitter = {
            GridChange: self.grid, ScribbleChange: self.scribbles, ThemeChange: self.themes,
            ColourMapChange: self.colour_map,
            ConfidenceChange: self.confidence, PriorChange: self.prior,
            HistoryChange: self.history,
        }[type(event)]
        emitter.emit(event)
