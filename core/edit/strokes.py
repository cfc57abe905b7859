"""A brush stroke in progress: painted as the mouse moves, one undo step at the end.

Each move paints the capsule from the last point at once, so the view follows the
mouse; :meth:`Stroke.finish` merges the atoms into the stroke's one undo step (with the
scribble layer's creation, for a first scribble).
"""

from __future__ import annotations

import numpy as np
from terratheme.core.edit.atoms import EditAtom, merge_atoms
from terratheme.core.edit.changes import (
    Change,
    Paint,
    SwapLayer,
    drop_prior_without_classes,
    repaint_colour_map,
)
from terratheme.core.edit.events import Event
from terratheme.core.edit.layers import DocumentData, Layer
from terratheme.core.edit.tools import capsule_footprint
from terratheme.core.errors import TerrathemeError

#: the layers a brush paints, and the label of their strokes in the history
STROKE_LABELS = {Layer.GRID: "brush stroke", Layer.SCRIBBLES: "scribble"}


class Stroke:
    """One stroke of ``value`` on a painted ``layer`` of ``data`` (checked by the caller).

    Points and radii are in the layer's units: vertices for the grid, photo
    pixels for the scribbles.
    """

    def __init__(self, data: DocumentData, layer: Layer, value: int) -> None:
        if layer not in STROKE_LABELS:
            raise TerrathemeError(f"the {layer.value} layer is not painted with a brush")
        self.data, self.layer, self.value = data, layer, value
        self.label = STROKE_LABELS[layer]
        self.before: list[Change] = []
        self.parts: list[EditAtom] = []
        self.last: tuple[float, float] | None = None

    def start(self, point: tuple[float, float], radius: float) -> list[Event]:
        """The first dab; returns the events of what it changed."""
        if not np.isfinite(radius) or radius < 0:
            raise TerrathemeError(f"brush radius must be a finite number >= 0, got {radius}")
        events: list[Event] = []
        photo = self.data.texture.photo
        if self.layer is Layer.SCRIBBLES and self.data.texture.scribbles is None:
            if photo is None:
                raise TerrathemeError("scribbles need a photo: there is none in this project")
            # The first stroke brings the layer into being (undone with it).
            self.before = [SwapLayer(Layer.SCRIBBLES, None, np.zeros(photo.shape[:2], np.uint8))]
            events += self.before[0].apply(self.data)
        self.last = point
        return events + self.extend(point, radius)[1]

    def extend(self, point: tuple[float, float], radius: float
               ) -> tuple[EditAtom | None, list[Event]]:
        """Paint the capsule from the last point to ``point``: the atom applied and its events."""
        array = self.data.layer(self.layer)
        fp = capsule_footprint(array.shape, self.last, point, radius)
        self.last = point
        atom = EditAtom.record(array, fp, self.value)
        if atom is None:
            return None, []
        self.parts.append(atom)
        return atom, Paint(self.layer, atom).apply(self.data)

    def finish(self) -> tuple[list[Change], list[Event]]:
        """The stroke's changes as one step (empty if it painted nothing) and the events
        of what finishing changed."""
        merged = merge_atoms(self.parts)
        if merged is None:
            # Nothing painted: take back the layer the stroke brought into being.
            return [], [e for c in reversed(self.before) for e in c.revert(self.data)]
        # The parts are applied already; the step records them as one paint.
        prior = (drop_prior_without_classes(self.data, self.data.scribble_classes())
                 if self.layer is Layer.SCRIBBLES else [])
        # A repainted grid shows its new themes' colours (no stale colour-map gain).
        recolour = (repaint_colour_map(self.data, merged)
                    if self.layer is Layer.GRID else None)
        after = [*prior, *([recolour] if recolour is not None else [])]
        events = [e for c in after for e in c.apply(self.data)]
        return [*self.before, Paint(self.layer, merged), *after], events
