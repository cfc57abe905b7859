"""The PySide6 editor (pytest-qt, offscreen): model/view sync, undo, files, dialogs."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("PySide6")
pytest.importorskip("pytestqt")

from PySide6.QtCore import QPoint, QPointF, Qt
from terratheme.core.model.project import save_project
from terratheme.core.render.renderer import render_cells
from terratheme.core.themes.library import Theme

pytestmark = pytest.mark.qt


def halves_photo() -> np.ndarray:
    """(64, 96, 3) uint8: green left half, blue right half (fits the ``small_texture`` grid)."""
    photo = np.zeros((64, 96, 3), dtype=np.uint8)
    photo[:, :48] = (30, 140, 40)
    photo[:, 48:] = (40, 60, 200)
    return photo


@pytest.fixture
def window(open_window, small_texture):
    from terratheme.app.editor.document import EditorDocument

    return open_window(EditorDocument(small_texture(photo=halves_photo())))


def screen_of(canvas, texel: QPointF) -> QPoint:
    s, o = canvas.view.scale, canvas.view.origin
    return QPoint(round((texel.x() - o.x()) * s), round((texel.y() - o.y()) * s))


def test_mouse_stroke_edits_model_render_and_is_one_undo_step(window, qtbot):
    doc = window.doc
    canvas = window.index_canvas
    window.palette_widget.select(1)
    window.size_box.setValue(1)  # radius 0.5: exactly the vertices nearest the path
    # Drag along vertex row 4 from vertex column 2 to 6 (texel = vertex * 8).
    qtbot.mousePress(canvas, Qt.MouseButton.LeftButton, pos=screen_of(canvas, QPointF(16, 32)))
    for x in (24, 32, 40, 48):
        qtbot.mouseMove(canvas, screen_of(canvas, QPointF(x, 32)))
    qtbot.mouseRelease(canvas, Qt.MouseButton.LeftButton, pos=screen_of(canvas, QPointF(48, 32)))
    expected = np.zeros((9, 13), dtype=np.uint8)
    expected[4, 2:7] = 1
    np.testing.assert_array_equal(doc.texture.grid.indices, expected)
    # The view's images follow the model: index colours and the live render.
    np.testing.assert_array_equal(doc.index_rgb[4, 3], doc.texture.library[1].colour)
    fresh = render_cells(doc.texture.grid.indices, doc.texture.library.textures, (8, 8))
    np.testing.assert_array_equal(doc.preview.image, fresh)
    assert len(doc.model.history.undo_steps) == 1
    doc.model.undo()
    assert not doc.texture.grid.indices.any()
    np.testing.assert_array_equal(doc.index_rgb[4, 3], doc.texture.library[0].colour)
    fresh0 = render_cells(doc.texture.grid.indices, doc.texture.library.textures, (8, 8))
    np.testing.assert_array_equal(doc.preview.image, fresh0)
    doc.model.redo()
    np.testing.assert_array_equal(doc.texture.grid.indices, expected)
    np.testing.assert_array_equal(doc.preview.image, fresh)


def test_tools_by_shortcut_fill_and_eyedropper(window, qtbot):
    doc = window.doc
    canvas = window.index_canvas
    canvas.setFocus()
    qtbot.keyClick(window, Qt.Key.Key_3)  # theme 3 (sand)
    qtbot.keyClick(window, Qt.Key.Key_R)
    qtbot.mousePress(canvas, Qt.MouseButton.LeftButton, pos=screen_of(canvas, QPointF(0, 0)))
    qtbot.mouseMove(canvas, screen_of(canvas, QPointF(16, 8)))
    qtbot.mouseRelease(canvas, Qt.MouseButton.LeftButton, pos=screen_of(canvas, QPointF(16, 8)))
    assert (doc.texture.grid.indices[:2, :3] == 2).all()
    assert int((doc.texture.grid.indices == 2).sum()) == 6
    # Flood fill the remaining zeros with water: the sand rectangle stays.
    qtbot.keyClick(window, Qt.Key.Key_2)
    qtbot.keyClick(window, Qt.Key.Key_F)
    qtbot.mouseClick(canvas, Qt.MouseButton.LeftButton, pos=screen_of(canvas, QPointF(80, 60)))
    assert int((doc.texture.grid.indices == 1).sum()) == 9 * 13 - 6
    # Eyedropper picks sand back into the palette.
    qtbot.keyClick(window, Qt.Key.Key_I)
    qtbot.mouseClick(canvas, Qt.MouseButton.LeftButton, pos=screen_of(canvas, QPointF(8, 0)))
    assert window.palette_widget.current == 2 and window.tools.theme == 2
    # Ctrl+Z twice undoes both fills.
    qtbot.keyClick(window, Qt.Key.Key_Z, Qt.KeyboardModifier.ControlModifier)
    qtbot.keyClick(window, Qt.Key.Key_Z, Qt.KeyboardModifier.ControlModifier)
    assert not doc.texture.grid.indices.any()
    qtbot.keyClick(window, Qt.Key.Key_Z,
                   Qt.KeyboardModifier.ControlModifier | Qt.KeyboardModifier.ShiftModifier)
    assert int((doc.texture.grid.indices == 2).sum()) == 6


def test_theme_rename_and_recolour_are_undoable(window):
    doc = window.doc
    old = doc.texture.library[1]
    doc.model.replace_theme(1, old.with_(name="lake", colour=(0, 0, 255)), "rename")
    assert doc.texture.library[1].name == "lake"
    assert window.palette_widget.list.item(1).text().endswith("lake")
    doc.model.undo()
    assert doc.texture.library[1] == old
    from terratheme.core.errors import TerrathemeError

    with pytest.raises(TerrathemeError, match="already in the library"):
        doc.model.replace_theme(1, old.with_(name="Grass"), "rename")


def test_adding_a_theme_is_undoable(window):
    doc = window.doc
    before = list(doc.texture.library)
    tex = np.full((4, 4, 3), 7, np.uint8)
    k = doc.model.add_theme(Theme("snow", (250, 250, 250), tex))
    assert k == 3 and doc.texture.library[3].name == "snow"
    assert window.palette_widget.list.count() == 4
    doc.model.undo()
    assert list(doc.texture.library) == before
    assert window.palette_widget.list.count() == 3
    doc.model.redo()
    assert doc.texture.library.names == ["grass", "water", "sand", "snow"]
    from terratheme.core.errors import TerrathemeError

    with pytest.raises(TerrathemeError, match="already in the library"):
        doc.model.add_theme(Theme("Snow", (1, 1, 1), tex))
    assert len(doc.model.history.undo_steps) == 1


def test_save_open_round_trip(window, tmp_path):
    doc = window.doc
    doc.model.fill_rect((1, 1), (4, 3), 2)
    path = tmp_path / "edited.ttproj"
    assert window._save_to(path)
    assert doc.clean
    before = doc.texture
    window.new_project()
    assert window.doc is not doc
    assert window.open_path(path)
    assert window.doc.texture == before
    assert window.doc.path == path
    assert window.windowTitle().startswith("edited.ttproj")


def test_damaged_project_shows_an_error_dialog(window, small_texture, tmp_path):
    bad = tmp_path / "bad.ttproj"
    save_project(bad, small_texture())
    data = bytearray(bad.read_bytes())
    data[len(data) // 2 : len(data) // 2 + 64] = b"\0" * 64
    bad.write_bytes(bytes(data))
    doc = window.doc
    assert not window.open_path(bad)
    assert window.doc is doc
    assert len(window.errors) == 1 and "bad.ttproj" in window.errors[0]
    assert not window.open_path(tmp_path / "missing.ttproj")
    assert "no such project file" in window.errors[1]


def test_export_render_writes_the_preview(window, tmp_path):
    from terratheme.core.io.images import read_image

    out = tmp_path / "render.png"
    assert window.export_render(str(out))
    np.testing.assert_array_equal(read_image(out), window.doc.preview.image)


def test_fidelity_view_marks_the_cells_that_differ(window):
    doc = window.doc
    # The photo is green on the left half, blue on the right; paint water on the right.
    doc.model.fill_rect((6, 0), (12, 8), 1)
    fid = doc.fidelity()
    assert fid.shape == (8, 12)
    window.fidelity_action.trigger()
    assert window.show_fidelity
    window.index_canvas.repaint()
    grab = window.index_canvas.grab()
    assert not grab.isNull()


def test_classification_from_the_menu_fills_the_grid(window, qtbot):
    from terratheme.core.edit.classification import ClassifyMode as Mode

    doc = window.doc
    job = window.start_classification(Mode.UNSUPERVISED_NEW)
    assert job is not None and window.progress.isVisible()
    qtbot.waitUntil(lambda: window.job is None, timeout=60000)
    ind = doc.texture.grid.indices
    # Two photo halves -> two new themes, left and right of the grid differ.
    assert len(doc.texture.library) >= 5
    assert ind[:, 1].min() == ind[:, 1].max() and ind[:, -2].min() == ind[:, -2].max()
    assert ind[0, 1] != ind[0, -2]
    assert len(doc.model.history.undo_steps) == 1
    doc.model.undo()
    assert not doc.texture.grid.indices.any()
    # One undo step takes back the grid and the themes the classification added.
    assert doc.texture.library.names == ["grass", "water", "sand"]
    doc.model.redo()
    redone = doc.texture.grid.indices
    assert len(doc.texture.library) >= 5 and redone[0, 1] != redone[0, -2]


def test_classification_can_be_cancelled(window, qtbot):
    from terratheme.core.edit.classification import ClassifyMode as Mode

    doc = window.doc
    n_themes = len(doc.texture.library)
    job = window.start_classification(Mode.UNSUPERVISED_MAP)
    window.cancel_action.trigger()
    assert window.job is None and not window.progress.isVisible()
    qtbot.waitUntil(job.isFinished, timeout=60000)
    qtbot.wait(50)
    assert not doc.texture.grid.indices.any()
    assert len(doc.texture.library) == n_themes and len(doc.model.history.undo_steps) == 0


def test_classification_without_photo_or_scribbles_reports(window, small_texture, qtbot):
    from terratheme.app.editor.document import EditorDocument
    from terratheme.core.edit.classification import ClassifyMode as Mode

    job = window.start_classification(Mode.SCRIBBLES)
    qtbot.waitUntil(lambda: window.job is None, timeout=60000)
    assert job is not None and "no scribbles" in window.errors[-1]
    window.set_document(EditorDocument(small_texture()))
    assert window.start_classification(Mode.UNSUPERVISED_MAP) is None
    assert "needs a photo" in window.errors[-1]


def test_screenshot_command_writes_a_png(small_texture, tmp_path, monkeypatch):
    from terratheme.app.cli import main
    from terratheme.core.io.images import read_image

    project = tmp_path / "p.ttproj"
    save_project(project, small_texture(photo=halves_photo()))
    out = tmp_path / "shot.png"
    assert main(["app", str(project), "--screenshot", str(out), "--size", "640x400"]) == 0
    img = read_image(out)
    assert img.shape[0] >= 400 and img.shape[1] >= 640  # the size asked, or the minimum
    assert img.std() > 5  # not a blank image


def test_perspective_tab_renders_a_frame_off_the_gui_thread(window, qtbot):
    tab = window.perspective_tab
    # Bilinear first: the parallelogram filter's first frame compiles numba kernels (~15 s).
    tab.method_box.setCurrentIndex(tab.method_box.findText("bilinear"))
    window.tabs.setCurrentWidget(tab)
    qtbot.waitUntil(lambda: tab._frame is not None, timeout=60000)
    frame = tab._frame
    assert frame.shape == (360, 640, 3) and frame.dtype == np.uint8
    # Low pitch: sky colour at the top, the textured plane at the bottom.
    sky = np.round(np.array([0.62, 0.74, 0.88]) * 255)  # FilterOptions' default sky
    assert np.abs(frame[0] - sky).max() <= 1 and frame[-1].std(axis=0).max() > 2
    first = frame
    tab.method_box.setCurrentIndex(tab.method_box.findText("nearest"))
    qtbot.waitUntil(lambda: tab._frame is not first, timeout=60000)
    tab.wait()


def drag(qtbot, canvas, points):
    qtbot.mousePress(canvas, Qt.MouseButton.LeftButton, pos=screen_of(canvas, points[0]))
    for p in points[1:]:
        qtbot.mouseMove(canvas, screen_of(canvas, p))
    qtbot.mouseRelease(canvas, Qt.MouseButton.LeftButton, pos=screen_of(canvas, points[-1]))


def test_scribbles_train_a_classifier_from_the_menu(window, qtbot):
    from terratheme.app.editor.tools import Tool
    from terratheme.core.edit.classification import ClassifyMode as Mode

    doc = window.doc
    canvas = window.index_canvas
    window.set_tool(Tool.SCRIBBLE)
    window.palette_widget.select(2)  # sand on the green half
    drag(qtbot, canvas, [QPointF(8, 10), QPointF(30, 50)])
    window.palette_widget.select(1)  # water on the blue half
    drag(qtbot, canvas, [QPointF(60, 10), QPointF(85, 50)])
    sc = doc.texture.scribbles
    assert set(np.unique(sc)) == {0, 2, 3}
    # Scribble value = theme + 1: sand (3) only on the left, water (2) only on the right.
    assert set(np.unique(sc[:, :48])) == {0, 3} and set(np.unique(sc[:, 48:])) == {0, 2}
    assert len(doc.model.history.undo_steps) == 2
    # The overlay, updated block by block while painting, shows the whole layer.
    np.testing.assert_array_equal(window.scribble_pyramid.base, doc.scribble_rgba())
    doc.model.undo()
    assert set(np.unique(doc.texture.scribbles)) == {0, 3}
    np.testing.assert_array_equal(window.scribble_pyramid.base, doc.scribble_rgba())
    doc.model.redo()
    window.start_classification(Mode.SCRIBBLES)
    qtbot.waitUntil(lambda: window.job is None, timeout=60000)
    ind = doc.texture.grid.indices
    assert (ind[:, :5] == 2).all() and (ind[:, 8:] == 1).all()


def test_new_project_over_a_photo_gets_the_classes_as_themes(qtbot, tmp_path, monkeypatch):
    from terratheme.app.editor.launch import load_start_document
    from terratheme.app.editor.window import MainWindow
    from terratheme.core.edit.classification import ClassifyMode as Mode
    from terratheme.core.io.images import write_image

    photo = np.zeros((64, 96, 3), dtype=np.uint8)
    photo[:, :48] = (30, 140, 40)
    photo[:, 48:] = (40, 60, 200)
    path = tmp_path / "photo.png"
    write_image(path, photo)
    doc, wants = load_start_document(str(path), classify=True)
    assert wants and doc.fresh_from_photo and doc.texture.grid.indices.shape == (5, 7)
    win = MainWindow(doc)
    qtbot.addWidget(win)
    win.start_classification(Mode.UNSUPERVISED_NEW)
    qtbot.waitUntil(lambda: win.job is None, timeout=60000)
    lib = win.doc.texture.library
    assert len(lib) == 2 and not doc.fresh_from_photo
    # The classes replace the start themes, so their names need no marks to differ from them.
    assert lib.names == [n.rstrip("'") for n in lib.names], lib.names
    ind = win.doc.texture.grid.indices
    assert ind[0, 0] != ind[0, -1]
    # One undo step takes the classes back to the shipped themes and the one-theme grid.
    assert win.undo_action.isEnabled() and win.undo_action.text() == "&Undo classification"
    win.undo_action.trigger()
    assert len(win.doc.texture.library) > 2 and not win.doc.texture.grid.indices.any()
    assert win.doc.model.confidence is None
    win.wait_for_jobs()


def test_export_packed_index_layer_round_trips(window, tmp_path):
    from terratheme.core.packing.layer import PackedLayer

    doc = window.doc
    doc.model.fill_rect((2, 1), (7, 5), 2)
    out = tmp_path / "index.sfc"
    assert window.export_packed(str(out)), window.errors
    np.testing.assert_array_equal(PackedLayer.load(out).unpack(), doc.texture.grid.indices)


@pytest.mark.parametrize("export", ["export_render", "export_packed"])
def test_an_export_that_cannot_be_written_shows_one_error(window, tmp_path, export):
    out = tmp_path / "no such folder" / "out.png"
    assert not getattr(window, export)(str(out))
    assert len(window.errors) == 1 and window.errors[0].startswith(f"Cannot export {out}:")
    assert not out.exists()


def test_app_command_reports_a_damaged_project_in_one_line(tmp_path, capsys):
    from terratheme.app.cli import main

    bad = tmp_path / "bad.ttproj"
    bad.write_bytes(b"not a zip at all")
    assert main(["app", str(bad), "--screenshot", str(tmp_path / "s.png")]) == 2
    err = capsys.readouterr().err
    assert "bad.ttproj" in err and "damaged" in err and "Traceback" not in err
    assert not (tmp_path / "s.png").exists()


def test_palette_adds_a_theme_and_assigns_a_texture_file(window, tmp_path, monkeypatch):
    from PySide6.QtWidgets import QFileDialog, QInputDialog
    from terratheme.core.io.images import write_image

    tex = np.zeros((16, 16, 3), dtype=np.uint8)
    tex[..., 0] = 200
    path = tmp_path / "red.png"
    write_image(path, tex)
    monkeypatch.setattr(QFileDialog, "getOpenFileName", lambda *a, **k: (str(path), ""))
    monkeypatch.setattr(QInputDialog, "getText", lambda *a, **k: ("brick", True))
    pal = window.palette_widget
    pal.add()
    lib = window.doc.texture.library
    assert lib.names[-1] == "brick" and lib[-1].colour == (200, 0, 0)
    assert pal.list.count() == 4 and pal.current == 3
    # Assign the file to theme 0 (undoable); the render follows.
    doc = window.doc
    pal.select(0)
    pal.assign_texture()
    np.testing.assert_array_equal(lib[0].texture, tex)
    assert (doc.preview.image[..., 0] == 200).all() and not doc.preview.image[..., 1:].any()
    doc.model.undo()
    assert not np.array_equal(lib[0].texture, tex)
    fresh = render_cells(doc.texture.grid.indices, lib.textures, (8, 8))
    np.testing.assert_array_equal(doc.preview.image, fresh)




def test_both_views_show_the_whole_map_when_the_window_opens(small_texture, qtbot):
    from terratheme.app.editor.document import EditorDocument
    from terratheme.app.editor.window import MainWindow

    win = MainWindow(EditorDocument(small_texture(photo=halves_photo())))
    qtbot.addWidget(win)
    win.resize(1100, 700)
    win.show()
    qtbot.waitExposed(win)
    w, h = win.doc.extent
    for canvas in (win.index_canvas, win.render_canvas):
        # no fit() called here: the window fits its views once it is laid out
        qtbot.waitUntil(lambda c=canvas: screen_of(c, QPointF(w, h)).x() <= c.width(),
                        timeout=5000)
        top_left, bottom_right = screen_of(canvas, QPointF(0, 0)), screen_of(canvas, QPointF(w, h))
        assert 0 <= top_left.x() and bottom_right.x() <= canvas.width()
        assert 0 <= top_left.y() and bottom_right.y() <= canvas.height()
    win.wait_for_jobs()


def test_palette_shows_a_detail_theme_in_the_colour_the_map_gives_it(open_window):
    from PySide6.QtCore import QSize
    from terratheme.app.editor.document import EditorDocument
    from terratheme.app.editor.palette import THUMB
    from terratheme.core.model.colour_map import ColourMap
    from terratheme.core.model.grid import IndexGrid
    from terratheme.core.model.project import ThematicTexture
    from terratheme.core.themes.library import ThemeLibrary

    grey = np.full((8, 8, 3), 128, np.uint8)  # a detail theme with no fine contrast
    lib = ThemeLibrary([Theme("sand", (200, 180, 120), grey), Theme("water", (40, 80, 170), grey)])
    grid = IndexGrid(np.zeros((9, 13), np.uint8), (8, 8))  # every vertex sand
    pixels = np.empty((*ColourMap.shape_for(grid.texture_size, 4), 3), np.uint8)
    pixels[...] = (200, 100, 50)
    window = open_window(EditorDocument(ThematicTexture(grid, lib, {},
                                                        colour_map=ColourMap(pixels, 4))))

    def swatch(row):
        icon = window.palette_widget.list.item(row).icon()
        image = icon.pixmap(QSize(THUMB + 10, THUMB)).toImage()
        c = image.pixelColor(10 + THUMB // 2, THUMB // 2)
        return c.red(), c.green(), c.blue()

    # Sand: grey 128 under a stored gain of (200, 100, 50) / 128 renders as that colour.
    assert swatch(0) == pytest.approx((200, 100, 50), abs=2)
    # Water has no vertex, so no gain: its texture as it is.
    assert swatch(1) == pytest.approx((128, 128, 128), abs=2)
