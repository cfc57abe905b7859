"""The editor's main window: canvases, palette, tools, menus and status bar."""

from __future__ import annotations

from PySide6.QtCore import QPointF, QRectF, Qt
from PySide6.QtGui import QAction, QActionGroup, QColor, QKeySequence, QPainter, QPen
from PySide6.QtWidgets import (
    QDockWidget,
    QLabel,
    QMainWindow,
    QSlider,
    QSpinBox,
    QSplitter,
    QTabWidget,
    QToolBar,
    QWidget,
)
from terratheme.app.editor.canvas import MapCanvas, ViewState
from terratheme.app.editor.document import EditorDocument
from terratheme.app.editor.help import HelpMixin
from terratheme.app.editor.imaging import ZoomPyramid
from terratheme.app.editor.palette import ThemePalette
from terratheme.app.editor.tools import Tool, ToolController
from terratheme.app.editor.uncertainty_view import UncertaintyMixin
from terratheme.app.editor.window_menus import MenuMixin
from terratheme.core.edit import HistoryChange, ScribbleChange


class MainWindow(MenuMixin, HelpMixin, UncertaintyMixin, QMainWindow):
    """The editor window over one :class:`EditorDocument` at a time.

    ``interactive=False`` (the screenshot command) reports problems in the
    status bar only, never in a dialog that would wait for a click.
    """

    def __init__(self, doc: EditorDocument, *, interactive: bool = True) -> None:
        super().__init__()
        self.interactive = interactive
        #: the last problem reported while not interactive (the screenshot command fails on it)
        self.failure: str | None = None
        self.resize(1400, 860)
        self.view = ViewState()
        self.index_canvas = MapCanvas(self.view, "Index map")
        self.render_canvas = MapCanvas(self.view, "Render")
        self.splitter = QSplitter(Qt.Orientation.Horizontal)
        self.splitter.addWidget(self.index_canvas)
        self.splitter.addWidget(self.render_canvas)
        self.tabs = QTabWidget()
        self.tabs.addTab(self.splitter, "Map")
        self.setCentralWidget(self.tabs)
        self.palette_widget = ThemePalette()
        dock = QDockWidget("Themes", self)
        dock.setObjectName("themes")
        dock.setWidget(self.palette_widget)
        dock.setFeatures(QDockWidget.DockWidgetFeature.DockWidgetMovable)
        self.addDockWidget(Qt.DockWidgetArea.LeftDockWidgetArea, dock)
        self.show_grid = True
        self.show_photo = True
        self.show_fidelity = False
        self.index_opacity = 0.75
        self.scribble_pyramid: ZoomPyramid | None = None
        self.job = None
        self.all_jobs: list = []
        self._status = QLabel()
        self.statusBar().addPermanentWidget(self._status)
        self.palette_widget.currentChanged.connect(self._theme_selected)
        self.palette_widget.error.connect(self.show_error)
        for canvas in (self.index_canvas, self.render_canvas):
            canvas.hovered.connect(self._hover)
        self.doc: EditorDocument | None = None
        self.tools: ToolController | None = None
        self._build_toolbar()
        self.build_menus()
        self.set_document(doc)

    # -- document ------------------------------------------------------------
    def set_document(self, doc: EditorDocument) -> None:
        """Show ``doc`` (a new, opened or classified project)."""
        if self.tools is not None:
            for canvas in (self.index_canvas, self.render_canvas):
                for sig in (canvas.pressed, canvas.dragged, canvas.released):
                    sig.disconnect()
        old = self.doc
        if old is not None:
            for sig in (old.regionChanged, old.scribblesChanged, old.historyChanged,
                        old.confidenceChanged, old.photoChanged):
                sig.disconnect()
        self.doc = doc
        tools = ToolController(doc)
        if self.tools is not None:
            tools.tool, tools.brush_size = self.tools.tool, self.tools.brush_size
        self.tools = tools
        tools.picked.connect(self.palette_widget.select)
        tools.error.connect(lambda msg: self.statusBar().showMessage(msg, 6000))
        for canvas in (self.index_canvas, self.render_canvas):
            canvas.pressed.connect(tools.press)
            canvas.dragged.connect(tools.drag)
            canvas.released.connect(self._released)
        doc.regionChanged.connect(self._region_changed)
        doc.scribblesChanged.connect(self._scribbles_changed)
        doc.confidenceChanged.connect(self._confidence_changed)
        doc.photoChanged.connect(self._photo_changed)
        doc.historyChanged.connect(self._history_changed)
        self.palette_widget.set_document(doc)
        self.index_canvas.layers = [self._paint_index]
        self.render_canvas.layers = [self._paint_render]
        for canvas in (self.index_canvas, self.render_canvas):
            canvas.overlays = [self._paint_grid, tools.paint_overlay]
        self._scribbles_changed(None)
        self._confidence_changed()
        self.photo_slider.setEnabled(doc.texture.photo is not None)
        self._history_changed(doc.history_state())
        self.fit()
        self.update_perspective_tab()

    def _history_changed(self, state: HistoryChange) -> None:
        """Edit > Undo / Redo and the title follow the core history."""
        for action, label, verb in ((self.undo_action, state.undo_label, "Undo"),
                                    (self.redo_action, state.redo_label, "Redo")):
            action.setEnabled(label is not None)
            action.setText(f"&{verb} {label}" if label else f"&{verb}")
        self._update_title()

    def _update_title(self, *_args) -> None:
        name = self.doc.path.name if self.doc and self.doc.path else "untitled"
        dirty = "" if self.doc is None or self.doc.clean else " *"
        self.setWindowTitle(f"{name}{dirty} — terratheme")

    def _photo_changed(self) -> None:
        self.photo_slider.setEnabled(self.doc.texture.photo is not None)
        self._scribbles_changed(None)
        self._repaint()

    # -- toolbar -------------------------------------------------------------
    def _build_toolbar(self) -> None:
        bar = QToolBar("Tools")
        bar.setObjectName("tools")
        self.addToolBar(bar)
        group = QActionGroup(self)
        self.tool_actions: dict[Tool, QAction] = {}
        for tool in Tool:
            act = QAction(f"{tool.label} ({tool.shortcut})", self, checkable=True)
            act.setShortcut(QKeySequence(tool.shortcut))
            act.triggered.connect(lambda _=False, t=tool: self.set_tool(t))
            group.addAction(act)
            bar.addAction(act)
            self.tool_actions[tool] = act
        self.tool_actions[Tool.BRUSH].setChecked(True)
        bar.addSeparator()
        bar.addWidget(QLabel(" Size "))
        self.size_box = QSpinBox()
        self.size_box.setRange(1, 200)
        self.size_box.setValue(3)
        self.size_box.setToolTip("Brush diameter in grid vertices ([ and ])")
        self.size_box.valueChanged.connect(self._size_changed)
        bar.addWidget(self.size_box)
        for key, delta in (("[", -1), ("]", 1)):
            act = QAction(self)
            act.setShortcut(QKeySequence(key))
            act.triggered.connect(lambda _=False, d=delta: self.size_box.setValue(
                self.size_box.value() + d))
            self.addAction(act)
        bar.addSeparator()
        bar.addWidget(QLabel(" Index opacity over photo "))
        self.photo_slider = QSlider(Qt.Orientation.Horizontal)
        self.photo_slider.setRange(0, 100)
        self.photo_slider.setValue(int(self.index_opacity * 100))
        self.photo_slider.setFixedWidth(120)
        self.photo_slider.valueChanged.connect(self._opacity_changed)
        bar.addWidget(self.photo_slider)
        for k in range(9):
            act = QAction(self)
            act.setShortcut(QKeySequence(str(k + 1)))
            act.triggered.connect(lambda _=False, i=k: self.palette_widget.select(i))
            self.addAction(act)

    def set_tool(self, tool: Tool) -> None:
        self.tool_actions[tool].setChecked(True)
        if self.tools is not None:
            self.tools.tool = tool
        self._repaint()

    def _size_changed(self, v: int) -> None:
        if self.tools is not None:
            self.tools.brush_size = float(v)
        self._repaint()

    def _opacity_changed(self, v: int) -> None:
        self.index_opacity = v / 100
        self.index_canvas.update()

    def _theme_selected(self, k: int) -> None:
        if self.tools is not None:
            self.tools.theme = k

    def _released(self, texel: QPointF) -> None:
        self.tools.release(texel)
        self._repaint()

    # -- painting ------------------------------------------------------------
    def _paint_index(self, p: QPainter, visible: QRectF, scale: float) -> None:
        doc = self.doc
        over_photo = self.show_photo and doc.photo_pyramid is not None
        if over_photo:
            doc.photo_pyramid.draw(p, visible, scale)
        if self.show_fidelity and doc.fidelity() is not None:
            doc.fidelity_pyramid.draw(p, visible, scale, self.index_opacity if over_photo else 1,
                                      smooth=False)
        else:
            doc.index_pyramid.draw(p, visible, scale, self.index_opacity if over_photo else 1.0,
                                   smooth=False)
        self._paint_uncertainty(p, visible, scale)
        if self.scribble_pyramid is not None:
            self.scribble_pyramid.draw(p, visible, scale, 0.9, smooth=False)

    def _paint_render(self, p: QPainter, visible: QRectF, scale: float) -> None:
        self.doc.render_pyramid.draw(p, visible, scale)

    def _paint_grid(self, p: QPainter, visible: QRectF, scale: float) -> None:
        n, m = self.doc.texture.grid.cell
        w, h = self.doc.extent
        if not self.show_grid or min(n, m) * scale < 24:
            return
        pen = QPen(QColor(0, 0, 0, 90))
        pen.setCosmetic(True)
        p.setPen(pen)
        area = visible.intersected(QRectF(0, 0, w, h))
        c0, c1 = int(area.left() // n), int(area.right() // n) + 1
        r0, r1 = int(area.top() // m), int(area.bottom() // m) + 1
        for c in range(c0, c1 + 1):
            p.drawLine(QPointF(c * n, area.top()), QPointF(c * n, area.bottom()))
        for r in range(r0, r1 + 1):
            p.drawLine(QPointF(area.left(), r * m), QPointF(area.right(), r * m))

    def _region_changed(self, r: QRectF) -> None:
        for canvas in (self.index_canvas, self.render_canvas):
            canvas.update_texels(r)

    def _scribbles_changed(self, change: ScribbleChange | None) -> None:
        """Refresh the block of the scribble overlay ``change`` names (all of it if None)."""
        sc = self.doc.texture.scribbles
        pyramid = self.scribble_pyramid
        if (change is None or change.whole or sc is None or pyramid is None
                or pyramid.base.shape[:2] != sc.shape):
            rgba = self.doc.scribble_rgba()
            self.scribble_pyramid = (None if rgba is None else
                                     ZoomPyramid(rgba, extent=self.doc.photo_extent()))
            self.index_canvas.update()
            return
        rows, cols = change.rows, change.cols
        pyramid.base[rows, cols] = self.doc.scribble_rgba(rows, cols)
        x, y = cols.start, rows.start
        w, h = cols.stop - x, rows.stop - y
        pyramid.update_region(x, y, w, h)
        ew, eh = self.doc.photo_extent()
        sx, sy = ew / sc.shape[1], eh / sc.shape[0]
        self.index_canvas.update_texels(QRectF(x * sx, y * sy, w * sx, h * sy))

    def _repaint(self) -> None:
        self.index_canvas.update()
        self.render_canvas.update()

    def fit(self) -> None:
        canvas = self.index_canvas if self.index_canvas.isVisible() else self.render_canvas
        size = canvas.size()
        if size.width() < 50:
            size = self.size() / 2
        self.view.fit(self.doc.extent, (size.width(), size.height()))

    # -- status --------------------------------------------------------------
    def _hover(self, texel: QPointF) -> None:
        doc = self.doc
        self.tools.hover = QPointF(texel)
        x, y = int(texel.x() // 1), int(texel.y() // 1)
        w, h = doc.extent
        n, m = doc.texture.grid.cell
        parts = []
        if 0 <= x < w and 0 <= y < h:
            parts.append(f"texel {x}, {y}")
            parts.append(f"cell {x // n}, {y // m}")
            k = doc.model.pick(doc.to_vertex(texel.x(), texel.y()))
            if k is not None:
                parts.append(f"theme {doc.texture.library[k].name}")
            fid = doc.fidelity() if self.show_fidelity else None
            if fid is not None:
                cy, cx = min(y // m, fid.shape[0] - 1), min(x // n, fid.shape[1] - 1)
                parts.append(f"ΔE {fid[cy, cx]:.1f}")
        parts.append(f"zoom {self.view.scale * 100:.0f}%")
        self._status.setText("   ".join(parts))
        if self.tools.tool in (Tool.BRUSH, Tool.SCRIBBLE, Tool.RECT):
            for canvas in (self.index_canvas, self.render_canvas):
                canvas.update()

    def show_error(self, message: str) -> None:
        if not self.interactive:
            # No dialog nobody could close: the status bar, and the caller's failure.
            self.failure = " ".join(message.split())
            self.statusBar().showMessage(self.failure)
            return
        from PySide6.QtWidgets import QMessageBox

        QMessageBox.critical(self, "terratheme", message)


def make_window(doc: EditorDocument) -> QWidget:
    return MainWindow(doc)
