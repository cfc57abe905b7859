"""The Perspective tab's fly-over (pytest-qt, offscreen): flying, live edits, height maps, CPU view.

Qt's offscreen platform makes no OpenGL context, so there the tab draws the
fly-over headless with EGL (``FlyoverImage``); the ``QOpenGLWidget`` path is
tested where Qt has a context and skipped with the reason elsewhere. Tests
that draw skip when no OpenGL 3.3 context can be made at all.
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("PySide6")
pytest.importorskip("pytestqt")

from PySide6.QtCore import QPoint, Qt
from terratheme.core.gpu import GpuUnavailableError, GroundView, gl_context
from terratheme.core.io.images import write_image
from terratheme.core.model.colour_map import ColourMap
from terratheme.core.model.grid import IndexGrid
from terratheme.core.model.project import ThematicTexture
from terratheme.core.perspective import FilterOptions, Method, PreparedTexture
from terratheme.core.perspective.flight import Flight
from terratheme.core.render.project import render_project
from terratheme.core.themes.library import Theme, ThemeLibrary

pytestmark = pytest.mark.qt


def styled_texture() -> ThematicTexture:
    """A small project with shaped borders and a colour map (a converted photo's style)."""
    rng = np.random.default_rng(8)
    lib = ThemeLibrary(
        Theme(name, colour, rng.integers(0, 256, (16, 16, 3), dtype=np.uint8))
        for name, colour in (("grass", (90, 160, 60)), ("water", (40, 80, 170)),
                             ("sand", (210, 190, 120))))
    coarse = rng.integers(0, 3, (9, 11))
    grid = np.kron(coarse, np.ones((2, 2), int))[:17, :21].astype(np.uint8)
    cmap = ColourMap(rng.integers(90, 170, (16, 20, 3), dtype=np.uint8), 8)
    return ThematicTexture(IndexGrid(grid, (8, 8)), lib, colour_map=cmap,
                           metadata={"render": {"boundary": {"width": 2.0}}})


def shown_tab(qtbot):
    """A Perspective tab on :func:`styled_texture`, shown offscreen at 700 x 360."""
    from terratheme.app.editor.document import EditorDocument
    from terratheme.app.editor.perspective_tab import PerspectiveTab

    widget = PerspectiveTab()
    qtbot.addWidget(widget)
    widget.set_document(EditorDocument(styled_texture()))
    widget.resize(700, 360)
    widget.show()
    qtbot.waitExposed(widget)
    return widget


@pytest.fixture
def tab(qtbot):
    widget = shown_tab(qtbot)
    yield widget
    widget.wait()


def _needs_gpu(tab) -> None:
    if tab.driver is None:
        pytest.skip(f"no OpenGL 3.3 context: {tab.gpu_info.text()}")


def _frame(tab, qtbot) -> np.ndarray:
    """The fly-over's current frame as (h, w, 3) uint8, row 0 at the top."""
    from terratheme.app.editor.flyover import FlyoverImage

    view = tab.view
    if isinstance(view, FlyoverImage):
        view.frame = None
        view.request_frame()
        qtbot.waitUntil(lambda: view.frame is not None, timeout=60000)
        return view.frame
    image = view.grabFramebuffer().convertToFormat(view.grabFramebuffer().Format.Format_RGB888)
    arr = np.frombuffer(image.constBits(), np.uint8).reshape(image.height(),
                                                             image.bytesPerLine())
    return arr[:, : 3 * image.width()].reshape(image.height(), image.width(), 3).copy()


def _fresh(tab, size) -> np.ndarray:
    """The same camera drawn by a new GroundView of the document as it is now."""
    texture = tab.doc.texture
    project = ThematicTexture(IndexGrid(texture.grid.indices.copy(), texture.grid.cell),
                              texture.library, metadata=texture.metadata,
                              colour_map=texture.colour_map)
    ground = GroundView.from_project(project)
    try:
        return ground.render(tab.camera(), size)
    finally:
        ground.release()


def test_the_fly_over_draws_the_project_in_its_style(tab, qtbot):
    _needs_gpu(tab)
    frame = _frame(tab, qtbot)
    assert frame.shape[0] > 100 and frame.std() > 5
    want = _fresh(tab, (frame.shape[1], frame.shape[0]))
    assert np.abs(frame.astype(np.int16) - want).mean() < 1.0
    assert "GPU fly-over" in tab.gpu_info.text() and "anisotropic" in tab.gpu_info.text()


def test_keys_mouse_and_wheel_fly_the_camera(tab, qtbot):
    _needs_gpu(tab)
    view, driver = tab.view, tab.driver
    start = tab.flight
    qtbot.keyPress(view, Qt.Key.Key_W)
    assert driver.timer.isActive() and driver.moving and view.moving()
    driver.tick(0.5)  # half a second of W: half a camera height along the heading
    qtbot.keyRelease(view, Qt.Key.Key_W)
    want = start.moved(0.5 * start.height, 0.0)
    assert (tab.flight.x, tab.flight.y) == pytest.approx((want.x, want.y))
    driver.tick(0.1)
    assert not driver.timer.isActive() and not view.moving()  # nothing held: it stops
    qtbot.keyPress(view, Qt.Key.Key_Right)
    driver.tick(0.5)
    qtbot.keyRelease(view, Qt.Key.Key_Right)
    assert tab.flight.yaw == pytest.approx(start.yaw + 30.0)
    assert tab.yaw_box.value() == pytest.approx(tab.flight.yaw)
    # Drag 40 pixels down: pitch 10 degrees further down; the wheel brings the camera lower.
    pitch = tab.flight.pitch
    qtbot.mousePress(view, Qt.MouseButton.LeftButton, pos=QPoint(100, 100))
    qtbot.mouseMove(view, QPoint(100, 140))
    qtbot.mouseRelease(view, Qt.MouseButton.LeftButton, pos=QPoint(100, 140))
    assert tab.flight.pitch == pytest.approx(pitch + 10.0)
    height = tab.flight.height
    tab.height_box.setValue(2 * height)  # the boxes fly the camera too
    assert tab.flight.height == pytest.approx(2 * height)
    assert tab.flight.pitch == pytest.approx(pitch + 10.0)


def test_a_short_tap_moves_the_camera(tab, qtbot):
    _needs_gpu(tab)
    view, start = tab.view, tab.flight
    qtbot.keyPress(view, Qt.Key.Key_W)
    qtbot.keyRelease(view, Qt.Key.Key_W)  # released before the first tick
    moved = np.hypot(tab.flight.x - start.x, tab.flight.y - start.y)
    # at least one tick (16 ms) of W: a sixtieth of the camera height or more
    assert moved >= 0.016 * start.height * 0.99
    assert not tab.driver.held


def test_c_switches_to_the_cpu_frame_and_back(tab, qtbot):
    _needs_gpu(tab)
    window = tab.window()
    window.activateWindow()
    qtbot.waitUntil(lambda: window.isActiveWindow(), timeout=5000)
    tab.view.setFocus()
    qtbot.keyClick(tab.view, Qt.Key.Key_C)
    assert tab.compare.isChecked() and tab.stack.currentWidget() is tab.image
    qtbot.keyClick(tab.image, Qt.Key.Key_C)
    assert not tab.compare.isChecked() and tab.stack.currentWidget() is tab.view


def test_a_brush_stroke_reuploads_only_its_cells(tab, qtbot):
    _needs_gpu(tab)
    tab.set_flight(Flight(80.0, 90.0, 40.0, yaw=0.0, pitch=60.0))
    _frame(tab, qtbot)
    ground = tab.view.ground
    model = tab.doc.model
    model.begin_stroke(1, (10.0, 8.0), 1.0)
    model.stroke_to((12.0, 8.0), 1.0)
    model.end_stroke()
    frame = _frame(tab, qtbot)
    assert tab.view.ground is ground  # edited in place, not rebuilt
    cells = sum(w * h for _, _, w, h in ground.uploaded)
    assert 0 < cells <= 10 * 8 and ground.uploaded[0][0] >= 6
    assert np.array_equal(frame, _fresh(tab, (frame.shape[1], frame.shape[0])))
    # A whole new grid is painted in place too: every cell is re-split.
    model.replace_grid(np.zeros_like(model.indices))
    frame = _frame(tab, qtbot)
    assert tab.view.ground is ground and ground.uploaded == [(0, 0, 20, 16)]
    assert np.array_equal(frame, _fresh(tab, (frame.shape[1], frame.shape[0])))
    # A theme's texture replaced: the ground is built again with the new themes.
    texture = np.full((16, 16, 3), (200, 30, 30), np.uint8)
    model.replace_theme(0, Theme("red", (200, 30, 30), texture))
    frame = _frame(tab, qtbot)
    assert tab.view.ground is not ground
    assert np.array_equal(frame, _fresh(tab, (frame.shape[1], frame.shape[0])))


def test_the_cpu_filter_is_one_click_away_on_the_same_camera(tab, qtbot):
    tab.method_box.setCurrentIndex(tab.method_box.findText("bilinear"))
    assert tab.compare.isChecked() and tab.stack.currentWidget() is tab.image
    qtbot.waitUntil(lambda: tab._frame is not None, timeout=60000)
    texture = render_project(tab.doc.texture)
    want = PreparedTexture(texture, FilterOptions(method=Method.BILINEAR)).render(
        tab.camera(), (640, 360)).image
    want = np.clip(want * 255 + 0.5, 0, 255).astype(np.uint8)
    assert np.array_equal(tab._frame, want)
    if tab.driver is not None:
        tab.compare.click()
        assert tab.stack.currentWidget() is tab.view


def test_a_height_map_displaces_the_ground(tab, qtbot, tmp_path):
    _needs_gpu(tab)
    tab.set_flight(Flight(80.0, 64.0, 60.0, yaw=10.0, pitch=40.0))
    flat = _frame(tab, qtbot)
    ramp = np.tile(np.linspace(0, 255, 32).astype(np.uint8), (24, 1))
    write_image(tmp_path / "h.png", ramp)
    tab.height_scale_box.setValue(30.0)
    tab.load_height_map(str(tmp_path / "h.png"))
    raised = _frame(tab, qtbot)
    heights = tab.view.ground.heights
    assert heights is not None and heights.scale == 30.0
    assert np.abs(raised.astype(np.int16) - flat).mean() > 3
    assert tab.ground_height(160.0, 64.0) == pytest.approx(30.0)
    tab.height_scale_box.setValue(10.0)
    _frame(tab, qtbot)
    assert tab.view.ground.heights.scale == 10.0
    tab.set_height_map(None)
    assert np.array_equal(_frame(tab, qtbot), flat)
    (tmp_path / "bad.png").write_bytes(b"not an image")
    tab.load_height_map(str(tmp_path / "bad.png"))
    assert "bad.png" in tab.gpu_info.text()


def test_without_opengl_the_tab_says_so_and_keeps_the_cpu_filters(qtbot, monkeypatch):
    import terratheme.app.editor.perspective_tab as perspective_tab
    from terratheme.app.editor.document import EditorDocument

    def no_egl():
        raise GpuUnavailableError("GPU rendering unavailable: no EGL (test)")

    monkeypatch.setattr(perspective_tab, "_QT_GL", ["Qt's test platform makes no OpenGL context"])
    monkeypatch.setattr("terratheme.core.gpu.gl_context", no_egl)
    widget = perspective_tab.PerspectiveTab()
    qtbot.addWidget(widget)
    widget.set_document(EditorDocument(styled_texture()))
    widget.show()
    assert widget.driver is None
    assert "No fly-over" in widget.gpu_info.text() and "no EGL" in widget.gpu_info.text()
    assert widget.compare.isChecked()
    qtbot.waitUntil(lambda: widget._frame is not None, timeout=60000)
    widget.wait()


def test_qt_opengl_widget_draws_where_qt_has_a_context(qtbot):
    from terratheme.app.editor.flyover import FlyoverGL, qt_gl_unavailable

    reason = qt_gl_unavailable()
    if reason is not None:
        pytest.skip(f"{reason} (the fly-over draws headless with EGL there)")
    try:
        gl_context()
    except GpuUnavailableError as exc:
        pytest.skip(str(exc))
    widget = shown_tab(qtbot)
    assert isinstance(widget.view, FlyoverGL)
    frame = _frame(widget, qtbot)
    want = _fresh(widget, (frame.shape[1], frame.shape[0]))
    assert np.abs(frame.astype(np.int16) - want).mean() < 2.0
