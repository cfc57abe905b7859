"""The fly-over view of the Perspective tab: the GPU renderer on the ground plane, flown live.

:class:`FlyoverGL` draws a :class:`core.gpu.GroundView` on Qt's own OpenGL context,
straight to the screen; :class:`FlyoverImage`, where Qt has no OpenGL (a remote or
offscreen session), draws it headless and shows images. :class:`FlightDriver` turns
keys, drags and the wheel into flight moves for either.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Protocol

import moderngl
import numpy as np
from PySide6.QtCore import QEvent, QObject, QPointF, Qt, QTimer, Signal
from PySide6.QtGui import QPainter, QSurfaceFormat
from PySide6.QtOpenGLWidgets import QOpenGLWidget
from PySide6.QtWidgets import QWidget
from terratheme.app.editor.imaging import qimage_view
from terratheme.core.gpu import GroundView
from terratheme.core.perspective import Camera
from terratheme.core.perspective.flight import Flight, FlightInput

#: keys held -> (FlightInput field, value)
KEYS = {
    Qt.Key.Key_W: ("forward", 1.0), Qt.Key.Key_S: ("forward", -1.0),
    Qt.Key.Key_D: ("right", 1.0), Qt.Key.Key_A: ("right", -1.0),
    Qt.Key.Key_E: ("up", 1.0), Qt.Key.Key_Q: ("up", -1.0),
    Qt.Key.Key_PageUp: ("up", 1.0), Qt.Key.Key_PageDown: ("up", -1.0),
    Qt.Key.Key_Right: ("yaw", 1.0), Qt.Key.Key_Left: ("yaw", -1.0),
    Qt.Key.Key_Down: ("pitch", 1.0), Qt.Key.Key_Up: ("pitch", -1.0),
}
HELP = ("W/S fly, A/D sideways, E/Q or PgUp/PgDn climb, arrows turn and pitch, "
        "drag to look, wheel to change height, Shift faster, C: CPU filter")
#: the motion timer's interval in milliseconds (about 60 steps a second)
TICK_MS = 16
#: pixels drawn along each side while the camera moves (stretched over the view)
MOVING_SCALE = 0.5


def surface_format() -> QSurfaceFormat:
    """OpenGL 3.3 core with a depth buffer (the shaders' and the height mesh's needs)."""
    fmt = QSurfaceFormat()
    fmt.setVersion(3, 3)
    fmt.setProfile(QSurfaceFormat.OpenGLContextProfile.CoreProfile)
    fmt.setDepthBufferSize(24)
    return fmt


def qt_gl_unavailable() -> str | None:
    """Why Qt cannot make an OpenGL 3.3 context here, or None when it can."""
    from PySide6.QtGui import QGuiApplication, QOffscreenSurface, QOpenGLContext

    fmt = surface_format()
    context = QOpenGLContext()
    context.setFormat(fmt)
    platform = QGuiApplication.platformName()
    if not context.create():
        return f"Qt's {platform} platform makes no OpenGL context"
    got = context.format()
    if (got.majorVersion(), got.minorVersion()) < (3, 3):
        return f"Qt's OpenGL context is {got.majorVersion()}.{got.minorVersion()}, not 3.3"
    surface = QOffscreenSurface()
    surface.setFormat(fmt)
    surface.create()
    if not context.makeCurrent(surface):
        return f"Qt's {platform} platform cannot make its OpenGL context current"
    context.doneCurrent()
    return None


class FlightDriver(QObject):
    """Keys, mouse and wheel on ``widget`` fly ``flight()`` (an event filter and a timer).

    Parameters
    ----------
    widget : QWidget
        Gets focus on click; its key, mouse and wheel events are taken.
    flight : callable() -> Flight
        The current flight.
    ground : callable(x, y) -> float
        The terrain's height under a ground point (the camera stays above it).

    Signals
    -------
    moved(Flight)
        The flight the input asks for (the owner stores it and redraws).
    settled()
        The camera stopped (keys released, drag ended): time for a full-size frame.
    """

    moved = Signal(object)
    settled = Signal()

    def __init__(self, widget: QWidget, flight: Callable[[], Flight],
                 ground: Callable[[float, float], float]) -> None:
        super().__init__(widget)
        self._flight, self._ground = flight, ground
        self.held: dict[Qt.Key, tuple[str, float]] = {}
        #: keys pressed since the last motion step
        self._unstepped: set[Qt.Key] = set()
        self.fast = False
        self._drag: QPointF | None = None
        self._last = 0.0
        self.timer = QTimer(self, interval=TICK_MS)
        self.timer.timeout.connect(self.tick)
        widget.setFocusPolicy(Qt.FocusPolicy.StrongFocus)
        widget.setMouseTracking(False)
        widget.installEventFilter(self)

    @property
    def moving(self) -> bool:
        """True while keys fly the camera or the mouse drags it."""
        return self.timer.isActive() or self._drag is not None

    def held_input(self) -> FlightInput:
        """The input the held keys make."""
        axes = {"forward": 0.0, "right": 0.0, "up": 0.0, "yaw": 0.0, "pitch": 0.0}
        for axis, value in self.held.values():
            axes[axis] = max(-1.0, min(1.0, axes[axis] + value))
        return FlightInput(**axes, fast=self.fast)

    def tick(self, seconds: float | None = None) -> None:
        """One motion step of the held keys (``seconds`` since the last; default: measured)."""
        now = time.perf_counter()
        step = min(0.1, now - self._last) if seconds is None else seconds
        self._last = now
        self._unstepped.clear()
        held = self.held_input()
        if held.idle:
            self.timer.stop()
            self.settled.emit()
            return
        flight = self._flight()
        self.moved.emit(flight.step(held, step, ground=self._ground(flight.x, flight.y)))

    def eventFilter(self, obj, event) -> bool:
        kind = event.type()
        if kind in (QEvent.Type.KeyPress, QEvent.Type.KeyRelease):
            return self._key(event, kind == QEvent.Type.KeyPress)
        if kind == QEvent.Type.MouseButtonPress:
            obj.setFocus()
            self._drag = event.position()
            return True
        if kind == QEvent.Type.MouseMove and self._drag is not None:
            delta = event.position() - self._drag
            self._drag = event.position()
            self.moved.emit(self._flight().looked(delta.x(), delta.y()))
            return True
        if kind == QEvent.Type.MouseButtonRelease:
            self._drag = None
            self.settled.emit()
            return True
        if kind == QEvent.Type.Wheel:
            flight = self._flight()
            steps = event.angleDelta().y() / 120.0
            self.moved.emit(flight.zoomed(steps, self._ground(flight.x, flight.y)))
            return True
        if kind == QEvent.Type.FocusOut:
            self.held.clear()
            self._unstepped.clear()
        return False

    def _key(self, event, pressed: bool) -> bool:
        key = Qt.Key(event.key())
        self.fast = bool(event.modifiers() & Qt.KeyboardModifier.ShiftModifier)
        if key not in KEYS:
            return False
        if event.isAutoRepeat():
            return True
        if pressed:
            self.held[key] = KEYS[key]
            self._unstepped.add(key)
            if not self.timer.isActive():
                self._last = time.perf_counter()
                self.timer.start()
        else:
            if key in self._unstepped:
                # A tap released before the first tick still moves, for the time it was
                # held (at least one tick).
                self.tick(max(TICK_MS / 1000, time.perf_counter() - self._last))
            self.held.pop(key, None)
        return True


class Scene(Protocol):
    """What both views draw (the Perspective tab): the ground, the camera, the height map."""

    #: the height map and its scale (texels per unit), or None for the flat plane
    heights: tuple[np.ndarray, float] | None

    def make_ground(self, context: moderngl.Context) -> GroundView:
        """A ground view of the open project on ``context``."""

    def camera(self) -> Camera:
        """The camera of the current flight."""


class FlyoverGL(QOpenGLWidget):
    """The ground plane drawn on Qt's own OpenGL context, straight to the screen.

    Signals
    -------
    drawn(float)
        Milliseconds the last frame took (with ``glFinish``).
    failed(str)
        The context or the drawing failed (one line).
    """

    drawn = Signal(float)
    failed = Signal(str)

    def __init__(self, scene: Scene, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setFormat(surface_format())
        self.setMinimumSize(320, 180)
        self.scene = scene
        self.ground: GroundView | None = None
        self.ctx = None
        #: True while frames may be drawn at MOVING_SCALE (the tab sets it to its driver's)
        self.moving: Callable[[], bool] = lambda: False
        self._stale = True
        self._heights: tuple[np.ndarray | None, float] | None = None

    def initializeGL(self) -> None:
        try:
            self.ctx = moderngl.create_context(require=330)
        except Exception as exc:  # moderngl raises plain Exception without a context
            self.failed.emit(f"no OpenGL 3.3 context: {str(exc).splitlines()[0]}")

    def rebuild(self) -> None:
        """Build the ground again at the next frame (themes or grid replaced)."""
        self._stale = True
        self.update()

    def mark_dirty(self, rows: slice, cols: slice) -> None:
        if self.ground is not None:
            self.ground.mark_dirty(rows, cols)
        self.update()

    def set_height_map(self, heights: np.ndarray | None, scale: float) -> None:
        self._heights = (heights, scale)
        self.update()

    def request_frame(self) -> None:
        self.update()

    def paintGL(self) -> None:
        if self.ctx is None:
            return
        try:
            t0 = time.perf_counter()
            if self._stale or self.ground is None:
                if self.ground is not None:
                    self.ground.release()
                self.ground = self.scene.make_ground(self.ctx)
                self._stale = False
                if self._heights is None and self.scene.heights is not None:
                    self._heights = self.scene.heights
            if self._heights is not None:
                self.ground.set_height_map(*self._heights)
                self._heights = None
            ratio = self.devicePixelRatioF()
            size = (max(1, round(self.width() * ratio)), max(1, round(self.height() * ratio)))
            fbo = self.ctx.detect_framebuffer(self.defaultFramebufferObject())
            self.ctx.scissor = None
            scale = MOVING_SCALE if self.moving() else 1.0
            self.ground.draw(self.scene.camera(), size, framebuffer=fbo, flip_y=True,
                             scale=scale)
            self.ctx.finish()
            self.drawn.emit(1e3 * (time.perf_counter() - t0))
        except Exception as exc:  # shown in the tab, never a crash
            self.failed.emit(str(exc) or type(exc).__name__)

    def release(self) -> None:
        if self.ground is not None and self.ctx is not None:
            self.makeCurrent()
            self.ground.release()
            self.doneCurrent()
        self.ground = None


class FlyoverImage(QWidget):
    """The ground plane drawn headless (EGL) and shown as an image, where Qt has no OpenGL.

    Frames are drawn at most :attr:`max_width` pixels wide (scaled to the widget).
    Signals as :class:`FlyoverGL`.
    """

    drawn = Signal(float)
    failed = Signal(str)
    max_width = 960

    def __init__(self, scene: Scene, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setMinimumSize(320, 180)
        self.scene = scene
        self.ground: GroundView | None = None
        self.frame: np.ndarray | None = None
        self.moving: Callable[[], bool] = lambda: False
        self._hidden_request = False
        self._timer = QTimer(self, singleShot=True, interval=0)
        self._timer.timeout.connect(self.draw_now)

    def rebuild(self) -> None:
        if self.ground is not None:
            self.ground.release()
        self.ground = None
        self.request_frame()

    def mark_dirty(self, rows: slice, cols: slice) -> None:
        if self.ground is not None:
            self.ground.mark_dirty(rows, cols)
        self.request_frame()

    def set_height_map(self, heights: np.ndarray | None, scale: float) -> None:
        try:
            self._ensure().set_height_map(heights, scale)
        except Exception as exc:  # shown in the tab, never a crash
            self.failed.emit(str(exc) or type(exc).__name__)
        self.request_frame()

    def request_frame(self) -> None:
        """Draw soon (requests arriving together give one frame)."""
        self._timer.start()

    def _ensure(self) -> GroundView:
        if self.ground is None:
            from terratheme.core.gpu import gl_context

            self.ground = self.scene.make_ground(gl_context())
            if self.scene.heights is not None:
                self.ground.set_height_map(*self.scene.heights)
        return self.ground

    def frame_size(self) -> tuple[int, int]:
        """The frame drawn: the widget's size, capped, smaller while the camera moves."""
        w, h = max(1, self.width()), max(1, self.height())
        s = min(1.0, self.max_width / w) * (MOVING_SCALE if self.moving() else 1.0)
        return max(1, round(w * s)), max(1, round(h * s))

    def draw_now(self) -> None:
        """Draw a frame at the widget's size (capped) and show it (once visible)."""
        if not self.isVisible():
            self._hidden_request = True
            return
        self._hidden_request = False
        try:
            t0 = time.perf_counter()
            self.frame = self._ensure().render(self.scene.camera(), self.frame_size())
            self.drawn.emit(1e3 * (time.perf_counter() - t0))
        except Exception as exc:  # shown in the tab, never a crash
            self.failed.emit(str(exc) or type(exc).__name__)
        self.update()

    def paintEvent(self, event) -> None:
        painter = QPainter(self)
        painter.fillRect(self.rect(), Qt.GlobalColor.black)
        if self.frame is not None:
            painter.setRenderHint(QPainter.RenderHint.SmoothPixmapTransform)
            painter.drawImage(self.rect(), qimage_view(self.frame))
        painter.end()

    def resizeEvent(self, event) -> None:
        super().resizeEvent(event)
        self.request_frame()

    def showEvent(self, event) -> None:
        super().showEvent(event)
        if self._hidden_request or self.frame is None:
            self.request_frame()

    def release(self) -> None:
        if self.ground is not None:
            self.ground.release()
        self.ground = None
