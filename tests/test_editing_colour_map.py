"""The colour map under edits: neutral where the grid is repainted, dropped with new themes."""

from __future__ import annotations

import numpy as np
from terratheme.core.edit import ClassificationUpdate, EditDocument, RenderPreview
from terratheme.core.model.colour_map import NEUTRAL, ColourMap
from terratheme.core.model.grid import IndexGrid
from terratheme.core.model.project import ThematicTexture
from terratheme.core.render.project import render_project
from terratheme.core.themes.library import Theme, ThemeLibrary

CELL = (8, 8)


def _doc() -> EditDocument:
    rng = np.random.default_rng(0)
    lib = ThemeLibrary(Theme(n, (50 * i, 90, 200 - 40 * i),
                             rng.integers(0, 256, (8, 8, 3), dtype=np.uint8))
                       for i, n in enumerate(("grass", "water", "sand")))
    grid = IndexGrid(np.zeros((9, 11), np.uint8), CELL)  # 80 x 64 texels
    cmap = ColourMap(np.full((*ColourMap.shape_for(grid.texture_size, 4), 3), 200, np.uint8), 4)
    return EditDocument(ThematicTexture(grid, lib, {"render": {"boundary": {}}},
                                        colour_map=cmap))


def test_painting_a_theme_the_map_never_had_makes_it_neutral_nearest_the_vertex():
    doc = _doc()
    doc.fill_rect((5, 4), (5, 4), 2)  # one vertex, at texel (40, 32)
    px = doc.texture.colour_map.pixels
    # Map pixels (4 texels) whose centre is nearest it: centres 38, 42 x 30, 34.
    assert (px[7:9, 9:11] == NEUTRAL).all()
    untouched = np.ones(px.shape[:2], bool)
    untouched[7:9, 9:11] = False
    assert (px[untouched] == 200).all()
    assert doc.texture.colour_map.data is None
    # One step: undo brings back both the grid and the map.
    doc.undo()
    assert not doc.indices.any() and (doc.texture.colour_map.pixels == 200).all()
    doc.redo()
    assert (doc.texture.colour_map.pixels[7:9, 9:11] == NEUTRAL).all()


def test_a_painted_theme_takes_its_gain_from_where_the_map_has_it():
    rng = np.random.default_rng(0)
    lib = ThemeLibrary(Theme(n, (90, 90, 90), rng.integers(0, 256, (8, 8, 3), dtype=np.uint8))
                       for n in ("sand", "water"))
    grid = IndexGrid(np.zeros((9, 11), np.uint8), CELL)
    grid.indices[:, :3] = 1  # water: vertex columns 0-2, nearest map columns 0-4
    pixels = np.full((16, 20, 3), 200, np.uint8)
    pixels[:, :5] = (60, 50, 40)
    doc = EditDocument(ThematicTexture(grid, lib, {}, colour_map=ColourMap(pixels, 4)))
    doc.fill_rect((8, 4), (8, 4), 1)  # water into the sand, at texel (64, 32)
    px = doc.texture.colour_map.pixels
    assert (px[7:9, 15:17] == (60, 50, 40)).all()
    assert (px[:, 5:15] == 200).all() and (px[:7, 15:] == 200).all()
    doc.fill_rect((1, 4), (1, 4), 0)  # sand into the water, at texel (8, 32)
    assert (doc.texture.colour_map.pixels[7:9, 1:3] == 200).all()
    assert (doc.texture.colour_map.pixels[:7, :5] == (60, 50, 40)).all()
    doc.undo()
    doc.undo()
    assert np.array_equal(doc.texture.colour_map.pixels, pixels)


def test_a_stroke_neutralises_the_map_as_one_step():
    doc = _doc()
    doc.begin_stroke(1, (2.0, 2.0), 0.6)
    doc.stroke_to((4.0, 2.0), 0.6)
    doc.end_stroke()
    assert (doc.texture.colour_map.pixels == NEUTRAL).any()
    assert len(doc.history.undo_steps) == 1
    doc.undo()
    assert (doc.texture.colour_map.pixels == 200).all()


def test_the_live_preview_follows_the_map():
    doc = _doc()
    preview = RenderPreview(doc.texture)
    doc.events.grid.connect(preview.refresh)
    doc.events.colour_map.connect(lambda e: preview.refresh_region(e.region))
    np.testing.assert_array_equal(preview.image, render_project(doc.texture))
    doc.fill_rect((1, 1), (3, 2), 1)
    np.testing.assert_array_equal(preview.image, render_project(doc.texture))
    doc.undo()
    np.testing.assert_array_equal(preview.image, render_project(doc.texture))


def test_new_themes_of_a_classification_drop_the_map():
    doc = _doc()
    new = [Theme("rock", (90, 90, 90), np.full((4, 4, 3), 90, np.uint8))]
    doc.apply_classification(ClassificationUpdate(np.zeros((9, 11), np.uint8), new_themes=new,
                                                  replace_themes=True))
    assert doc.texture.colour_map is None
    doc.undo()
    assert doc.texture.colour_map is not None


def test_without_a_map_an_edit_records_only_the_paint():
    doc = _doc()
    doc.texture.colour_map = None
    step = doc.fill_rect((1, 1), (2, 2), 1)
    assert len(step.changes) == 1


def test_a_new_project_over_a_photo_gets_detail_themes_under_a_fitted_map():
    from terratheme.core.edit.classification import ClassifyMode, run_classification

    # Two flat halves with a fine grain: green and blue.
    rng = np.random.default_rng(1)
    photo = (rng.integers(-12, 13, (64, 96, 3)) + 100).astype(np.uint8)
    photo[:, :48] += np.array([0, 60, 0], np.uint8)
    photo[:, 48:] += np.array([0, 0, 80], np.uint8)
    doc = _doc()
    doc.texture.colour_map = None
    doc.data.theme_gains = None
    update, _ = run_classification(ClassifyMode.UNSUPERVISED_NEW, photo, None, doc.library,
                                   CELL, (9, 13), None, replace_themes=True)
    # Detail themes are ratios around mid-grey; the colour is in the map.
    for theme in update.new_themes:
        assert abs(theme.texture.mean() - NEUTRAL) < 3
    doc = EditDocument(ThematicTexture(IndexGrid(np.zeros((9, 13), np.uint8), CELL),
                                       doc.library, {}, photo=photo))
    doc.apply_classification(update)
    shown = render_project(doc.texture).astype(float)[:64, :96]
    # The render keeps each half's colour (green left, blue right), within the map's error.
    assert np.abs(shown[:, :40].mean(axis=(0, 1)) - (100, 160, 100)).max() < 8
    assert np.abs(shown[:, 56:].mean(axis=(0, 1)) - (100, 100, 180)).max() < 8
    # One step: undo takes the map and the themes back.
    doc.undo()
    assert doc.texture.colour_map is None
    # Painting the green theme into the blue half takes green's colour from the map.
    doc.redo()
    green = int(doc.indices[4, 1])
    doc.fill_rect((10, 4), (10, 4), green)
    shown = render_project(doc.texture).astype(float)
    assert np.abs(shown[30:34, 78:82].mean(axis=(0, 1)) - (100, 160, 100)).max() < 12
