"""The editor's uncertainty view and kept class prior: the model side (no window)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("PySide6")

pytest.importorskip("pytestqt")

from PySide6.QtCore import QPoint, QPointF, Qt

from app.editor.uncertainty import (
    TINT,
    KeptPrior,
    next_kept_prior,
    scribble_classes,
    uncertain_mask,
    uncertainty_rgba,
)
from core.errors import TerrathemeError


def test_the_lowest_tenth_without_filter_is_the_smallest_values():
    conf = np.random.default_rng(3).random((25, 40)).astype(np.float32)
    mask = uncertain_mask(conf, size=1)
    # 1000 distinct values: the 10% quantile (linear) sits between the 100th and 101st.
    smallest = np.zeros(conf.size, bool)
    smallest[np.argsort(conf, axis=None)[:100]] = True
    np.testing.assert_array_equal(mask.ravel(), smallest)


def test_majority_filter_keeps_regions_and_drops_specks():
    conf = np.full((40, 40), 0.9, np.float32)
    conf[10:20, 10:20] = 0.3  # a 10 x 10 unsure region (6.25% of the photo)
    conf[15, 15] = 0.9  # a pinhole in it
    conf[30, 5] = conf[5, 32] = conf[34, 34] = 0.5  # isolated specks
    # Quantile 0.1 is the top value 0.9: only the 102 pixels below it are candidates.
    assert uncertain_mask(conf, size=1).sum() == 99 + 3
    mask = uncertain_mask(conf)
    assert mask[15, 15] and mask[12:18, 12:18].all()  # the pinhole is filled
    assert not mask[30, 5] and not mask[5, 32] and not mask[34, 34]  # specks are gone
    assert not mask[:6].any() and not mask[25:].any()
    # A 9 x 9 window at a region corner sees 5 x 5 = 25 of 81 unsure pixels: not a majority.
    assert not mask[10, 10] and mask[10, 14]


def test_flat_and_tied_confidence():
    assert not uncertain_mask(np.ones((20, 30), np.float32)).any()
    conf = np.full((20, 30), 0.8, np.float32)
    conf[:, :15] = 0.2  # half the photo tied at the lowest value: all of it counts
    np.testing.assert_array_equal(uncertain_mask(conf), conf == 0.2)
    assert uncertain_mask(np.zeros((0, 0), np.float32)).shape == (0, 0)


def test_overlay_colours():
    mask = np.array([[True, False], [False, True]])
    rgba = uncertainty_rgba(mask)
    assert rgba.shape == (2, 2, 4) and rgba.dtype == np.uint8
    assert tuple(rgba[0, 0]) == TINT and tuple(rgba[1, 1]) == TINT
    assert not rgba[0, 1].any() and not rgba[1, 0].any()


def test_kept_prior_lifecycle():
    assert scribble_classes(None) == frozenset()
    assert scribble_classes(np.array([[0, 3], [2, 3]], np.uint8)) == {2, 3}
    first = next_kept_prior(None, frozenset({2, 3}), {2: 1.0, 3: 0.4})
    assert first == KeptPrior({2: 1.0, 3: 0.4}, frozenset({2, 3}))
    # Correction strokes of the same classes: the first run's weights stay.
    assert next_kept_prior(first, frozenset({2, 3}), {2: 0.7, 3: 1.0}) is first
    # A new class: the run estimated afresh, and that becomes the kept prior.
    fresh = next_kept_prior(first, frozenset({2, 3, 4}), {2: 1.0, 3: 0.5, 4: 0.2})
    assert fresh.classes == {2, 3, 4} and fresh.weights[4] == 0.2
    # No weights (one class, no correction) or no scribbles: nothing kept.
    assert next_kept_prior(first, frozenset({2}), None) is None
    assert next_kept_prior(None, frozenset(), {1: 1.0}) is None
    assert not first.applies_to(frozenset())


def small_doc():
    from app.editor.document import EditorDocument
    from core.model.grid import IndexGrid
    from core.model.project import ThematicTexture
    from core.themes.library import Theme, ThemeLibrary

    rng = np.random.default_rng(5)
    lib = ThemeLibrary(Theme(n, c, rng.integers(0, 256, (8, 8, 3), dtype=np.uint8))
                       for n, c in (("grass", (90, 160, 60)), ("water", (40, 80, 170)),
                                    ("sand", (210, 190, 120))))
    photo = np.zeros((64, 96, 3), np.uint8)
    return EditorDocument(ThematicTexture(IndexGrid(np.zeros((9, 13), np.uint8), (8, 8)), lib,
                                          photo=photo))


@pytest.mark.qt
def test_document_keeps_the_confidence_until_the_photo_changes(qapp):
    doc = small_doc()
    seen = []
    doc.confidenceChanged.connect(lambda: seen.append(doc.confidence() is not None))
    assert doc.confidence() is None and doc.uncertain() is None
    with pytest.raises(TerrathemeError, match=r"\(10, 10\) confidence map does not fit"):
        doc.set_confidence(np.ones((10, 10)))
    conf = np.full((64, 96), 0.9)
    conf[20:40, 30:60] = 0.2
    doc.set_confidence(conf)
    assert doc.confidence().dtype == np.float32 and seen == [True]
    np.testing.assert_array_equal(doc.uncertain(), uncertain_mask(conf))
    # Grid edits keep it (the user corrects where it was unsure) ...
    doc.commit(doc.session.fill_rect((1, 1), (4, 3), 1), "rect")
    assert doc.confidence() is not None
    # ... another photo drops it.
    doc.texture.photo = np.zeros((64, 96, 3), np.uint8)
    assert doc.confidence() is None and doc.uncertain() is None and seen[-1] is False


@pytest.mark.qt
def test_document_kept_prior(qapp):
    doc = small_doc()
    sc = np.zeros((64, 96), np.uint8)
    sc[5, 5:20], sc[40, 50:70] = 1, 2
    assert doc.prior_for(sc) is None
    doc.remember_prior(scribble_classes(sc), {1: 1.0, 2: 0.3})
    sc[50, 10:30] = 2  # correction strokes of the same classes
    assert doc.prior_for(sc) == {1: 1.0, 2: 0.3}
    doc.remember_prior(scribble_classes(sc), {1: 0.6, 2: 1.0})  # the kept run's own weights
    assert doc.prior_for(sc) == {1: 1.0, 2: 0.3}
    sc[60, 60:70] = 3  # a new class drops it
    assert doc.prior_for(sc) is None and doc.kept_prior is None
    doc.remember_prior(scribble_classes(sc), {1: 1.0, 2: 0.5, 3: 0.25})
    # Clearing the scribbles (an undo that empties the layer) drops it too.
    doc.texture.scribbles = np.zeros((64, 96), np.uint8)
    doc.scribblesChanged.emit()
    assert doc.kept_prior is None


def test_scribble_run_uses_and_reports_the_class_weights():
    from app.editor.classify_job import Mode, run_classification

    doc = small_doc()
    photo = np.zeros((64, 96, 3), np.uint8)
    photo[:, :48] = (30, 140, 40)
    photo[:, 48:] = (40, 60, 200)
    sc = np.zeros((64, 96), np.uint8)
    sc[30:33, 10:30], sc[30:33, 60:80] = 1, 2
    lib, cell = doc.texture.library, (8, 8)
    kept = run_classification(Mode.SCRIBBLES, photo, sc, lib, cell, (9, 13), None,
                              class_weights={1: 0.25, 2: 1.0})
    assert kept.class_weights == {1: 0.25, 2: 1.0} and kept.scribble_classes == {1, 2}
    assert kept.confidence.shape == (64, 96) and kept.confidence.dtype == np.float32
    assert (kept.indices[:, :5] == 0).all() and (kept.indices[:, 8:] == 1).all()
    fresh = run_classification(Mode.SCRIBBLES, photo, sc, lib, cell, (9, 13), None)
    assert set(fresh.class_weights) == {1, 2} and fresh.class_weights != kept.class_weights
    unsup = run_classification(Mode.UNSUPERVISED_MAP, photo, None, lib, cell, (9, 13), None)
    assert unsup.class_weights is None and unsup.scribble_classes == frozenset()
    assert unsup.confidence.shape == (64, 96)



def test_scribble_run_passes_the_position_option(monkeypatch):
    import core.convert.step
    from app.editor.classify_job import Mode, run_classification

    seen = []
    train = core.convert.step.train_classifier

    def spy(pairs, options=None, **kw):
        seen.append(options.features.position)
        return train(pairs, options, **kw)

    monkeypatch.setattr(core.convert.step, "train_classifier", spy)
    photo = np.zeros((64, 96, 3), np.uint8)
    photo[:, 48:] = (40, 60, 200)
    sc = np.zeros((64, 96), np.uint8)
    sc[30:33, 10:30], sc[30:33, 60:80] = 1, 2
    lib = small_doc().texture.library
    for position in (False, True):
        out = run_classification(Mode.SCRIBBLES, photo, sc, lib, (8, 8), (9, 13), None,
                                 position=position)
        assert (out.indices[:, :5] == 0).all() and (out.indices[:, 8:] == 1).all()
    assert seen == [False, True]


# -- in the window (pytest-qt, offscreen) --------------------------------------


@pytest.fixture
def window(open_window):
    doc = small_doc()
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
    from app.editor.classify_job import Mode
    from app.editor.tools import Tool
    from app.editor.uncertainty import uncertain_mask, uncertainty_rgba

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
    conf = doc.confidence()
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
    doc.set_confidence(None)
    assert not act.isChecked() and not window.show_uncertainty
    assert window.uncertainty_pyramid is None


@pytest.mark.qt
def test_scribble_reruns_keep_the_first_class_prior(window, qtbot):
    from app.editor.classify_job import Mode
    from app.editor.tools import Tool

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
    kept = doc.kept_prior
    assert kept is not None and kept.classes == {2, 3} and set(kept.weights) == {2, 3}
    # A correction stroke of a class already painted: the kept weights are passed on.
    drag(qtbot, window.index_canvas, [QPointF(70, 55), QPointF(90, 55)])
    second = window.start_classification(Mode.SCRIBBLES)
    assert second.class_weights == dict(kept.weights)
    qtbot.waitUntil(lambda: window.job is None, timeout=60000)
    assert doc.kept_prior is kept
    # A new class (grass, value 1): estimate afresh.
    window.palette_widget.select(0)
    drag(qtbot, window.index_canvas, [QPointF(20, 56), QPointF(36, 56)])
    window.position_action.trigger()
    third = window.start_classification(Mode.SCRIBBLES)
    assert third.class_weights is None and third.position is True
    qtbot.waitUntil(lambda: window.job is None, timeout=60000)
    assert not window.errors, window.errors
    assert set(np.unique(doc.texture.scribbles)) == {0, 1, 2, 3}
    assert doc.kept_prior.classes == {1, 2, 3}
