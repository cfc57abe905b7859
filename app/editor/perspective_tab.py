"""The perspective preview tab: the render on a terrain plane seen from a camera.

Uses ``core.perspective`` (the seed's anisotropic parallelogram filter and its
baselines). The texture is the editor's render, reduced to at most
``MAX_TEXTURE`` texels a side; frames are rendered on a worker thread so
camera changes never block the window. "Update texture" picks up edits.
"""

from __future__ import annotations

import cv2
import numpy as np
from PySide6.QtCore import QThread, QTimer, Signal
from PySide6.QtWidgets import (
    QComboBox,
    QDoubleSpinBox,
    QFormLayout,
    QHBoxLayout,
    QLabel,
    QPushButton,
    QSizePolicy,
    QVBoxLayout,
    QWidget,
)

from app.editor.classify_job import keep_alive
from app.editor.imaging import qimage_view
from core.perspective import Camera, FilterOptions, Method, PreparedTexture

MAX_TEXTURE = 2048
FRAME = (640, 360)


class FrameJob(QThread):
    """Prepares the texture if needed and renders one frame."""

    done = Signal(object, float)
    failed = Signal(str)

    def __init__(self, prepared, camera: Camera, method: Method) -> None:
        super().__init__()
        self.prepared, self.camera, self.method = prepared, camera, method

    def run(self) -> None:
        import time

        try:
            t0 = time.perf_counter()
            prepared = self.prepared()
            frame = prepared.render(self.camera, FRAME, FilterOptions(method=self.method)).image
            rgb = np.ascontiguousarray(np.clip(frame[..., :3] * 255 + 0.5, 0, 255)
                                       .astype(np.uint8))
            self.done.emit(rgb, time.perf_counter() - t0)
        except Exception as exc:  # shown in the tab, never a crash
            self.failed.emit(str(exc) or type(exc).__name__)


class PerspectiveTab(QWidget):
    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.doc = None
        self._prepared: PreparedTexture | None = None
        self._job: FrameJob | None = None
        self._pending = False
        self._frame: np.ndarray | None = None
        self.image = QLabel("no frame yet")
        self.image.setMinimumSize(320, 180)
        self.image.setSizePolicy(QSizePolicy.Policy.Expanding, QSizePolicy.Policy.Expanding)
        form = QFormLayout()
        self.height_box = self._spin(1, 100000, 60, " texels")
        self.pitch_box = self._spin(1, 90, 12, "°")
        self.yaw_box = self._spin(-180, 180, 30, "°")
        self.fov_box = self._spin(10, 120, 60, "°")
        for label, box in (("Height", self.height_box), ("Pitch", self.pitch_box),
                           ("Yaw", self.yaw_box), ("Field of view", self.fov_box)):
            form.addRow(label, box)
        self.method_box = QComboBox()
        for m in Method:
            if m is not Method.REFERENCE:
                self.method_box.addItem(m.value, m)
        self.method_box.currentIndexChanged.connect(self.request)
        form.addRow("Filter", self.method_box)
        refresh = QPushButton("Update texture from the render")
        refresh.clicked.connect(self.refresh_texture)
        form.addRow(refresh)
        self.info = QLabel("")
        form.addRow(self.info)
        side = QVBoxLayout()
        side.addLayout(form)
        side.addStretch(1)
        layout = QHBoxLayout(self)
        layout.addWidget(self.image, 1)
        layout.addLayout(side)
        self._timer = QTimer(self, singleShot=True, interval=150)
        self._timer.timeout.connect(self._start)

    def _spin(self, lo: float, hi: float, value: float, suffix: str) -> QDoubleSpinBox:
        box = QDoubleSpinBox()
        box.setRange(lo, hi)
        box.setValue(value)
        box.setSuffix(suffix)
        box.valueChanged.connect(self.request)
        return box

    def set_document(self, doc) -> None:
        self.doc = doc
        w, h = doc.extent
        self.height_box.setValue(max(8.0, min(w, h) / 24))
        self.refresh_texture()

    def refresh_texture(self) -> None:
        self._prepared = None
        self.request()

    def prepared(self) -> PreparedTexture:
        """The (reduced) render prefiltered for the chosen method; built on the worker."""
        if self._prepared is None:
            img = self.doc.preview.image
            scale = MAX_TEXTURE / max(img.shape[:2])
            if scale < 1:
                size = (max(1, round(img.shape[1] * scale)), max(1, round(img.shape[0] * scale)))
                img = cv2.resize(img, size, interpolation=cv2.INTER_AREA)
            self._prepared = PreparedTexture(img, FilterOptions(method=Method.BILINEAR))
        return self._prepared

    def camera(self) -> Camera:
        return Camera(height=self.height_box.value(), pitch=self.pitch_box.value(),
                      yaw=self.yaw_box.value(), fov=self.fov_box.value())

    def request(self, *_args) -> None:
        """Render a new frame soon (debounced; one frame at a time)."""
        if self.isVisible():
            self._timer.start()
        else:
            self._pending = True

    def showEvent(self, event) -> None:
        super().showEvent(event)
        if self._pending or self._frame is None:
            self._pending = False
            self._timer.start()

    def _start(self) -> None:
        if self.doc is None:
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
        self.info.setText(f"{self.method_box.currentText()}: {seconds * 1000:.0f} ms per frame")

    def wait(self, msecs: int = 30000) -> None:
        """Stop scheduling frames and join the running one (before the window closes)."""
        self._timer.stop()
        self._pending = False
        if self._job is not None:
            self._job.wait(msecs)
