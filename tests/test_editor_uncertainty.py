"""The editor's uncertainty view and kept class prior: classify_job and the window.

The model side (which pixels are uncertain, the kept prior's rules, the
document keeping the map) is tested without Qt in tests/test_editing_uncertainty.py.
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("PySide6")

pytest.importorskip("pytestqt")

from PySide6.QtCore import QPoint, QPointF, Qt
from terratheme.core.edit import ClassificationUpdate, uncertain_mask, uncertainty_rgba


@pytest.fixture
def doc(small_texture):
    from terratheme.app.editor.document import EditorDocument

    return EditorDocument(small_texture(photo=np.zeros((64, 96, 3), np.uint8)))


def test_scribble_run_uses_and_reports_the_class_weights(doc):
    from terratheme.core.edit.classification import ClassifyMode as Mode
    from terratheme.core.edit.classification import run_classification

    photo = np.zeros((64, 96, 3), np.uint8)
    photo[:, :48] = (30, 140, 40)
    photo[:, 48:] = (40, 60, 200)
    sc = np.zeros((64, 96), np.uint8)
    sc[30:33, 10:30], sc[30:33, 60:80] = 1, 2
    lib, cell = doc.texture.library, (8, 8)
    kept, _ = run_classification(Mode.SCRIBBLES, photo, sc, lib, cell, (9, 13), None,
                              class_weights={1: 0.25, 2: 1.0})
    assert kept.class_weights == {1: 0.25, 2: 1.0} and kept.scribble_classes == {1, 2}
    assert kept.confidence.shape == (64, 96) and kept.confidence.dtype == np.float32
    assert (kept.indices[:, :5] == 0).all() and (kept.indices[:, 8:] == 1).all()
    fresh, _ = run_classification(Mode.SCRIBBLES, photo, sc, lib, cell, (9, 13), None)
    assert set(fresh.class_weights) == {1, 2} and fresh.class_weights != kept.class_weights
    unsup, _ = run_classification(Mode.UNSUPERVISED_MAP, photo, None, lib, cell, (9, 13), None)
    assert unsup.class_weights is None and unsup.scribble_classes is None
    assert unsup.confidence.shape == (64, 96)



def test_scribble_run_passes_the_position_option(monkeypatch, doc):
    import terratheme.core.convert.step
    from terratheme.core.edit.classification import ClassifyMode as Mode
    from terratheme.core.edit.classification import run_classification

    seen = []
    train = terratheme.core.convert.step.train_classifier

    def spy(pairs, options=None, **kw):
        seen.append(options.features.position)
        return train(pairs, options, **kw)

    monkeypatch.setattr(terratheme.core.convert.step, "train_classifier", spy)
    photo = np.zeros((64, 96, 3), np.uint8)
    photo[:, 48:] = (40, 60, 200)
    sc = np.zeros((64, 96), np.uint8)
    sc[30:33, 10:30], sc[30:33, 60:80] = 1, 2
    lib = doc.texture.library
    for position in (False, True):
        out, _ = run_classification(Mode.SCRIBBLES, photo, sc, lib, (8, 8), (9, 13), None,
                                 position=position)
        assert (out.indices[:, :5] == 0).all() and (out.indices[:, 8:] == 1).all()
    assert seen == [False, True]


# -- in the window (pytest-qt, offscreen) --------------------------------------


@pytest.fixture
def window(open_window, doc):
    doc.texture.photo[:, :48] = (30, 140, 40)
    doc.texture.photo[:, 48:] = (40, 60, 200)
    return open_window(doc)


def drag(qtbot, canvas, points):
    def screen(t):
        s, o = canvas.view.scale, canvas.view.origin
        return QPoint(round((t.x() - o.x()) * s), round((t.y() - o.y()) * s))

    qtbot.mousePress(canvas, Qt.MouseButton.LeftButton, pos=screen(points[0]))
    for p in points[1:]:
        qtbot.mouseMove(canvas, screen(p))
    qtbot.mouseRelease(canvas, Qt.MouseButton.LeftButton, pos=screen(points[-1]))


@pytest.mark.qt
def test_uncertainty_toggle_follows_the_confidence_map(window, qtbot):
    from terratheme.app.editor.tools import Tool
    from terratheme.core.edit.classification import ClassifyMode as Mode
    doc = window.doc
    act = window.uncertainty_action
    assert act.shortcut().toString() == "U"
    # No confidence map yet: the toggle refuses and stays off.
    act.trigger()
    assert not act.isChecked() and not window.show_uncertainty
    assert window.uncertainty_pyramid is None
    window.set_tool(Tool.SCRIBBLE)
    window.palette_widget.select(2)
    drag(qtbot, window.index_canvas, [QPointF(8, 10), QPointF(30, 50)])
    window.palette_widget.select(1)
    drag(qtbot, window.index_canvas, [QPointF(60, 10), QPointF(85, 50)])
    window.start_classification(Mode.SCRIBBLES)
    qtbot.waitUntil(lambda: window.job is None, timeout=60000)
    conf = doc.model.confidence
    assert conf.shape == (64, 96) and conf.dtype == np.float32
    # Toggle on (action -> window, canvas overlay and status bar).
    act.trigger()
    assert act.isChecked() and window.show_uncertainty
    mask = uncertain_mask(conf)
    np.testing.assert_array_equal(window.uncertainty_pyramid.base, uncertainty_rgba(mask))
    assert window.uncertainty_label.isVisibleTo(window)
    assert f"{100 * mask.mean():.1f}% of the photo" in window.uncertainty_label.text()
    window.index_canvas.repaint()
    # Window -> action.
    window.set_show_uncertainty(False)
    assert not act.isChecked() and window.uncertainty_pyramid is None
    assert not window.uncertainty_label.isVisibleTo(window)
    window.set_show_uncertainty(True)
    assert act.isChecked()
    # The document drops its map: the overlay goes and the toggle turns off.
    doc.model.apply_classification(ClassificationUpdate(doc.model.indices))
    assert not act.isChecked() and not window.show_uncertainty
    assert window.uncertainty_pyramid is None


@pytest.mark.qt
def test_scribble_reruns_keep_the_first_class_prior(window, qtbot):
    from terratheme.app.editor.tools import Tool
    from terratheme.core.edit.classification import ClassifyMode as Mode

    doc = window.doc
    window.set_tool(Tool.SCRIBBLE)
    window.size_box.setValue(1)  # thin strokes: well under half the photo is labelled
    window.palette_widget.select(2)
    drag(qtbot, window.index_canvas, [QPointF(8, 10), QPointF(30, 50)])
    window.palette_widget.select(1)
    drag(qtbot, window.index_canvas, [QPointF(60, 10), QPointF(85, 50)])
    first = window.start_classification(Mode.SCRIBBLES)
    assert first.class_weights is None  # the first run estimates
    assert first.position is False  # Classify > "use where the strokes lie" is off
    qtbot.waitUntil(lambda: window.job is None, timeout=60000)
    kept = doc.model.kept_prior
    assert kept is not None and kept.classes == {2, 3} and set(kept.weights) == {2, 3}
    # A correction stroke of a class already painted: the kept weights are passed on.
    drag(qtbot, window.index_canvas, [QPointF(70, 55), QPointF(90, 55)])
    second = window.start_classification(Mode.SCRIBBLES)
    assert second.class_weights == dict(kept.weights)
    qtbot.waitUntil(lambda: window.job is None, timeout=60000)
    assert doc.model.kept_prior is kept
    # A new class (grass, value 1): estimate afresh.
    window.palette_widget.select(0)
    drag(qtbot, window.index_canvas, [QPointF(20, 56), QPointF(36, 56)])
    window.position_action.trigger()
    third = window.start_classification(Mode.SCRIBBLES)
    assert third.class_weights is None and third.position is True
    qtbot.waitUntil(lambda: window.job is None, timeout=60000)
    assert not window.errors, window.errors
    assert set(np.unique(doc.texture.scribbles)) == {0, 1, 2, 3}
    assert doc.model.kept_prior.classes == {1, 2, 3}
