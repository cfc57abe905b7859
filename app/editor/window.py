"""The editor's main window: canvases, palette, tools, menus and status bar.

View > Show uncertainty tints where the last classification was least sure
(:mod:`core.edit.uncertainty` decides which pixels).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
from PySide6.QtCore import QPointF, QRectF, Qt, QTimer, QUrl
from PySide6.QtGui import (
    QAction,
    QActionGroup,
    QColor,
    QDesktopServices,
    QKeySequence,
    QPainter,
    QPen,
)
from PySide6.QtWidgets import (
    QDockWidget,
    QFileDialog,
    QLabel,
    QMainWindow,
    QMessageBox,
    QProgressBar,
    QPushButton,
    QSlider,
    QSpinBox,
    QSplitter,
    QTabWidget,
    QToolBar,
)
from terratheme.app.editor.canvas import MapCanvas, ViewState
from terratheme.app.editor.classify_job import ClassifyJob, keep_alive
from terratheme.app.editor.document import EditorDocument
from terratheme.app.editor.help import DOCS, about_text, docs_text, keys_help_html
from terratheme.app.editor.imaging import ZoomPyramid
from terratheme.app.editor.newproject import empty_project
from terratheme.app.editor.palette import ThemePalette
from terratheme.app.editor.tools import Tool, ToolController
from terratheme.core.edit import (
    UNCERTAIN_SHARE,
    ClassificationUpdate,
    ClassifyMode,
    HistoryChange,
    ScribbleChange,
    uncertainty_rgba,
)
from terratheme.core.errors import TerrathemeError

PROJECT_FILTER = "terratheme project (*.ttproj)"


class MainWindow(QMainWindow):
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
        self.show_uncertainty = False
        self._shown = False
        self.uncertainty_pyramid: ZoomPyramid | None = None
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
                        old.confidenceChanged):
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

    def showEvent(self, event) -> None:
        """Fit the views once the window is first laid out (before, the canvases have no size)."""
        super().showEvent(event)
        if not self._shown:
            self._shown = True
            QTimer.singleShot(0, self.fit)

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

    # -- menus: File, Edit, View, Classify ----------------------------------

    def build_menus(self) -> None:
        mb = self.menuBar()
        file = mb.addMenu("&File")
        self._act(file, "&New", self.new_project, QKeySequence.StandardKey.New)
        self._act(file, "&Open…", self.open_dialog, QKeySequence.StandardKey.Open)
        self._act(file, "&Save", self.save, QKeySequence.StandardKey.Save)
        self._act(file, "Save &As…", self.save_as, "Ctrl+Shift+S")
        file.addSeparator()
        self._act(file, "Export &render (PNG/TIFF/EXR)…", self.export_render, "Ctrl+E")
        self._act(file, "Export &packed index layer…", self.export_packed)
        file.addSeparator()
        self._act(file, "&Quit", self.close, QKeySequence.StandardKey.Quit)
        self.edit_menu = mb.addMenu("&Edit")
        # Bound once; the text and enabled state follow the core history.
        self.undo_action = self._act(self.edit_menu, "&Undo", lambda: self.doc.model.undo(),
                                     "Ctrl+Z")
        self.redo_action = self._act(self.edit_menu, "&Redo", lambda: self.doc.model.redo())
        self.redo_action.setShortcuts([QKeySequence("Ctrl+Shift+Z"), QKeySequence("Ctrl+Y")])
        self.undo_action.setData("Undo")
        self.redo_action.setData("Redo")
        view = mb.addMenu("&View")
        self._act(view, "&Fit to window", self.fit, "Ctrl+0")
        self._act(view, "Side by side", lambda: self.set_layout("both"), "Ctrl+1")
        self._act(view, "Index map only", lambda: self.set_layout("index"), "Ctrl+2")
        self._act(view, "Render only", lambda: self.set_layout("render"), "Ctrl+3")
        self._act(view, "&Toggle index map / render", self.toggle_layout, "T")
        view.addSeparator()
        self.grid_action = self._act(view, "Cell &grid", self._toggle("show_grid"), "G", True)
        self.photo_action = self._act(view, "&Photo under the index map",
                                      self._toggle("show_photo"), "P", True)
        self.fidelity_action = self._act(view, "Fidelity &heat map (render vs photo)",
                                         self._toggle("show_fidelity"), "H", False)
        self.build_uncertainty_action(view)
        cls = mb.addMenu("&Classify")
        for mode in ClassifyMode:
            self._act(cls, mode.value + "…", lambda _=False, m=mode: self.start_classification(m))
        cls.addSeparator()
        # Off by default: such a model fits this photo only (see classify --position).
        self.position_action = self._act(cls, "Scribbles: use where the strokes &lie",
                                         lambda _=False: None, checked=False)
        self.cancel_action = self._act(cls, "&Cancel classification", self.cancel_classification,
                                       "Esc")
        self.cancel_action.setEnabled(False)
        self.progress = QProgressBar()
        self.progress.setMaximumWidth(220)
        self.progress.setVisible(False)
        self.cancel_button = QPushButton("Cancel")
        self.cancel_button.setVisible(False)
        self.cancel_button.clicked.connect(self.cancel_classification)
        self.statusBar().addPermanentWidget(self.progress)
        self.statusBar().addPermanentWidget(self.cancel_button)
        self.build_help_menu(mb)

    def _act(self, menu, text, slot, shortcut=None, checked=None) -> QAction:
        act = QAction(text, self)
        if shortcut is not None:
            act.setShortcut(QKeySequence(shortcut))
        if checked is not None:
            act.setCheckable(True)
            act.setChecked(checked)
        act.triggered.connect(slot)
        menu.addAction(act)
        return act

    def _toggle(self, attr: str):
        def flip(checked: bool) -> None:
            setattr(self, attr, bool(checked))
            if attr == "show_fidelity":
                if checked and self.doc.texture.photo is None:
                    self.statusBar().showMessage("the fidelity view needs a photo", 4000)
                summary = self.doc.fidelity_summary() if checked else None
                self.index_canvas.title = (
                    "Fidelity: per-cell colour difference render vs photo "
                    "(CIEDE2000, dark 0 -> bright 25+)"
                    + (f"; whole texture: {summary}" if summary else "")
                    if checked else "Index map")
            self._repaint()

        return flip

    # -- layout ----------------------------------------------------------------
    def set_layout(self, which: str) -> None:
        self.index_canvas.setVisible(which in ("both", "index"))
        self.render_canvas.setVisible(which in ("both", "render"))

    def toggle_layout(self) -> None:
        self.set_layout("render" if self.index_canvas.isVisible() else "index")

    # -- files ---------------------------------------------------------------
    def _confirm_discard(self) -> bool:
        if self.doc is None or self.doc.clean:
            return True
        answer = QMessageBox.question(
            self, "terratheme", "Discard the unsaved changes?",
            QMessageBox.StandardButton.Discard | QMessageBox.StandardButton.Cancel)
        return answer == QMessageBox.StandardButton.Discard

    def new_project(self) -> None:
        if self._confirm_discard():
            self.set_document(EditorDocument(empty_project()))

    def open_dialog(self) -> None:
        if not self._confirm_discard():
            return
        path, _ = QFileDialog.getOpenFileName(self, "Open project", "", PROJECT_FILTER)
        if path:
            self.open_path(path)

    def open_path(self, path: str | Path) -> bool:
        """Open a project; a damaged or unreadable file shows an error dialog."""
        try:
            doc = EditorDocument.open(path, progress=self.render_progress())
        except (TerrathemeError, OSError) as exc:
            self.show_error(f"Cannot open {path}:\n{exc}")
            return False
        self.set_document(doc)
        return True

    def render_progress(self):
        """A progress callback for a long first render: the status-bar bar, kept painted."""
        from PySide6.QtCore import QEventLoop
        from PySide6.QtWidgets import QApplication

        def progress(done: int, total: int) -> None:
            self.progress.setVisible(done < total)
            self.progress.setRange(0, max(total, 1))
            self.progress.setValue(done)
            self.statusBar().showMessage("rendering…" if done < total else "", 2000)
            # Repaint only: no user input while the document is half made.
            QApplication.processEvents(QEventLoop.ProcessEventsFlag.ExcludeUserInputEvents)

        return progress

    def save(self) -> bool:
        if self.doc.path is None:
            return self.save_as()
        return self._save_to(self.doc.path)

    def save_as(self) -> bool:
        path, _ = QFileDialog.getSaveFileName(self, "Save project", "untitled.ttproj",
                                              PROJECT_FILTER)
        if not path:
            return False
        if not path.endswith(".ttproj"):
            path += ".ttproj"
        return self._save_to(path)

    def _save_to(self, path) -> bool:
        try:
            saved = self.doc.save(path)
        except (TerrathemeError, OSError) as exc:
            self.show_error(f"Cannot save {path}:\n{exc}")
            return False
        self.statusBar().showMessage(f"saved {saved}", 4000)
        self._update_title()
        return True

    def export_render(self, path: str | None = None) -> bool:
        """The preview render as an image (PNG, TIFF or EXR)."""
        from terratheme.core.io.images import write_image

        return self._export(path, "Export render", "render.png",
                            "Images (*.png *.tif *.tiff *.exr)",
                            lambda out: write_image(out, self.doc.preview.image))

    def export_packed(self, path: str | None = None) -> bool:
        """The vertex index grid packed along a Hilbert curve (``core.packing``)."""

        def write(out: str) -> None:
            try:
                from terratheme.core.packing import pack
            except ImportError as exc:
                raise TerrathemeError("the packer (core.packing.pack) is not available "
                                      "in this build") from exc
            pack(self.doc.texture.grid.indices).save(out)

        return self._export(path, "Export packed index layer", "index.sfc",
                            "Packed layer (*.sfc)", write)

    def _export(self, path: str | None, title: str, default_name: str, file_filter: str,
                write: Callable[[str], None]) -> bool:
        """``write(path)``, asking for the path unless given; errors go to a dialog."""
        if not path:
            path, _ = QFileDialog.getSaveFileName(self, title, default_name, file_filter)
        if not path:
            return False
        try:
            write(path)
        except (TerrathemeError, OSError) as exc:
            self.show_error(f"Cannot export {path}:\n{exc}")
            return False
        self.statusBar().showMessage(f"exported {path}", 4000)
        return True

    # -- classification --------------------------------------------------------
    def start_classification(self, mode: ClassifyMode) -> ClassifyJob | None:
        """Classify the project's photo on a worker thread (progress bar, Cancel)."""
        tex = self.doc.texture
        if tex.photo is None:
            self.show_error("Classification needs a photo: start a project with "
                            "`terratheme app PHOTO`.")
            return None
        if self.job is not None:
            return None
        scribbles = None if tex.scribbles is None else tex.scribbles.copy()
        # Scribble runs reuse the class prior of the first strokes (same classes painted).
        prior = self.doc.model.prior_for_scribbles() if mode is ClassifyMode.SCRIBBLES else None
        # A project just started over a photo: its themes become the classes, nothing else.
        fresh = (self.doc.fresh_from_photo and not self.doc.model.history.can_undo
                 and mode in (ClassifyMode.AERIAL, ClassifyMode.UNSUPERVISED_NEW))
        job = ClassifyJob(mode, tex.photo, scribbles, tex.library, tex.grid.cell,
                          tex.grid.indices.shape, class_weights=prior,
                          position=mode is ClassifyMode.SCRIBBLES
                          and self.position_action.isChecked(),
                          replace_themes=fresh)
        keep_alive(job)
        job.progressed.connect(self._job_progress)
        job.succeeded.connect(lambda result, j=job: self._job_done(j, result))
        job.failed.connect(lambda msg: self.show_error(f"Classification failed:\n{msg}"))
        job.finished.connect(lambda j=job: self._job_finished(j))
        self.job = job
        self.all_jobs.append(job)
        self.progress.setRange(0, 0)
        self.progress.setVisible(True)
        self.cancel_button.setVisible(True)
        self.cancel_action.setEnabled(True)
        kept = " (keeping the first strokes' class prior)" if prior else ""
        self.statusBar().showMessage(f"classifying: {mode.value}{kept}")
        job.start()
        return job

    def cancel_classification(self) -> None:
        if self.job is not None:
            self.job.cancel()
            self.statusBar().showMessage("classification cancelled", 4000)
            self._job_finished(self.job)

    def _job_progress(self, done: int, total: int) -> None:
        self.progress.setRange(0, max(total, 1))
        self.progress.setValue(done)

    def _job_done(self, job: ClassifyJob, result: tuple[ClassificationUpdate, int]) -> None:
        """Apply a classification result as one undo step of the core document."""
        if job is not self.job or job.cancelled:
            return
        doc = self.doc
        model = doc.model
        update, n_classes = result
        unchanged = not update.new_themes and np.array_equal(update.indices,
                                                             doc.texture.grid.indices)
        try:
            model.apply_classification(update)
        except TerrathemeError as exc:
            self.show_error(f"Classification result not applied:\n{exc}")
            return
        doc.fresh_from_photo = doc.fresh_from_photo and not update.replace_themes
        if unchanged:
            # A rerun: say so (only the confidence map and prior were replaced).
            self.statusBar().showMessage("classified: the grid is unchanged", 6000)
        else:
            self.statusBar().showMessage(f"classified into {n_classes} classes", 6000)

    def _job_finished(self, job: ClassifyJob) -> None:
        if job is not self.job:
            return
        self.job = None
        self.progress.setVisible(False)
        self.cancel_button.setVisible(False)
        self.cancel_action.setEnabled(False)

    def wait_for_jobs(self, msecs: int = 30000) -> None:
        """Cancel and join every classification thread (before the window closes)."""
        for job in self.all_jobs:
            job.cancel()
            job.wait(msecs)
        self.all_jobs = [j for j in self.all_jobs if j.isRunning()]
        if getattr(self, "perspective_tab", None) is not None:
            self.perspective_tab.wait(msecs)

    def closeEvent(self, event) -> None:
        if not self._confirm_discard():
            event.ignore()
            return
        self.wait_for_jobs()
        event.accept()

    # -- perspective -----------------------------------------------------------
    def update_perspective_tab(self) -> None:
        """Add or refresh the perspective preview tab (when core.perspective is available)."""
        try:
            from terratheme.app.editor.perspective_tab import PerspectiveTab
        except ImportError:
            return
        if getattr(self, "perspective_tab", None) is None:
            self.perspective_tab = PerspectiveTab()
            self.tabs.addTab(self.perspective_tab, "Perspective")
        self.perspective_tab.set_document(self.doc)

    # -- help menu -----------------------------------------------------------

    def build_help_menu(self, menubar) -> None:
        help_menu = menubar.addMenu("&Help")
        keys = QAction("&Keys and mouse…", self)
        keys.setShortcut(QKeySequence(QKeySequence.StandardKey.HelpContents))
        keys.triggered.connect(self.show_keys_help)
        docs = QAction("&Documentation…", self)
        docs.triggered.connect(self.show_docs)
        about = QAction("&About terratheme…", self)
        about.triggered.connect(self.show_about)
        for act in (keys, docs, about):
            help_menu.addAction(act)
        self.help_menu = help_menu

    def show_keys_help(self) -> None:
        box = QMessageBox(QMessageBox.Icon.NoIcon, "Keys and mouse — terratheme",
                          keys_help_html(self), parent=self)
        box.setStyleSheet("QLabel { min-width: 640px; }")
        box.exec()

    def show_docs(self) -> None:
        """Open the README in the desktop's viewer, and say where the docs are."""
        readme = DOCS[0]
        if readme.exists():
            QDesktopServices.openUrl(QUrl.fromLocalFile(str(readme)))
        QMessageBox.information(self, "Documentation — terratheme", docs_text())

    def show_about(self) -> None:
        QMessageBox.about(self, "About terratheme", about_text())

    # -- View > Show uncertainty -----------------------------------------------

    def build_uncertainty_action(self, menu) -> QAction:
        act = QAction("Show &uncertainty (least confident 10% of the photo)", self)
        act.setShortcut(QKeySequence("U"))
        act.setCheckable(True)
        act.setStatusTip("Tint where the last classification was least sure: "
                         "add correction strokes there")
        act.toggled.connect(self.set_show_uncertainty)
        menu.addAction(act)
        self.uncertainty_action = act
        self.uncertainty_label = QLabel()
        self.uncertainty_label.setVisible(False)
        self.statusBar().addPermanentWidget(self.uncertainty_label)
        return act

    def set_show_uncertainty(self, on: bool, quiet: bool = False) -> None:
        """Show or hide the tint; the toggle follows (off when there is no confidence map)."""
        doc = self.doc
        mask = None if doc is None else doc.model.uncertain()
        if on and mask is None and not quiet:
            self.statusBar().showMessage(
                "no confidence map: classify the photo first (Classify menu)", 4000)
        on = bool(on) and mask is not None
        self.show_uncertainty = on
        if self.uncertainty_action.isChecked() != self.show_uncertainty:
            self.uncertainty_action.blockSignals(True)
            self.uncertainty_action.setChecked(self.show_uncertainty)
            self.uncertainty_action.blockSignals(False)
        if self.show_uncertainty:
            self.uncertainty_pyramid = ZoomPyramid(uncertainty_rgba(mask),
                                               extent=doc.photo_extent())
            self.uncertainty_label.setText(
                f"uncertain: {100 * mask.mean():.1f}% of the photo "
                f"(lowest {100 * UNCERTAIN_SHARE:.0f}% confidence, as regions)")
        else:
            self.uncertainty_pyramid = None
        self.uncertainty_label.setVisible(self.show_uncertainty)
        self.index_canvas.update()

    def _confidence_changed(self) -> None:
        """A new or cleared confidence map: rebuild or drop the tint, keeping the toggle."""
        self.set_show_uncertainty(self.show_uncertainty, quiet=True)

    def _paint_uncertainty(self, p: QPainter, visible: QRectF, scale: float) -> None:
        if self.show_uncertainty and self.uncertainty_pyramid is not None:
            self.uncertainty_pyramid.draw(p, visible, scale, 1.0, smooth=False)
