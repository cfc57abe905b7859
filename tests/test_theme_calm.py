"""Calm twins (core.themes.calm): a class's calm part as a second theme, on every path."""

from __future__ import annotations

import numpy as np
import pytest
import terratheme.core.convert.region_sample as rs
from terratheme.core.convert.cell_choice import packed_bytes
from terratheme.core.convert.colour_fit import ColourMapOptions
from terratheme.core.convert.labels_to_grid import vote_grid
from terratheme.core.convert.photo import ConvertOptions, convert_photo
from terratheme.core.convert.step import calm_grid, detail_mapping, keep_calm
from terratheme.core.convert.tiled import convert_file_tiled, grid_from_file
from terratheme.core.io.images import write_image
from terratheme.core.io.tiles import Scheduler
from terratheme.core.model.grid import IndexGrid
from terratheme.core.themes.calm import (
    ENERGY_REACH,
    CalmTwin,
    calm_threshold,
    class_log_energy,
    fit_calm_twins,
    log_energy,
    split_calm,
    twin_parents,
    twin_vertices,
    with_twins,
)
from terratheme.core.themes.from_photo import ThemeMapping
from terratheme.core.themes.library import Theme, ThemeLibrary, flat_theme


def _grain(shape, sigma, seed, mean=128.0):
    """(h, w, 3) uint8 grey of ``mean`` with per-pixel noise of ``sigma`` (same on each band)."""
    noise = np.random.default_rng(seed).normal(0.0, sigma, shape)
    return np.repeat(np.clip(mean + noise, 0, 255)[:, :, None], 3, axis=2).astype(np.uint8)


def _fit(photo, labels, themes, first_twin):
    """:func:`fit_calm_twins` on the photo's class energies, as a conversion fits them."""
    return fit_calm_twins(class_log_energy(photo, labels, themes), labels, themes, first_twin)


def _split(photo, labels, twins):
    """:func:`split_calm` of ``labels`` by the photo's energies in the twins' themes."""
    return split_calm(labels, twins, class_log_energy(photo, labels, [t.theme for t in twins]))


def _calm_and_busy(h=128, w=512):
    """One class: its left half calm (noise 1), its right half busy (noise 24)."""
    photo = np.concatenate([_grain((h, w // 2), 1.0, 1), _grain((h, w // 2), 24.0, 2)], axis=1)
    return photo, np.zeros((h, w), np.uint8)


def test_a_class_of_a_calm_and_a_busy_half_gets_a_twin_for_the_calm_half():
    photo, labels = _calm_and_busy()
    twins = _fit(photo, labels, [0], 1)
    assert len(twins) == 1 and (twins[0].theme, twins[0].twin) == (0, 1)
    # Relative RMS 1/128 against 24/128: log2 energies near -14 and -4.8.
    assert -13.0 < twins[0].threshold < -6.0
    split = _split(photo, labels, twins)
    # Four of the energy's sigmas (32 px) away from the middle, each half is one theme.
    assert (split[:, :128] == 1).all() and (split[:, -128:] == 0).all()


def test_one_grain_everywhere_or_a_small_class_gets_no_twin():
    photo = _grain((128, 256), 12.0, 3)
    assert _fit(photo, np.zeros((128, 256), np.uint8), [0], 1) == ()
    # Halves of 48 x 48 are under TWIN_MIN_PIXELS (4096): edges, not areas.
    small, labels = _calm_and_busy(48, 96)
    assert _fit(small, labels, [0], 1) == ()


def _busy_class_with_a_calm_island(calm_width):
    """Class 0 busy (noise 24) on 768 columns and calm (noise 1) on ``calm_width`` columns,
    128 px of class 1 between them (4 of the energy's sigmas: neither part reaches the
    other)."""
    h, w = 128, 896 + calm_width
    photo = _grain((h, w), 24.0, 30)
    photo[:, 896:] = _grain((h, calm_width), 1.0, 31)
    labels = np.zeros((h, w), np.uint8)
    labels[:, 768:896] = 1
    return photo, labels


def test_a_calm_area_too_small_for_a_bimodal_split_still_gets_a_twin():
    # 128 x 64 calm pixels: 7.7% of the class, under TWIN_SHARE, over TWIN_MIN_PIXELS.
    photo, labels = _busy_class_with_a_calm_island(64)
    twins = _fit(photo, labels, [0], 2)
    assert len(twins) == 1 and (twins[0].theme, twins[0].twin) == (0, 2)
    # Relative RMS 24/128: log2 energy near -4.8, the tail TWIN_SEPARATION under it.
    assert -7.0 < twins[0].threshold < -6.0
    split = _split(photo, labels, twins)
    assert (split[:, 896:] == 2).all() and (split[:, :700] == 0).all()
    assert (split[:, 768:896] == 1).all()
    # 128 x 24 calm pixels are under TWIN_MIN_PIXELS: an edge, not an area.
    photo, labels = _busy_class_with_a_calm_island(24)
    assert _fit(photo, labels, [0], 2) == ()


def test_calm_threshold_splits_bimodal_energies_else_cuts_a_calm_tail():
    two = np.array([0.0] * 9000 + [-2.0] * 5000)
    assert -2.0 < calm_threshold(two) < 0.0  # Otsu's, between the modes
    # 5% calm: under TWIN_SHARE, so the tail TWIN_SEPARATION under the median.
    assert calm_threshold(np.array([0.0] * 95000 + [-2.0] * 5000)) == -1.5
    # A tail under TWIN_MIN_PIXELS, or not that far under the median: no twin.
    assert calm_threshold(np.array([0.0] * 95000 + [-2.0] * 4000)) is None
    assert calm_threshold(np.array([0.0] * 95000 + [-1.0] * 5000)) is None


def test_the_step_to_a_neighbour_class_and_its_border_pixels_do_not_count():
    # Two classes of one grain each, dark and bright; the classifier's border is 2 px off
    # the photo's, so the bright class holds a strip of the dark one's pixels.
    h, w = 128, 256
    photo = _grain((h, w), 3.0, 4, mean=200.0)
    photo[:, :128] = _grain((h, 128), 1.5, 5, mean=60.0)
    labels = np.zeros((h, w), np.uint8)
    labels[:, 126:] = 1
    energy = log_energy(photo, labels == 1)[labels == 1]
    # Noise of 3 over 200: log2 of (0.015)^2 is -12.1; the strip and the step are left out.
    assert energy.max() - energy.min() < 1.0
    assert _fit(photo, labels, [0, 1], 2) == ()
    # A plain blur over the whole photo would have raised the border to a busy rim.
    y = photo.mean(axis=2)
    plain = np.abs(y[:, 120:136] / y[:, 120:136].mean() - 1).max()
    assert plain > 0.5


def test_twin_vertices_take_the_twin_only_where_the_class_is_the_same():
    grid = np.array([[0, 0, 1], [0, 1, 1]], np.uint8)
    votes = np.array([[2, 0, 2], [1, 3, 0]], np.uint8)  # twins: 0 -> 2, 1 -> 3
    twins = (CalmTwin(0, 2, -8.0), CalmTwin(1, 3, -9.0))
    assert twin_vertices(grid, votes, twins).tolist() == [[2, 0, 1], [0, 3, 1]]
    assert twin_parents(4, twins).tolist() == [0, 1, 0, 1]


def test_twins_are_their_themes_renamed_distinctly():
    library = ThemeLibrary([flat_theme("sand", (200, 190, 150)),
                            flat_theme("sand calm", (10, 10, 10))])
    out = with_twins(library, (CalmTwin(0, 2, -8.0),))
    assert out.names == ["sand", "sand calm", "sand calm 2"]
    assert np.array_equal(out[2].texture, library[0].texture)
    assert out[2].colour == (227, 222, 202)  # halfway from (200, 190, 150) to white
    assert with_twins(library, ()) is library


def _classes(pixels: np.ndarray) -> np.ndarray:
    """A per-pixel classifier: dark (1) or bright (2)."""
    return np.where(pixels[..., :3].mean(axis=2) < 100, 1, 2).astype(np.uint8)


@pytest.mark.parametrize(("cell", "tile", "keep_specks"), [(8, 64, False), (5, 48, True)])
def test_the_tiled_grid_takes_the_whole_photos_twins(tmp_path, cell, tile, keep_specks):
    # Bright land calm on the left, busy on the right, and a dark lake with the same split.
    rng = np.random.default_rng(8)
    # Larger than a tile and its context (ENERGY_REACH), so tiles see parts of it.
    h, w = 400, 520
    photo = _grain((h, w), 1.0, 9, mean=190.0)
    photo[:, 260:] = _grain((h, w - 260), 28.0, 10, mean=190.0)
    lake = _grain((h, w), 1.0, 11, mean=50.0)
    lake[:, 260:] = _grain((h, w - 260), 10.0, 12, mean=50.0)
    yy, xx = np.mgrid[:h, :w]
    inside = (yy - 200) ** 2 / 140 ** 2 + (xx - 260) ** 2 / 180 ** 2 < 1
    photo[inside] = lake[inside]
    photo[rng.random((h, w)) < 0.002] = 0  # a few dark specks in the land
    path = tmp_path / "photo.tif"
    write_image(path, photo, tile=32)
    assert tile + 2 * ENERGY_REACH < w
    lut = np.zeros(256, np.uint8)
    lut[1], lut[2] = 0, 1
    theme_labels = lut[_classes(photo)]
    twins = _fit(photo, theme_labels, [0, 1], 2)
    assert {t.theme for t in twins} == {0, 1}
    whole = IndexGrid(vote_grid(theme_labels, (cell, cell), keep_specks=keep_specks), (cell, cell))
    want = calm_grid(_split(photo, theme_labels, twins), whole, twins)
    assert set(np.unique(want.indices)) == {0, 1, 2, 3}
    for sched in Scheduler:
        got = grid_from_file(path, cell, _classes, lut=lut, tile=tile, overlap=8,
                             scheduler=sched, keep_specks=keep_specks, calm=twins)
        assert np.array_equal(got.indices, want.indices), sched
    # The class grid itself is the one without twins.
    plain = grid_from_file(path, cell, _classes, lut=lut, tile=tile, keep_specks=keep_specks)
    assert np.array_equal(twin_parents(4, twins)[got.indices], plain.indices)


def test_twins_over_the_grids_share_of_the_budget_are_dropped():
    library = ThemeLibrary([flat_theme("sand", (200, 190, 150)), flat_theme("water", (0, 0, 90)),
                            flat_theme("sand calm", (200, 190, 150))])
    twins = (CalmTwin(0, 2, -8.0),)
    mapping = ThemeMapping(library, np.array([0, 0, 1] + [0] * 253, np.uint8), (1, 2), twins)
    rng = np.random.default_rng(0)
    grid = IndexGrid(rng.choice([0, 1, 2], (33, 33)).astype(np.uint8), (8, 8))
    size = packed_bytes(grid) * 8
    # Within the share (bits per photo pixel x pixels): kept as they are.
    assert keep_calm(grid, mapping, size / 1000, 1000) == (grid, mapping)
    assert keep_calm(grid, mapping, None, 1000) == (grid, mapping)
    # Over it: the twins' vertices are their classes' again and the twin themes go.
    got, plain = keep_calm(grid, mapping, (size - 8) / 1000, 1000)
    assert plain.library.names == ["sand", "water"] and plain.calm == ()
    assert np.array_equal(got.indices, np.where(grid.indices == 2, 0, grid.indices))
    assert got.cell == grid.cell and np.array_equal(plain.lut, mapping.lut)


def test_a_class_grid_over_its_share_still_takes_twins_that_add_little_to_it():
    library = ThemeLibrary([flat_theme("sand", (200, 190, 150)), flat_theme("water", (0, 0, 90)),
                            flat_theme("sand calm", (200, 190, 150))])
    mapping = ThemeMapping(library, np.array([0, 0, 1] + [0] * 253, np.uint8), (1, 2),
                           (CalmTwin(0, 2, -8.0),))
    # A class grid of random sand and water, a block of sand at its middle calm.
    classes = np.random.default_rng(1).choice([0, 1], (33, 33)).astype(np.uint8)
    classes[12:20, 12:20] = 0
    twinned = classes.copy()
    twinned[14:18, 14:18] = 2
    grid = IndexGrid(twinned, (8, 8))
    assert packed_bytes(grid) > packed_bytes(IndexGrid(classes, (8, 8)))
    # Over the share by far, the class grid too: the twins' few bytes are within
    # TWIN_GRID_EXTRA of the class grid's own.
    assert keep_calm(grid, mapping, 8 / 1000, 1000) == (grid, mapping)
    # Twins on a third of the vertices at random cost more than that: dropped.
    noisy = IndexGrid(np.random.default_rng(0).choice([0, 1, 2], (33, 33)).astype(np.uint8),
                      (8, 8))
    assert keep_calm(noisy, mapping, 8 / 1000, 1000)[1].calm == ()


def _quarter_calm(calm_noise=1.0, texture_noise=20.0):
    """(photo, labels, mapping): one class calm on its left quarter (noise ``calm_noise``)
    and busy on the rest (noise 24), themed by a grey texture of noise ``texture_noise``."""
    h, w = 128, 512
    photo = np.concatenate([_grain((h, 128), calm_noise, 1), _grain((h, w - 128), 24.0, 2)],
                           axis=1)
    mapping = ThemeMapping(ThemeLibrary([Theme("sand", (200, 190, 150),
                                               _grain((64, 64), texture_noise, 6))]),
                           np.zeros(256, np.uint8), (1,))
    return photo, np.zeros((h, w), np.uint8), mapping


def test_a_calm_twin_carries_less_grain_than_its_class():
    photo, labels, mapping = _quarter_calm()
    made = detail_mapping(photo, labels, mapping)[0]
    assert len(made.calm) == 1 and made.library.names == ["sand", "sand calm"]
    whole = detail_mapping(photo, labels, mapping, calm=())[0]
    assert whole.library.names == ["sand"]
    # Each part at its own pixels' gain: the busy part more grain than the whole class
    # had, the calm part far less.
    grain = [float(np.abs(t.texture.astype(float) - 128).mean()) for t in made.library]
    assert grain[0] > float(np.abs(whole.library[0].texture.astype(float) - 128).mean())
    assert grain[1] < 0.5 * grain[0]


def test_twins_dropped_over_the_budget_leave_each_theme_at_its_whole_classs_gain(monkeypatch):
    import terratheme.core.convert.step as step

    # Twins on no more than the budget's share: a grid over it drops them.
    monkeypatch.setattr(step, "TWIN_GRID_EXTRA", 0.0)
    # With its twin the theme carries the busy part's grain.
    photo, labels, mapping = _quarter_calm()
    made = detail_mapping(photo, labels, mapping)[0]
    whole = detail_mapping(photo, labels, mapping, calm=())[0]
    assert len(made.calm) == 1 and made.plain is not None and whole.plain is None
    assert not np.array_equal(made.library[0].texture, whole.library[0].texture)
    classes = IndexGrid(vote_grid(labels, (16, 16)), (16, 16))
    grid = calm_grid(_split(photo, labels, made.calm), classes, made.calm)
    assert set(np.unique(grid.indices)) == {0, 1}
    # No bits for the twins: the grid is the class's, its theme the one made without twins.
    got, plain = keep_calm(grid, made, 1e-6, labels.size)
    assert plain.calm == () and plain.library.names == ["sand"]
    assert np.array_equal(plain.library[0].texture, whole.library[0].texture)
    assert (got.indices == 0).all()


def test_a_twin_whose_detail_comes_out_as_its_themes_is_dropped():
    # A nearly flat texture: the calm quarter's gain and the busy part's both reach the top
    # of the gain range, so the twin's texture would be the theme's, byte for byte.
    photo, labels, mapping = _quarter_calm(calm_noise=2.0, texture_noise=0.3)
    assert len(_fit(photo, labels, [0], 1)) == 1
    made = detail_mapping(photo, labels, mapping)[0]
    assert made.calm == () and made.library.names == ["sand"]
    assert np.array_equal(made.library[0].texture,
                          detail_mapping(photo, labels, mapping, calm=())[0].library[0].texture)


@pytest.fixture
def halves_region(tmp_path, monkeypatch):
    """(photo, its tiled TIFF): sand calm on the left and busy on the right around a lake,
    larger than its region sample (2 x 2 windows of 192 px)."""
    h, w = 448, 640
    photo = _grain((h, w), 1.0, 20, mean=200.0)
    photo[:, w // 2:] = _grain((h, w - w // 2), 26.0, 21, mean=200.0)
    yy, xx = np.mgrid[:h, :w]
    lake = (yy - h // 2) ** 2 + (xx - w // 2) ** 2 < 110 ** 2
    photo[lake] = _grain((h, w), 3.0, 22, mean=50.0)[lake]
    path = tmp_path / "halves.tif"
    write_image(path, photo, tile=64)
    monkeypatch.setattr(rs, "SAMPLE_PIECE", 192)
    monkeypatch.setattr(rs, "SAMPLE_GRID", 2)
    return photo, path


def test_a_region_gets_the_whole_photos_twins_tile_by_tile(halves_region):
    photo, path = halves_region
    options = ConvertOptions(cell=8, themes=2, colour_map=ColourMapOptions(budget=0.3))
    whole = convert_photo(photo, options).project
    tiled = convert_file_tiled(path, None, 8, themes=2, tile=128,
                               colour_map=ColourMapOptions(budget=0.3))
    assert whole.library.names == tiled.library.names
    assert len(whole.library) == 3 and whole.library.names[2].endswith(" calm")
    assert all(np.array_equal(a.texture, b.texture) for a, b in zip(whole.library,
                                                                    tiled.library, strict=True))
    assert np.array_equal(whole.grid.indices, tiled.grid.indices)
    # The calm twin holds the calm half's vertices (away from the lake), the class the busy.
    twin = whole.library.names.index(whole.library.names[2])
    sand = whole.library.names.index(whole.library.names[2].removesuffix(" calm"))
    assert (whole.grid.indices[:, :12] == twin).all()
    assert (whole.grid.indices[:, -12:] == sand).all()


def test_the_editors_new_project_gets_converts_twins(halves_region):
    from terratheme.core.edit.classification import ClassifyMode, run_classification

    photo, _ = halves_region
    update, _ = run_classification(ClassifyMode.UNSUPERVISED_NEW, photo, None,
                                   ThemeLibrary([]), (8, 8), (57, 81), None,
                                   replace_themes=True)
    names = [t.name for t in update.new_themes]
    assert len(names) == 3 and names[2].removesuffix(" calm") in names[:2]
    assert (update.indices[:, :12] == 2).all()
    assert update.colour_map is not None


def test_a_region_whose_grid_cannot_afford_twins_gets_the_plain_themes_tile_by_tile(
        halves_region, monkeypatch):
    import terratheme.core.convert.step as step

    photo, path = halves_region
    # The grid's share of the least area budget (512 bytes) holds the class grid, not twins,
    # and twins get no bytes over it.
    monkeypatch.setattr(step, "GRID_SHARE", 0.03)
    monkeypatch.setattr(step, "TWIN_GRID_EXTRA", 0.0)
    options = ConvertOptions(cell=8, themes=2, colour_map=ColourMapOptions(budget=0.001))
    whole = convert_photo(photo, options).project
    tiled = convert_file_tiled(path, None, 8, themes=2, tile=128,
                               colour_map=ColourMapOptions(budget=0.001))
    assert len(whole.library) == 2 and whole.library.names == tiled.library.names
    # Each theme as a conversion with no twins makes it, on both paths.
    monkeypatch.setattr(step, "fit_calm_twins", lambda *args: ())
    plain = convert_photo(photo, options).project
    for got in (whole, tiled):
        assert all(np.array_equal(a.texture, b.texture)
                   for a, b in zip(got.library, plain.library, strict=True))


def test_detail_mappings_twin_labels_are_its_kept_twins_split():
    photo, labels, mapping = _quarter_calm()
    made, split = detail_mapping(photo, labels, mapping)
    assert len(made.calm) == 1
    assert np.array_equal(split, _split(photo, labels, made.calm))
    assert (split[:, :48] == 1).all() and (split[:, -128:] == 0).all()
    # A twin dropped (its detail its theme's): its pixels are its theme's again.
    photo, labels, mapping = _quarter_calm(calm_noise=2.0, texture_noise=0.3)
    made, split = detail_mapping(photo, labels, mapping)
    assert made.calm == () and (split == 0).all()


def test_class_energies_leave_other_and_small_themes_unmeasured():
    photo, labels = _calm_and_busy()
    labels[:, :8] = 1  # 1,024 pixels of theme 1
    energy = class_log_energy(photo, labels, [0, 1], min_pixels=2048)
    assert np.isnan(energy[:, :8]).all() and not np.isnan(energy[:, 8:]).any()
    assert np.array_equal(energy[labels == 0], log_energy(photo, labels == 0)[labels == 0])
    assert np.isnan(class_log_energy(photo, labels, [1])[:, 8:]).all()
