"""The editing tools: mouse gestures on the canvases turned into core edits.

Brush (B) paints a disc swept along the mouse path (one stroke = one undo
step); Rectangle (R) fills the vertices inside a dragged box; Fill (F) floods
the connected region of equal indices; Pick (I) is the eyedropper; Scribble
(S) paints training strokes into the photo's scribble layer for supervised
classification.
"""

from __future__ import annotations

from enum import Enum

from PySide6.QtCore import QObject, QPointF, QRectF, Qt, Signal
from PySide6.QtGui import QColor, QPainter, QPen
from terratheme.app.editor.document import EditorDocument
from terratheme.core.edit import Layer
from terratheme.core.errors import TerrathemeError


class Tool(Enum):
    BRUSH = ("Brush", "B")
    RECT = ("Rectangle", "R")
    FILL = ("Fill", "F")
    PICK = ("Pick", "I")
    SCRIBBLE = ("Scribble", "S")

    @property
    def label(self) -> str:
        return self.value[0]

    @property
    def shortcut(self) -> str:
        return self.value[1]


#: what each tool does, for Help > Keys and mouse
TOOL_HELP = {
    Tool.BRUSH: "paint the selected theme on the grid vertices under the brush",
    Tool.RECT: "drag a box: every vertex inside takes the selected theme",
    Tool.FILL: "click: the connected region of one theme takes the selected theme",
    Tool.PICK: "click: select the theme under the cursor",
    Tool.SCRIBBLE: "paint training strokes of the selected theme over the photo "
                   "(Classify > From scribbles)",
}


class ToolController(QObject):
    """Routes canvas mouse signals to the active tool, as edits of the core document.

    ``brush_size`` is the brush diameter in vertices (radius = size / 2).
    """

    picked = Signal(int)
    error = Signal(str)

    def __init__(self, doc: EditorDocument) -> None:
        super().__init__()
        self.doc = doc
        self.tool = Tool.BRUSH
        self.brush_size = 3.0
        self.theme = 0
        self.hover: QPointF | None = None
        self._rect_from: QPointF | None = None
        self._stroke_layer: Layer | None = None

    def _layer_point(self, layer: Layer, texel: QPointF) -> tuple[float, float]:
        """A texel position in the units of ``layer``: vertices or photo pixels."""
        if layer is Layer.GRID:
            return self.doc.model.texel_to_vertex(texel.x(), texel.y())
        return self.doc.model.texel_to_photo(texel.x(), texel.y())

    def _radius(self, layer: Layer) -> float:
        radius = self.brush_size / 2
        if layer is Layer.GRID:
            return radius
        # Scribbles: the brush's size in texels, in photo pixels.
        n = self.doc.texture.grid.cell[0]
        return radius * n * self.doc.texture.photo.shape[1] / self.doc.photo_extent()[0]

    # -- gestures ------------------------------------------------------------
    def press(self, texel: QPointF, modifiers=None) -> None:
        model = self.doc.model
        try:
            if self.tool in (Tool.BRUSH, Tool.SCRIBBLE):
                layer = Layer.GRID if self.tool is Tool.BRUSH else Layer.SCRIBBLES
                value = self.theme if layer is Layer.GRID else self.theme + 1
                if layer is Layer.SCRIBBLES and model.photo is None:
                    raise TerrathemeError("scribbles are painted over the photo, and this "
                                          "project has none")
                model.begin_stroke(value, self._layer_point(layer, texel), self._radius(layer),
                                   layer)
                self._stroke_layer = layer
            elif self.tool is Tool.RECT:
                self._rect_from = QPointF(texel)
            elif self.tool is Tool.FILL:
                model.flood_fill(model.texel_to_vertex(texel.x(), texel.y()), self.theme)
            elif self.tool is Tool.PICK:
                k = model.pick(model.texel_to_vertex(texel.x(), texel.y()))
                if k is not None:
                    self.picked.emit(k)
        except TerrathemeError as exc:
            self.error.emit(str(exc))

    def drag(self, texel: QPointF) -> None:
        self.hover = QPointF(texel)
        layer = self._stroke_layer
        if layer is not None and self.doc.model.in_stroke:
            self.doc.model.stroke_to(self._layer_point(layer, texel), self._radius(layer))

    def release(self, texel: QPointF) -> None:
        model = self.doc.model
        if model.in_stroke:  # even if the tool changed during the drag
            model.end_stroke()
        elif self.tool is Tool.RECT and self._rect_from is not None:
            a = model.texel_to_vertex(self._rect_from.x(), self._rect_from.y())
            b = model.texel_to_vertex(texel.x(), texel.y())
            self._rect_from = None
            model.fill_rect(a, b, self.theme)
        self._stroke_layer = None

    # -- overlay -------------------------------------------------------------
    def paint_overlay(self, p: QPainter, visible: QRectF, scale: float) -> None:
        """Brush outline or the rectangle being dragged (texel coordinates)."""
        pen = QPen(QColor(255, 255, 255, 220))
        pen.setCosmetic(True)
        pen.setWidthF(1.5)
        p.setPen(pen)
        p.setBrush(Qt.BrushStyle.NoBrush)
        if self._rect_from is not None and self.hover is not None:
            p.drawRect(QRectF(self._rect_from, self.hover).normalized())
        elif self.hover is not None and self.tool in (Tool.BRUSH, Tool.SCRIBBLE):
            n, m = self.doc.texture.grid.cell
            r = self.brush_size / 2
            if self.tool is Tool.SCRIBBLE:
                m = n
            p.drawEllipse(self.hover, r * n, r * m)
