"""The core edit document beyond the grid: layers, themes, results, history, events (no Qt)."""

from __future__ import annotations

import numpy as np
import pytest
from terratheme.core.edit import (
    ClassificationUpdate,
    EditDocument,
    Emitter,
    GridChange,
    HistoryChange,
    Layer,
    ScribbleChange,
    ThemeChange,
    photo_extent,
)
from terratheme.core.errors import TerrathemeError
from terratheme.core.model.grid import IndexGrid
from terratheme.core.model.project import ThematicTexture, load_project
from terratheme.core.themes.library import Theme, ThemeLibrary

PHOTO = (20, 30)  # rows, cols of the test photo: the grid below renders 32 x 24 texels


def make_doc(photo=True, scribbles=None, **kw) -> EditDocument:
    rng = np.random.default_rng(1)
    lib = ThemeLibrary(Theme(n, (40 * i, 90, 200 - 40 * i),
                             rng.integers(0, 256, (4, 4, 3), dtype=np.uint8))
                       for i, n in enumerate(("grass", "water", "sand")))
    ph = np.zeros((*PHOTO, 3), np.uint8) if photo is True else photo
    tex = ThematicTexture(IndexGrid(np.zeros((7, 9), np.uint8), (4, 4)), lib, photo=ph,
                          scribbles=scribbles)
    return EditDocument(tex, **kw)


def record(doc: EditDocument) -> list:
    seen: list = []
    for name in ("grid", "scribbles", "themes", "confidence", "prior", "history"):
        getattr(doc.events, name).connect(seen.append)
    return seen


# -- layers the editor cannot show ---------------------------------------------------------
ODD_PHOTOS = [
    (np.zeros(5, np.uint8), r"photo layer must be \(H, W, 3\), got shape \(5,\)"),
    (np.zeros(1, np.uint8), r"photo layer must be \(H, W, 3\), got shape \(1,\)"),
    (np.zeros((4, 4, 2), np.uint8), r"got shape \(4, 4, 2\)"),
    (np.zeros((*PHOTO, 3), np.float64), "photo layer must be uint8, got float64"),
    (np.zeros((0, 7, 3), np.uint8), "photo layer has no pixels"),
]


@pytest.mark.parametrize(("photo", "message"), ODD_PHOTOS)
def test_an_odd_photo_is_refused_with_one_line(photo, message):
    with pytest.raises(TerrathemeError, match=message):
        make_doc(photo=photo)


ODD_SCRIBBLES = [
    (np.zeros(5, np.uint8), r"scribbles layer must be \(H, W\), got shape \(5,\)"),
    (np.zeros(PHOTO, np.float32), "scribbles layer must be uint8, got float32"),
    (np.zeros((3, 3), np.uint8), "scribbles layer is 3 x 3 but the photo is 30 x 20"),
]


@pytest.mark.parametrize(("scribbles", "message"), ODD_SCRIBBLES)
def test_odd_scribbles_are_refused_with_one_line(scribbles, message):
    with pytest.raises(TerrathemeError, match=message):
        make_doc(scribbles=scribbles)


def test_photo_extent_is_one_to_one_unless_more_than_a_cell_smaller():
    grid = IndexGrid(np.zeros((7, 9), np.uint8), (4, 4))  # renders 32 x 24 texels
    assert photo_extent((21, 29, 3), grid) == (29.0, 21.0)
    assert photo_extent((10, 15, 3), grid) == (32.0, 24.0)  # stretched
    doc = make_doc()
    assert doc.texel_to_photo(16, 12) == (15.0, 10.0)  # the 30 x 20 photo lies 1:1
    assert doc.texel_to_vertex(16, 12) == (4.0, 3.0)


# -- scribbles --------------------------------------------------------------------------
def test_the_first_scribble_brings_the_layer_and_undo_takes_it_away():
    doc = make_doc()
    seen = record(doc)
    doc.begin_stroke(2, (3, 4), 0.0, Layer.SCRIBBLES)
    doc.stroke_to((6, 4), 0.0)
    step = doc.end_stroke()
    assert step.label == "scribble" and len(doc.history.undo_steps) == 1
    expected = np.zeros(PHOTO, np.uint8)
    expected[4, 3:7] = 2
    np.testing.assert_array_equal(doc.scribbles, expected)
    assert seen[0] == ScribbleChange(slice(0, 20), slice(0, 30), whole=True)
    doc.undo()
    assert doc.scribbles is None and doc.scribble_classes() == frozenset()
    # Erasing where nothing is painted records nothing and leaves no layer behind.
    doc.begin_stroke(0, (3, 4), 2.0, Layer.SCRIBBLES)
    assert doc.end_stroke() is None and doc.scribbles is None


def test_scribble_errors_name_the_problem():
    with pytest.raises(TerrathemeError, match="scribbles need a photo"):
        make_doc(photo=None).begin_stroke(1, (0, 0), 1, Layer.SCRIBBLES)
    doc = make_doc()
    with pytest.raises(TerrathemeError, match=r"scribble class value 4 is out of range 0\.\.3"):
        doc.begin_stroke(4, (0, 0), 1, Layer.SCRIBBLES)
    with pytest.raises(TerrathemeError, match="not painted with a brush"):
        doc.begin_stroke(1, (0, 0), 1, Layer.PHOTO)
    assert not doc.history.can_undo


# -- themes ---------------------------------------------------------------------------------
def test_theme_edits_are_undo_steps_with_events():
    doc = make_doc()
    seen = record(doc)
    old = doc.library[1]
    doc.replace_theme(1, old.with_(name="lake"))
    assert seen[0] == ThemeChange(1, colours=False, textures=False)
    doc.replace_theme(1, doc.library[1].with_(colour=(1, 2, 3)), "recolour lake")
    assert seen[2] == ThemeChange(1, colours=True, textures=False)
    assert doc.history.undo_label == "recolour lake"
    doc.replace_theme(0, doc.library[0].with_(texture=np.zeros((2, 2, 3), np.uint8)))
    assert seen[4] == ThemeChange(0, colours=False, textures=True)
    assert doc.replace_theme(0, doc.library[0]) is None  # the same theme: no step
    k = doc.add_theme(Theme("snow", (250, 250, 250), np.full((2, 2, 3), 250, np.uint8)))
    assert k == 3 and doc.library.names == ["grass", "lake", "sand", "snow"]
    for _ in range(4):
        doc.undo()
    assert doc.library.names == ["grass", "water", "sand"] and doc.library[1] == old


def test_theme_errors_are_refused_before_anything_changes():
    doc = make_doc()
    with pytest.raises(TerrathemeError, match="'Water' is already in the library"):
        doc.replace_theme(0, doc.library[0].with_(name="Water"))
    with pytest.raises(TerrathemeError, match="'sand' is already in the library"):
        doc.add_theme(doc.library[2])
    with pytest.raises(TerrathemeError, match="no theme with index 7"):
        doc.replace_theme(7, doc.library[0])
    assert not doc.history.can_undo


# -- classification results, photo, confidence ------------------------------------------------
def test_a_classification_with_new_themes_is_one_undo_step():
    doc = make_doc()
    seen = record(doc)
    new = [Theme(f"class {i}", (i, i, i), np.full((2, 2, 3), i, np.uint8)) for i in range(2)]
    grid = np.zeros((7, 9), np.uint8)
    grid[:, 4:] = 4  # the second new theme
    conf = np.full(PHOTO, 0.5)
    step = doc.apply_classification(ClassificationUpdate(grid, new_themes=new, confidence=conf))
    assert step.label == "classification" and len(doc.history.undo_steps) == 1
    assert doc.library.names[3:] == ["class 0", "class 1"] and doc.confidence.mean() == 0.5
    np.testing.assert_array_equal(doc.indices, grid)
    # Every event comes after the whole step: the grid event sees the new themes.
    kinds = [type(e).__name__ for e in seen]
    assert kinds == ["ThemeChange", "ThemeChange", "GridChange", "ConfidenceChange",
                     "HistoryChange"]
    doc.undo()
    assert len(doc.library) == 3 and not doc.indices.any() and doc.confidence is None


def test_a_classification_can_replace_the_themes():
    doc = make_doc()
    before = list(doc.library)
    classes = [Theme(f"c{i}", (i, 0, 0), np.full((2, 2, 3), i, np.uint8)) for i in range(2)]
    grid = np.ones((7, 9), np.int64)
    doc.apply_classification(ClassificationUpdate(grid, new_themes=classes, replace_themes=True))
    assert doc.library.names == ["c0", "c1"] and (doc.indices == 1).all()
    doc.undo()
    assert list(doc.library) == before and not doc.indices.any()
    doc.redo()
    assert doc.library.names == ["c0", "c1"]


def test_classification_results_are_checked_first():
    doc = make_doc()
    with pytest.raises(TerrathemeError, match=r"theme indices 0\.\.2"):
        doc.apply_classification(ClassificationUpdate(np.full((7, 9), 3)))
    with pytest.raises(TerrathemeError, match="shape"):
        doc.apply_classification(ClassificationUpdate(np.zeros((3, 3), np.uint8)))
    with pytest.raises(TerrathemeError, match="needs themes"):
        doc.apply_classification(ClassificationUpdate(np.zeros((7, 9), np.uint8),
                                                      replace_themes=True))
    with pytest.raises(TerrathemeError, match="confidence map does not fit"):
        doc.apply_classification(ClassificationUpdate(np.zeros((7, 9), np.uint8),
                                                      confidence=np.ones((2, 2))))
    assert len(doc.library) == 3 and not doc.history.can_undo
    # The same grid and no map: nothing to record.
    assert doc.apply_classification(ClassificationUpdate(np.zeros((7, 9), np.uint8))) is None


# -- history ------------------------------------------------------------------------------
def test_saved_state_and_history_events(tmp_path):
    doc = make_doc()
    seen = []
    doc.events.history.connect(seen.append)
    assert doc.history.clean
    doc.fill_rect((0, 0), (1, 1), 1)
    assert seen[-1] == HistoryChange("rectangle fill", None, clean=False)
    path = tmp_path / "p.ttproj"
    doc.save(path)
    assert seen[-1].clean and load_project(path) == doc.texture
    doc.undo()
    assert seen[-1] == HistoryChange(None, "rectangle fill", clean=False)
    doc.redo()
    assert doc.history.clean
    # Undo, then a new edit: the saved state is gone for good.
    doc.undo()
    doc.flood_fill((0, 0), 2)
    doc.undo()
    assert not doc.history.clean and not doc.history.can_undo


def test_groups_make_one_step_and_undo_waits_for_them():
    doc = make_doc()
    with doc.group("two rectangles"):
        doc.fill_rect((0, 0), (1, 1), 1)
        doc.fill_rect((3, 3), (4, 4), 2)
        with pytest.raises(TerrathemeError, match="cannot undo while the step"):
            doc.undo()
    assert [s.label for s in doc.history.undo_steps] == ["two rectangles"]
    doc.undo()
    assert not doc.indices.any()
    # A group that raises still records what it applied.
    with pytest.raises(TerrathemeError), doc.group("half done"):
        doc.fill_rect((0, 0), (0, 0), 1)
        doc.fill_rect((0, 0), (0, 0), 9)
    assert doc.history.undo_label == "half done" and doc.indices[0, 0] == 1


def test_undo_in_the_middle_of_a_stroke_takes_the_stroke_back():
    doc = make_doc()
    doc.fill_rect((0, 0), (0, 0), 2)
    doc.begin_stroke(1, (5, 5), 1)
    doc.stroke_to((7, 5), 1)
    assert doc.undo().label == "brush stroke" and not doc.in_stroke
    assert doc.indices.sum() == 2 and doc.history.redo_label == "brush stroke"


def test_emitter_connect_and_disconnect():
    em: Emitter[GridChange] = Emitter()
    got = []
    off = em.connect(got.append)
    em.emit(GridChange(slice(0, 1), slice(0, 1)))
    off()
    off()  # twice is harmless
    em.emit(GridChange(slice(0, 2), slice(0, 2)))
    assert got == [GridChange(slice(0, 1), slice(0, 1))]
