"""The Qt editor bound to the core document (pytest-qt, offscreen): undo menu, odd layers, Help."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("PySide6")
pytest.importorskip("pytestqt")

from PySide6.QtCore import QPoint, QPointF, Qt
from terratheme.core.model.project import ThematicTexture, save_project

pytestmark = pytest.mark.qt


def screen_of(canvas, texel: QPointF) -> QPoint:
    s, o = canvas.view.scale, canvas.view.origin
    return QPoint(round((texel.x() - o.x()) * s), round((texel.y() - o.y()) * s))


@pytest.fixture
def texture(small_texture) -> ThematicTexture:
    """Two themes (grass, water) over a 9 x 13 grid of theme 0."""
    return small_texture(themes=2, seed=2)


@pytest.fixture
def window(open_window, small_texture):
    from terratheme.app.editor.document import EditorDocument

    texture = small_texture(themes=2, seed=2, photo=np.zeros((64, 96, 3), np.uint8))
    return open_window(EditorDocument(texture))


def test_edit_menu_and_title_follow_the_core_history(window, qtbot, tmp_path):
    doc = window.doc
    assert not window.undo_action.isEnabled() and not window.redo_action.isEnabled()
    assert "*" not in window.windowTitle()
    doc.model.fill_rect((0, 0), (2, 2), 1)
    assert window.undo_action.text() == "&Undo rectangle fill" and window.undo_action.isEnabled()
    assert window.windowTitle().startswith("untitled *")
    # Ctrl+Z goes to the core history; the render and index colours follow its events.
    window.index_canvas.setFocus()
    qtbot.keyClick(window, Qt.Key.Key_Z, Qt.KeyboardModifier.ControlModifier)
    assert not doc.texture.grid.indices.any()
    assert window.redo_action.text() == "&Redo rectangle fill"
    assert (doc.index_rgb == doc.texture.library[0].colour).all()
    assert "*" not in window.windowTitle()
    window.redo_action.trigger()
    assert doc.texture.grid.indices[:3, :3].all()
    assert window._save_to(tmp_path / "p.ttproj") and doc.clean
    assert window.windowTitle() == "p.ttproj — terratheme"


def test_undo_during_a_brush_drag_takes_the_stroke_back(window, qtbot):
    doc = window.doc
    canvas = window.index_canvas
    doc.model.fill_rect((12, 8), (12, 8), 1)  # an earlier step: Undo is enabled
    window.palette_widget.select(1)
    qtbot.mousePress(canvas, Qt.MouseButton.LeftButton, pos=screen_of(canvas, QPointF(16, 16)))
    qtbot.mouseMove(canvas, screen_of(canvas, QPointF(40, 16)))
    assert doc.model.in_stroke and doc.texture.grid.indices.sum() > 1
    window.undo_action.trigger()
    # The stroke is finished and taken back; the earlier step stays.
    assert doc.texture.grid.indices.sum() == 1 and not doc.model.in_stroke
    # The rest of the drag paints nothing: the stroke it belonged to is undone.
    qtbot.mouseMove(canvas, screen_of(canvas, QPointF(60, 16)))
    qtbot.mouseRelease(canvas, Qt.MouseButton.LeftButton, pos=screen_of(canvas, QPointF(60, 16)))
    assert doc.texture.grid.indices.sum() == 1
    assert doc.model.history.undo_label == "rectangle fill"
    assert doc.model.history.redo_label == "brush stroke"


def test_brush_then_undo_of_a_single_vertex(window, qtbot):
    doc = window.doc
    window.palette_widget.select(1)
    window.size_box.setValue(1)
    canvas = window.index_canvas
    qtbot.mouseClick(canvas, Qt.MouseButton.LeftButton, pos=screen_of(canvas, QPointF(24, 16)))
    assert doc.texture.grid.indices[2, 3] == 1 and doc.texture.grid.indices.sum() == 1
    window.undo_action.trigger()
    assert not doc.texture.grid.indices.any()
    np.testing.assert_array_equal(doc.index_rgb[2, 3], doc.texture.library[0].colour)


ODD_LAYERS = [
    ({"photo": np.zeros(5, np.uint8)}, r"photo.npy has shape \(5,\); expected 3 dimensions"),
    ({"photo": np.zeros((64, 96, 3), np.float32)}, "photo.npy holds float32, not uint8"),
    ({"photo": np.zeros((64, 96, 3), np.uint8), "scribbles": np.zeros(7, np.uint8)},
     r"scribbles.npy has shape \(7,\); expected 2 dimensions"),
]


def _odd_project(path, texture: ThematicTexture, layers: dict) -> None:
    """A project file holding layers no ThematicTexture accepts (written member by member)."""
    import io
    import json
    import zipfile

    save_project(path, texture)
    with zipfile.ZipFile(path) as zf:
        members = {n: zf.read(n) for n in zf.namelist()}
    manifest = json.loads(members["manifest.json"])
    manifest["layers"] = list(layers)
    members["manifest.json"] = json.dumps(manifest).encode()
    for name, arr in layers.items():
        buf = io.BytesIO()
        np.save(buf, arr, allow_pickle=False)
        members[f"{name}.npy"] = buf.getvalue()
    with zipfile.ZipFile(path, "w") as zf:
        for name, data in members.items():
            zf.writestr(name, data)


@pytest.mark.parametrize(("layers", "message"), ODD_LAYERS)
def test_a_project_with_an_odd_layer_is_refused_with_one_line(window, texture, tmp_path, layers,
                                                               message):
    import re

    before = window.doc
    path = tmp_path / "odd.ttproj"
    _odd_project(path, texture, layers)
    assert not window.open_path(path)
    assert len(window.errors) == 1 and re.search(message, window.errors[0])
    assert "odd.ttproj" in window.errors[0]
    # The open document is untouched and still works.
    assert window.doc is before
    window.doc.model.fill_rect((0, 0), (3, 3), 1)
    window.index_canvas.repaint()


def test_the_screenshot_command_refuses_an_odd_layer_in_one_line(tmp_path, texture, capsys,
                                                                  monkeypatch):
    from PySide6.QtWidgets import QMessageBox
    from terratheme.app.cli import main

    dialogs = []
    monkeypatch.setattr(QMessageBox, "critical", lambda *a, **k: dialogs.append(a[2]))
    path = tmp_path / "odd.ttproj"
    _odd_project(path, texture, {"photo": np.zeros(5, np.uint8)})
    out = tmp_path / "shot.png"
    assert main(["app", str(path), "--screenshot", str(out), "--size", "640x400"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "photo.npy has shape (5,)" in err[0] and dialogs == []
    assert not out.exists()


def test_help_menu_lists_keys_docs_and_version(window, monkeypatch):
    import terratheme.core
    from PySide6.QtGui import QDesktopServices
    from PySide6.QtWidgets import QMessageBox
    from terratheme.app.editor.help import DOCS

    shown, opened = [], []
    monkeypatch.setattr(QMessageBox, "exec", lambda box: shown.append(box.text()))
    monkeypatch.setattr(QMessageBox, "information", lambda *a, **k: shown.append(a[2]))
    monkeypatch.setattr(QMessageBox, "about", lambda *a, **k: shown.append(a[2]))
    monkeypatch.setattr(QDesktopServices, "openUrl", lambda url: opened.append(url) or True)
    texts = [a.text() for a in window.help_menu.actions()]
    assert texts == ["&Keys and mouse…", "&Documentation…", "&About terratheme…"]
    window.doc.model.fill_rect((0, 0), (1, 1), 1)  # Undo's text names the step now
    for act in window.help_menu.actions():
        act.trigger()
    keys, docs, about = shown
    for must in ("Brush", "Scribble", "Wheel", "Ctrl+Z", "Edit &gt; Undo<", "File &gt; Save",
                 "[ and ]"):
        assert must in keys, must
    assert str(DOCS[0]) in docs
    assert opened and opened[0].toLocalFile() == str(DOCS[0])
    assert f"terratheme {terratheme.core.__version__}" in about and "PySide6" in about


def test_the_fidelity_view_names_the_whole_texture_figures(open_window, small_texture):
    from terratheme.app.editor.document import EditorDocument

    photo = np.full((64, 96, 3), 120, np.uint8)
    photo[:, ::2] = 160
    window = open_window(EditorDocument(small_texture(themes=2, seed=2, photo=photo)))
    window.fidelity_action.trigger()
    title = window.index_canvas.title
    assert "whole texture: dE8" in title and "bytes per area" in title
    window.fidelity_action.trigger()
    assert window.index_canvas.title == "Index map"
