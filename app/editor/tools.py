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

from app.editor.commands import ScribbleCommand
from app.editor.document import EditorDocument
from core.edit.session import merge_atoms


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


class ToolController(QObject):
    """Routes canvas mouse signals to the active tool.

    ``brush_size`` is the brush diameter in vertices (radius = size / 2).
    """

    picked = Signal(int)
    scribbled = Signal(object)  # the applied scribble atom

    def __init__(self, doc: EditorDocument) -> None:
        super().__init__()
        self.doc = doc
        self.tool = Tool.BRUSH
        self.brush_size = 3.0
        self.theme = 0
        self.hover: QPointF | None = None
        self._rect_from: QPointF | None = None
        self._points: list[tuple[float, float]] = []
        self._stroke_atoms: list = []

    # -- gestures ------------------------------------------------------------
    def press(self, texel: QPointF, modifiers=None) -> None:
        doc, v = self.doc, self.doc.to_vertex(texel.x(), texel.y())
        if self.tool is Tool.BRUSH:
            doc.session.begin_stroke(self.theme, v, self.brush_size / 2)
        elif self.tool is Tool.RECT:
            self._rect_from = QPointF(texel)
        elif self.tool is Tool.FILL:
            doc.commit(doc.session.flood_fill(v, self.theme), "flood fill")
        elif self.tool is Tool.PICK:
            k = doc.session.pick(v)
            if k is not None:
                self.picked.emit(k)
        elif self.tool is Tool.SCRIBBLE:
            self._points = [(texel.x(), texel.y())]
            self._scribble_segment()

    def drag(self, texel: QPointF) -> None:
        self.hover = QPointF(texel)
        if self.tool is Tool.BRUSH and self.doc.session.in_stroke:
            self.doc.session.stroke_to(self.doc.to_vertex(texel.x(), texel.y()),
                                       self.brush_size / 2)
        elif self.tool is Tool.SCRIBBLE and self._points:
            self._points.append((texel.x(), texel.y()))
            self._scribble_segment()

    def release(self, texel: QPointF) -> None:
        doc = self.doc
        if doc.session.in_stroke:  # even if the tool changed during the drag
            doc.commit(doc.session.end_stroke(), "brush stroke")
        elif self.tool is Tool.RECT and self._rect_from is not None:
            a = doc.to_vertex(self._rect_from.x(), self._rect_from.y())
            b = doc.to_vertex(texel.x(), texel.y())
            self._rect_from = None
            doc.commit(doc.session.fill_rect(a, b, self.theme), "rectangle fill")
        elif self._points:
            self._points = []
            atom, self._stroke_atoms = merge_atoms(self._stroke_atoms), []
            if atom is not None:
                doc.undo_stack.push(ScribbleCommand(doc, atom, "scribble"))

    def _scribble_segment(self) -> None:
        a = self._points[-2] if len(self._points) > 1 else self._points[-1]
        n = self.doc.texture.grid.cell[0]
        atom = self.doc.scribble_segment(a, self._points[-1], self.brush_size / 2 * n,
                                         self.theme + 1)
        if atom is not None:
            self._stroke_atoms.append(atom)
            self.scribbled.emit(atom)

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
