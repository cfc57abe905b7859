"""convert_photo chooses the cell while the themes are cut: as if one after the other."""

from __future__ import annotations

import numpy as np
from terratheme.core.convert.cell_choice import cell_within_budget, choose_cell_size
from terratheme.core.convert.labels_to_grid import apply_lut, vote_grid
from terratheme.core.convert.photo import ConvertOptions, convert_photo
from terratheme.core.convert.step import cuts_themes, grid_and_colour, themes_and_cell
from terratheme.core.packing import pack
from terratheme.core.themes import ThemeLibrary, shipped_theme_library
from terratheme.core.themes.from_photo import photo_theme_lut, themes_from_photo


def _photo() -> np.ndarray:
    rng = np.random.default_rng(1)
    img = np.empty((160, 200, 3), np.uint8)
    img[:, :90] = (40, 110, 50)
    img[:, 90:] = (200, 180, 150)
    img[60:100, 120:180] = (30, 40, 90)
    return np.clip(img + rng.normal(0, 8, img.shape), 0, 255).astype(np.uint8)


def test_theme_lut_is_known_before_the_themes_are_cut() -> None:
    labels = np.ones((40, 50), np.uint8)
    labels[:, 25:] = 4
    labels[:3, :3] = 0
    mapping = themes_from_photo(_photo()[:40, :50], labels)
    np.testing.assert_array_equal(photo_theme_lut(labels), mapping.lut)
    np.testing.assert_array_equal(photo_theme_lut(labels, [1, 2, 4]),
                                  themes_from_photo(_photo()[:40, :50], labels,
                                                    classes=[1, 2, 4]).lut)


def test_overlapped_cell_choice_equals_the_sequential_one() -> None:
    photo = _photo()
    result = convert_photo(photo, ConvertOptions())
    theme_labels = apply_lut(result.labels, result.mapping.lut)
    alone = choose_cell_size(theme_labels, 0.9, candidates=ConvertOptions().candidates,
                             class_target=ConvertOptions().class_target, full_curve=False,
                             keep_specks=ConvertOptions().keep_specks)
    assert result.choice == alone
    again = grid_and_colour(photo, theme_labels, result.mapping,
                            class_target=ConvertOptions().class_target,
                            candidates=ConvertOptions().candidates, full_curve=False,
                            keep_specks=ConvertOptions().keep_specks)
    np.testing.assert_array_equal(again.grid.indices, result.project.grid.indices)
    assert again.choice == result.choice


def test_which_theme_specs_cut_from_the_photo() -> None:
    assert cuts_themes("auto") and cuts_themes(3)
    assert not cuts_themes(["water", "sand"]) and not cuts_themes({1: "water"})
    assert not cuts_themes(ThemeLibrary(list(shipped_theme_library())[:2]))


def test_themes_and_cell_for_every_kind_of_theme_spec() -> None:
    photo = _photo()
    labels = np.ones(photo.shape[:2], np.uint8)
    labels[:, 90:] = 2
    for spec in ("auto", 2, ["grass", "sand"], {1: "grass", 2: "sand"}):
        themed = themes_and_cell(photo, labels, [1, 2], spec, class_target=0.5)
        theme_labels = apply_lut(labels, themed.mapping.lut)
        np.testing.assert_array_equal(themed.theme_labels, theme_labels)
        alone = choose_cell_size(theme_labels, 0.9, class_target=0.5)
        assert themed.choice == alone, spec
        # The choice carries the grid voted at its cell (the grid stage takes it).
        size = themed.choice.cell
        np.testing.assert_array_equal(themed.choice.grid.indices, vote_grid(theme_labels, size))
        assert themes_and_cell(photo, labels, [1, 2], spec, cell=8).choice is None


def test_the_budget_choice_carries_its_grid_and_packed_size() -> None:
    labels = np.zeros((96, 128), np.uint8)
    labels[:, 40:] = 1
    labels[30:60, 70:100] = 2
    choice = choose_cell_size(labels, 0.9, candidates=(2, 4, 8), keep_specks=False)
    # A budget only the largest candidate meets: the cell grows, its grid and size come along.
    wide = cell_within_budget(labels, choice, (2, 4, 8), 1e-9, keep_specks=False)
    assert wide.cell == (8, 8)
    np.testing.assert_array_equal(wide.grid.indices,
                                  vote_grid(labels, (8, 8), keep_specks=False))
    assert wide.packed_bytes == len(pack(wide.grid.indices, curve="auto").to_bytes())
    # A budget the choice meets: the same cell, its own grid.
    kept = cell_within_budget(labels, choice, (2, 4, 8), 1e9, keep_specks=False)
    assert kept == choice and kept.grid is choice.grid
    assert kept.packed_bytes == len(pack(choice.grid.indices, curve="auto").to_bytes())
