"""The map canvas: a zoomable, pannable view of texel space with drawable layers.

Two canvases (index map and render) share one :class:`ViewState`, so they
zoom and pan together. Coordinates: a texel ``(X, Y)`` shows at screen
``((X - ox) * s, (Y - oy) * s)``. Wheel zooms about the cursor, the middle or
right button (or Space + left) pans, the left button goes to the active tool
via the ``pressed``/``dragged``/``released`` signals (texel coordinates).
"""

from __future__ import annotations

from collections.abc import Callable

from PySide6.QtCore import QObject, QPointF, QRectF, Qt, Signal
from PySide6.QtGui import QColor, QPainter, QPen
from PySide6.QtWidgets import QWidget

Layer = Callable[[QPainter, QRectF, float], None]
MIN_SCALE, MAX_SCALE = 1 / 256, 64.0


class ViewState(QObject):
    """Zoom ``scale`` (screen pixels per texel) and ``origin`` (texel at the top-left)."""

    changed = Signal()

    def __init__(self) -> None:
        super().__init__()
        self.scale = 1.0
        self.origin = QPointF(0, 0)

    def set(self, scale: float, origin: QPointF) -> None:
        self.scale = min(max(scale, MIN_SCALE), MAX_SCALE)
        self.origin = QPointF(origin)
        self.changed.emit()

    def zoom_about(self, factor: float, screen: QPointF) -> None:
        """Zoom by ``factor`` keeping the texel under ``screen`` fixed."""
        texel = self.origin + screen / self.scale
        scale = min(max(self.scale * factor, MIN_SCALE), MAX_SCALE)
        self.set(scale, texel - screen / scale)

    def fit(self, extent: tuple[float, float], size: tuple[int, int]) -> None:
        """Fit a ``(width, height)`` texel extent into a ``size`` widget, centred."""
        w, h = extent
        sw, sh = max(size[0], 1), max(size[1], 1)
        scale = 0.95 * min(sw / max(w, 1), sh / max(h, 1))
        self.set(scale, QPointF(w / 2 - sw / 2 / scale, h / 2 - sh / 2 / scale))


class MapCanvas(QWidget):
    """Paints its layers in texel coordinates and reports mouse positions in texels."""

    pressed = Signal(QPointF, object)  # texel, modifiers
    dragged = Signal(QPointF)
    released = Signal(QPointF)
    hovered = Signal(QPointF)

    def __init__(self, view: ViewState, title: str = "", parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.view = view
        self.title = title
        self.layers: list[Layer] = []
        self.overlays: list[Layer] = []
        self._pan_from: QPointF | None = None
        self._tool_down = False
        self._space = False
        self.setMouseTracking(True)
        self.setFocusPolicy(Qt.FocusPolicy.StrongFocus)
        self.setMinimumSize(200, 160)
        self.setAttribute(Qt.WidgetAttribute.WA_OpaquePaintEvent)
        view.changed.connect(self.update)

    # -- coordinates ---------------------------------------------------------
    def to_texel(self, screen: QPointF) -> QPointF:
        return self.view.origin + screen / self.view.scale

    def to_screen_rect(self, r: QRectF) -> QRectF:
        s, o = self.view.scale, self.view.origin
        return QRectF((r.x() - o.x()) * s, (r.y() - o.y()) * s, r.width() * s, r.height() * s)

    def update_texels(self, r: QRectF) -> None:
        """Repaint only the screen area of a texel rectangle."""
        self.update(self.to_screen_rect(r).toAlignedRect().adjusted(-2, -2, 2, 2))

    # -- painting ------------------------------------------------------------
    def paintEvent(self, event) -> None:
        p = QPainter(self)
        p.fillRect(event.rect(), QColor(48, 48, 52))
        s, o = self.view.scale, self.view.origin
        exposed = QRectF(event.rect())
        visible = QRectF(o.x() + exposed.x() / s, o.y() + exposed.y() / s,
                         exposed.width() / s, exposed.height() / s)
        p.save()
        p.scale(s, s)
        p.translate(-o.x(), -o.y())
        for layer in self.layers + self.overlays:
            layer(p, visible, s)
        p.restore()
        if self.title:
            p.setPen(QPen(QColor(255, 255, 255, 200)))
            p.drawText(8, 16, self.title)
        p.end()

    # -- mouse ---------------------------------------------------------------
    def _is_pan(self, event) -> bool:
        b = event.button() if event.button() != Qt.MouseButton.NoButton else event.buttons()
        return bool(b & (Qt.MouseButton.MiddleButton | Qt.MouseButton.RightButton)) or (
            self._space and bool(b & Qt.MouseButton.LeftButton)
        )

    def mousePressEvent(self, event) -> None:
        if self._is_pan(event):
            self._pan_from = event.position()
        elif event.button() == Qt.MouseButton.LeftButton:
            self._tool_down = True
            self.pressed.emit(self.to_texel(event.position()), event.modifiers())

    def mouseMoveEvent(self, event) -> None:
        pos = event.position()
        if self._pan_from is not None:
            delta = (pos - self._pan_from) / self.view.scale
            self._pan_from = pos
            self.view.set(self.view.scale, self.view.origin - delta)
        elif self._tool_down:
            self.dragged.emit(self.to_texel(pos))
        self.hovered.emit(self.to_texel(pos))

    def mouseReleaseEvent(self, event) -> None:
        if self._pan_from is not None:
            self._pan_from = None
        elif self._tool_down and event.button() == Qt.MouseButton.LeftButton:
            self._tool_down = False
            self.released.emit(self.to_texel(event.position()))

    def wheelEvent(self, event) -> None:
        steps = event.angleDelta().y() / 120.0
        if steps:
            self.view.zoom_about(1.25**steps, event.position())

    def keyPressEvent(self, event) -> None:
        if event.key() == Qt.Key.Key_Space and not event.isAutoRepeat():
            self._space = True
        super().keyPressEvent(event)

    def keyReleaseEvent(self, event) -> None:
        if event.key() == Qt.Key.Key_Space and not event.isAutoRepeat():
            self._space = False
        super().keyReleaseEvent(event)
