"""The Perspective tab: a real-time fly-over of the textured ground, and the CPU filters beside it.

The fly-over (:mod:`.flyover`) draws the open project with the GPU's filtered path,
displaced by a grey height map if given, and follows edits live. One click (or C) shows
the same camera through a CPU preview filter, rendered on a worker thread from the
project's render (at most ``MAX_TEXTURE`` texels a side).
"""

from __future__ import annotations

import numpy as np
from PySide6.QtCore import Qt, QThread, QTimer, Signal
from PySide6.QtWidgets import (
    QComboBox,
    QDoubleSpinBox,
    QFileDialog,
    QFormLayout,
    QHBoxLayout,
    QLabel,
    QPushButton,
    QSizePolicy,
    QStackedWidget,
    QVBoxLayout,
    QWidget,
)
from terratheme.app.editor.classify_job import keep_alive
from terratheme.app.editor.flyover import (
    HELP,
    FlightDriver,
    FlyoverGL,
    FlyoverImage,
    qt_gl_unavailable,
)
from terratheme.app.editor.imaging import qimage_view
from terratheme.core.gpu import GroundView
from terratheme.core.perspective import Camera, FilterOptions, Method, PreparedTexture
from terratheme.core.perspective.flight import MAX_PITCH, MIN_PITCH, Flight

MAX_TEXTURE = 2048
FRAME = (640, 360)
#: Qt's answer to "can you make an OpenGL 3.3 context?", asked once per process
_QT_GL: list[str | None] = []


class FrameJob(QThread):
    """Prepares the CPU texture if needed and renders one frame with a CPU filter."""

    done = Signal(object, float)
    failed = Signal(str)

    def __init__(self, prepared, camera: Camera, method: Method) -> None:
        super().__init__()
        self.prepared, self.camera, self.method = prepared, camera, method

    def run(self) -> None:
        import time

        try:
            t0 = time.perf_counter()
            prepared, scale = self.prepared()
            c = self.camera
            camera = Camera(height=c.height * scale, pitch=c.pitch, yaw=c.yaw, fov=c.fov,
                            x=c.x * scale, y=c.y * scale)
            frame = prepared.render(camera, FRAME, FilterOptions(method=self.method)).image
            rgb = np.ascontiguousarray(np.clip(frame[..., :3] * 255 + 0.5, 0, 255)
                                       .astype(np.uint8))
            self.done.emit(rgb, time.perf_counter() - t0)
        except Exception as exc:  # shown in the tab, never a crash
            self.failed.emit(str(exc) or type(exc).__name__)


class PerspectiveTab(QWidget):
    """The fly-over and the CPU comparison of one editor window."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.doc = None
        self.flight: Flight | None = None
        #: the height map and its scale, or None (flat, repeating plane)
        self.heights: tuple[np.ndarray, float] | None = None
        self._disconnect: list = []
        self._prepared: tuple[PreparedTexture, float] | None = None
        self._job: FrameJob | None = None
        self._pending = False
        self._frame: np.ndarray | None = None
        self.image = QLabel("no CPU frame yet")
        self.image.setFocusPolicy(Qt.FocusPolicy.StrongFocus)
        self.image.setMinimumSize(320, 180)
        self.image.setSizePolicy(QSizePolicy.Policy.Expanding, QSizePolicy.Policy.Expanding)
        self.gpu_info = QLabel("")
        self.gpu_info.setWordWrap(True)
        self.view = self._make_view()
        self.stack = QStackedWidget()
        self.stack.addWidget(self.view)
        self.stack.addWidget(self.image)
        self.stack.setSizePolicy(QSizePolicy.Policy.Expanding, QSizePolicy.Policy.Expanding)
        layout = QHBoxLayout(self)
        layout.addWidget(self.stack, 1)
        layout.addLayout(self._controls())
        self._timer = QTimer(self, singleShot=True, interval=150)
        self._timer.timeout.connect(self._start)
        self.show_cpu(self.driver is None)

    # -- building ----------------------------------------------------------------
    def _make_view(self) -> QWidget:
        """The GPU view Qt can host: its own OpenGL widget, else headless EGL, else a note."""
        if not _QT_GL:
            _QT_GL.append(qt_gl_unavailable())
        reason = _QT_GL[0]
        if reason is None:
            view = FlyoverGL(self)
        else:
            from terratheme.core.gpu import GpuUnavailableError, gl_context

            try:
                gl_context()
            except GpuUnavailableError as exc:
                self.driver = None
                self.gpu_info.setText(f"No fly-over: {reason}, and {exc}. The CPU filters "
                                      "still work.")
                return QLabel("no OpenGL 3.3 context")
            view = FlyoverImage(self)
            self.gpu_info.setText(f"{reason}: frames are drawn headless (EGL) and shown as "
                                  "images")
        view.drawn.connect(self._drawn)
        view.failed.connect(lambda msg: self.gpu_info.setText(f"GPU error: {msg}"))
        self.driver = FlightDriver(view, lambda: self.flight, self.ground_height)
        self.driver.moved.connect(self.set_flight)
        self.driver.settled.connect(view.request_frame)
        view.moving = lambda: self.driver.moving
        return view

    def _controls(self) -> QVBoxLayout:
        form = QFormLayout()
        self.height_box = self._spin(0.5, 1e6, 60, " texels")
        self.pitch_box = self._spin(MIN_PITCH, MAX_PITCH, 12, "°")
        self.yaw_box = self._spin(-180, 180, 30, "°")
        self.fov_box = self._spin(10, 120, 60, "°")
        for label, box in (("Height", self.height_box), ("Pitch", self.pitch_box),
                           ("Yaw", self.yaw_box), ("Field of view", self.fov_box)):
            form.addRow(label, box)
        self.compare = QPushButton("Compare: CPU filter (C)")
        self.compare.setCheckable(True)
        self.compare.toggled.connect(self.show_cpu)
        form.addRow(self.compare)
        self.method_box = QComboBox()
        for m in Method:
            if m is not Method.REFERENCE:
                self.method_box.addItem(m.value, m)
        self.method_box.currentIndexChanged.connect(lambda _i: self.show_cpu(True))
        form.addRow("CPU filter", self.method_box)
        load = QPushButton("Load height map…")
        load.clicked.connect(self._ask_height_map)
        flat = QPushButton("Flat")
        flat.clicked.connect(lambda: self.set_height_map(None))
        row = QHBoxLayout()
        row.addWidget(load)
        row.addWidget(flat)
        form.addRow(row)
        self.height_scale_box = self._spin(0, 1e6, 100, " texels", self._rescale_heights)
        form.addRow("Height scale", self.height_scale_box)
        self.info = QLabel("")
        self.info.setWordWrap(True)
        form.addRow(self.info)
        form.addRow(self.gpu_info)
        keys = QLabel(HELP)
        keys.setWordWrap(True)
        form.addRow(keys)
        side = QVBoxLayout()
        side.addLayout(form)
        side.addStretch(1)
        return side

    def _spin(self, lo: float, hi: float, value: float, suffix: str, slot=None) -> QDoubleSpinBox:
        box = QDoubleSpinBox()
        box.setRange(lo, hi)
        box.setValue(value)
        box.setSuffix(suffix)
        box.valueChanged.connect(slot or self._camera_edited)
        return box

    # -- the document --------------------------------------------------------------
    def set_document(self, doc) -> None:
        for disconnect in self._disconnect:
            disconnect()
        self.doc = doc
        events = doc.model.events
        self._disconnect = [events.grid.connect(self._grid_changed),
                            events.colour_map.connect(self._colour_map_changed),
                            events.themes.connect(self._themes_changed)]
        w, h = doc.extent
        self.set_flight(Flight(w / 2.0, h / 2.0, max(8.0, min(w, h) / 24), yaw=30.0, pitch=12.0))
        self.refresh_texture()
        if self.driver is not None:
            self.view.rebuild()

    def make_ground(self, context) -> GroundView:
        """The open project on ``context``, in its own style (the views call this)."""
        return GroundView.from_project(self.doc.texture, context=context)

    def ground_height(self, x: float, y: float) -> float:
        ground = getattr(self.view, "ground", None)
        return 0.0 if ground is None else ground.ground_height(x, y)

    def _grid_changed(self, change) -> None:
        # An edit in place re-uploads its cells; a replaced grid (new array) rebuilds.
        self._prepared = None
        ground = getattr(self.view, "ground", None)
        if ground is not None and ground.indices is not self.doc.texture.grid.indices:
            self.view.rebuild()
        elif self.driver is not None:
            self.view.mark_dirty(change.rows, change.cols)
        if self.compare.isChecked():
            self.request()

    def _colour_map_changed(self, change) -> None:
        # The colour map went neutral under an edit: swapped in place; gone with new themes:
        # a new ground.
        self._prepared = None
        ground = getattr(self.view, "ground", None)
        if self.driver is not None:
            if ground is None or not ground.set_colour_map(self.doc.texture.colour_map,
                                                           change.region):
                self.view.rebuild()
            else:
                self.view.request_frame()
        if self.compare.isChecked():
            self.request()

    def _themes_changed(self, change) -> None:
        if change.textures or change.index is None:
            self._prepared = None
            if self.driver is not None:
                self.view.rebuild()
            if self.compare.isChecked():
                self.request()

    # -- the camera -----------------------------------------------------------------
    def camera(self) -> Camera:
        return self.flight.camera()

    def set_flight(self, flight: Flight) -> None:
        """Fly to ``flight``: the boxes show it, the views draw it."""
        self.flight = flight
        for box, value in ((self.height_box, flight.height), (self.pitch_box, flight.pitch),
                           (self.yaw_box, flight.yaw), (self.fov_box, flight.fov)):
            box.blockSignals(True)
            box.setValue(value)
            box.blockSignals(False)
        if self.driver is not None:
            self.view.request_frame()
        if self.compare.isChecked():
            self.request()

    def _camera_edited(self, *_args) -> None:
        if self.flight is None:
            return
        f = self.flight
        self.set_flight(Flight(f.x, f.y, self.height_box.value(), self.yaw_box.value(),
                               self.pitch_box.value(), self.fov_box.value()))

    # -- height map -------------------------------------------------------------------
    def _ask_height_map(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Height map (a grey image)", "",
                                              "Images (*.png *.tif *.tiff *.exr *.jpg)")
        if path:
            self.load_height_map(path)

    def load_height_map(self, path: str) -> None:
        """Read a grey image and displace the ground by it (errors shown in the tab)."""
        from terratheme.core.errors import TerrathemeError
        from terratheme.core.io.images import read_image

        try:
            self.set_height_map(read_image(path))
        except TerrathemeError as exc:
            self.gpu_info.setText(str(exc))

    def set_height_map(self, heights: np.ndarray | None) -> None:
        self.heights = None if heights is None else (heights, self.height_scale_box.value())
        if self.driver is not None:
            self.view.set_height_map(*(self.heights or (None, 1.0)))
        self.info.setText("the CPU filters draw the flat plane" if heights is not None else "")

    def _rescale_heights(self, *_args) -> None:
        if self.heights is not None:
            self.set_height_map(self.heights[0])

    # -- drawing ----------------------------------------------------------------------
    def _drawn(self, ms: float) -> None:
        ground = getattr(self.view, "ground", None)
        if ground is None:
            return
        renderer = ground.ctx.info.get("GL_RENDERER", "OpenGL")
        aniso = (f"{ground.probes}x in the shader" if ground.probes
                 else f"{ground.sampler_anisotropy:g}x by the driver")
        self.gpu_info.setText(f"GPU fly-over: {ms:.0f} ms a frame on {renderer}; "
                              f"anisotropic filtering {aniso}")

    def show_cpu(self, on: bool) -> None:
        """Show the CPU filter's frame of the same camera (True) or the fly-over."""
        on = bool(on) or self.driver is None
        if self.compare.isChecked() != on:
            self.compare.blockSignals(True)
            self.compare.setChecked(on)
            self.compare.blockSignals(False)
        self.stack.setCurrentWidget(self.image if on and self.driver is not None
                                    else self.view if self.driver is not None else self.image)
        if on:
            self.image.setFocus()
            self.request()
        elif self.driver is not None:
            self.view.setFocus()
            self.view.request_frame()

    def keyPressEvent(self, event) -> None:
        """C switches between the fly-over and the CPU filter's frame, from either view."""
        if event.key() == Qt.Key.Key_C and not event.isAutoRepeat():
            self.compare.toggle()
            event.accept()
            return
        super().keyPressEvent(event)

    def refresh_texture(self) -> None:
        self._prepared = None
        if self.compare.isChecked():
            self.request()

    def prepared(self) -> tuple[PreparedTexture, float]:
        """The project's render (reduced) prefiltered, and the reduction; built on the worker."""
        if self._prepared is None:
            from terratheme.core.render.project import render_project

            w, h = self.doc.extent
            scale = min(1.0, MAX_TEXTURE / max(w, h))
            img = render_project(self.doc.texture, None, scale)
            scale = img.shape[1] / w
            self._prepared = (PreparedTexture(img, FilterOptions(method=Method.BILINEAR)), scale)
        return self._prepared

    def request(self, *_args) -> None:
        """Render a new CPU frame soon (debounced; one frame at a time)."""
        if self.isVisible():
            self._timer.start()
        else:
            self._pending = True

    def showEvent(self, event) -> None:
        super().showEvent(event)
        if self.compare.isChecked() and (self._pending or self._frame is None):
            self._pending = False
            self._timer.start()

    def _start(self) -> None:
        if self.doc is None or self.flight is None:
            return
        if self._job is not None and self._job.isRunning():
            self._pending = True
            return
        self._job = keep_alive(FrameJob(self.prepared, self.camera(),
                                        self.method_box.currentData()))
        self._job.done.connect(self._show)
        self._job.failed.connect(lambda msg: self.info.setText(f"error: {msg}"))
        self._job.finished.connect(self._finished)
        self.info.setText("rendering…")
        self._job.start()

    def _finished(self) -> None:
        if self._pending:
            self._pending = False
            self._timer.start()

    def _show(self, rgb: np.ndarray, seconds: float) -> None:
        from PySide6.QtGui import QPixmap

        self._frame = rgb
        self.image.setPixmap(QPixmap.fromImage(qimage_view(rgb).copy()))
        self.info.setText(f"CPU {self.method_box.currentText()}: {seconds * 1000:.0f} ms "
                          "per frame")

    def wait(self, msecs: int = 30000) -> None:
        """Stop scheduling frames and join the running one (before the window closes)."""
        self._timer.stop()
        self._pending = False
        if self._job is not None:
            self._job.wait(msecs)
