"""The colour map fitted by convert, and the one class-to-theme matching rule."""

from __future__ import annotations

import numpy as np
import pytest
from terratheme.core.convert.cell_choice import (
    CONVERT_CELL_CANDIDATES,
    CellChoice,
    agreement,
    cell_within_budget,
    packed_bytes,
    road_candidates,
)
from terratheme.core.convert.colour_fit import ColourMapOptions, choose_colour_map, fit_gain
from terratheme.core.errors import TerrathemeError
from terratheme.core.fidelity import colour_error
from terratheme.core.io.codec import decode_image, encode_image
from terratheme.core.model.colour_map import ColourMap
from terratheme.core.render.colour_map import apply_colour_map
from terratheme.core.themes.library import ThemeLibrary, flat_theme, shipped_theme_library
from terratheme.core.themes.matching import (
    Appearance,
    class_appearances,
    match_classes,
    shipped_names,
)
from terratheme.core.themes.patch_search import texture_stats


def _photo_and_render(seed=0):
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:96, 0:128]
    # The photo: a slow colour change over a grain the render shares.
    grain = rng.normal(0, 6, (96, 128, 1))
    photo = np.clip(np.stack([90 + 0.6 * xx, 120 + 0.3 * yy, 80 + 0 * xx], 2) + grain, 0, 255)
    render = np.clip(110 + grain.repeat(3, 2), 0, 255)
    return photo.astype(np.uint8), render.astype(np.uint8)


def test_block_gain_brings_block_means_to_the_photo():
    photo, render = _photo_and_render()
    gain = fit_gain(photo, render, 16, iterations=0)
    assert gain.shape == (6, 8, 3)
    want = photo[:16, :16].reshape(-1, 3).mean(0) / render[:16, :16].reshape(-1, 3).mean(0)
    assert gain[0, 0] == pytest.approx(want, rel=1e-3)


def test_a_finer_map_or_more_iterations_lower_the_colour_error():
    photo, render = _photo_and_render()
    errors = []
    for scale, it in [(64, 0), (16, 0), (16, 2)]:
        gain = fit_gain(photo, render, scale, it)
        cmap = ColourMap(np.clip(np.rint(gain * 128), 0, 255).astype(np.uint8), scale)
        errors.append(colour_error(apply_colour_map(render.copy(), cmap, (0, 0, 128, 96)), photo))
    assert errors[0] > errors[1] >= errors[2] - 0.05
    assert errors[2] < 1.5 and colour_error(render, photo) > 8


def test_the_coarsest_scale_meeting_the_target_is_chosen_and_shipped_as_decoded():
    photo, render = _photo_and_render()
    fitted = choose_colour_map(photo, render, ColourMapOptions(target=3.0, scales=(64, 32, 16)))
    scales = [p[0] for p in fitted.curve]
    # Tried coarsest first, stopped at the first that meets the target.
    assert scales == [64, 32, 16][: len(scales)]
    assert all(p[2] > 3.0 for p in fitted.curve[:-1])
    assert fitted.curve[-1][2] <= 3.0 or len(scales) == 3
    assert fitted.colour_map.scale == scales[-1] and fitted.colour_error == fitted.curve[-1][2]
    # The map renders exactly what its stored bytes decode to.
    assert np.array_equal(fitted.colour_map.pixels, decode_image(fitted.data, codec=fitted.codec))
    loose = choose_colour_map(photo, render, ColourMapOptions(target=50.0))
    assert [p[0] for p in loose.curve] == [64]


def test_colour_fit_errors():
    photo, render = _photo_and_render()
    with pytest.raises(TerrathemeError, match="smaller than"):
        choose_colour_map(photo, render[:50])
    with pytest.raises(TerrathemeError, match="scales"):
        ColourMapOptions(scales=())
    with pytest.raises(TerrathemeError, match="unknown image codec"):
        encode_image(photo, codec="bmpx")
    with pytest.raises(TerrathemeError, match="quality"):
        encode_image(photo, quality=0)


def test_png_codec_is_lossless():
    photo, _ = _photo_and_render()
    assert np.array_equal(decode_image(encode_image(photo, codec="png"), codec="png"), photo)


def test_classes_go_to_the_theme_that_looks_like_them():
    looks = [Appearance(np.array([60.0, 60, 40]), 1e-3), Appearance(np.array([30.0, 5, -40]), 1e-4)]
    themes = [Appearance(np.array([32.0, 4, -38]), 1e-4),
              Appearance(np.array([58.0, 55, 45]), 1e-3),
              Appearance(np.array([90.0, 0, 0]), 1e-5)]
    assert match_classes(looks, themes, distinct=False) == [1, 0]
    assert match_classes(looks, themes, distinct=True) == [1, 0]
    # Two classes that both look like theme 1: distinct gives one of them the next best.
    twins = [looks[0], looks[0]]
    assert match_classes(twins, themes, distinct=False) == [1, 1]
    assert sorted(match_classes(twins, themes, distinct=True)) in ([0, 1], [1, 2])
    with pytest.raises(TerrathemeError, match="only 1 themes"):
        match_classes(looks, themes[:1], distinct=True)


def test_shipped_names_name_classes_and_number_repeats():
    water = np.zeros((32, 32, 3), np.uint8)
    water[:] = (40, 90, 200)
    snowy = np.full((32, 32, 3), 245, np.uint8)
    photo = np.concatenate([water, snowy, water], axis=1)
    labels = np.repeat(np.repeat(np.array([[1, 2, 3]], np.uint8), 32, 0), 32, 1)
    looks = class_appearances(texture_stats(photo), labels, [1, 2, 3])
    lib = ThemeLibrary([flat_theme("water", (40, 90, 200)), flat_theme("snow", (240, 240, 250))])
    assert shipped_names(looks, lib) == ["water", "snow", "water 2"]
    assert shipped_names(looks[:1], shipped_theme_library()) == ["water"]


def test_tile_by_tile_map_equals_the_whole_photo_block_gain(tmp_path):
    from terratheme.core.convert.colour_fit import colour_map_from_file
    from terratheme.core.io.codec import decode_image
    from terratheme.core.io.images import write_image
    from terratheme.core.model.grid import IndexGrid
    from terratheme.core.render.renderer import render_cells

    rng = np.random.default_rng(8)
    photo = rng.integers(30, 220, (100, 140, 3), dtype=np.uint8)
    write_image(tmp_path / "p.png", photo)
    grid = IndexGrid(rng.integers(0, 2, (8, 10)).astype(np.uint8), (16, 16))  # 144 x 112
    themes = [np.full((8, 8, 3), 90, np.uint8), np.full((8, 8, 3), 160, np.uint8)]
    opts = ColourMapOptions(codec="png")
    tiled = colour_map_from_file(tmp_path / "p.png", grid, themes, 16, options=opts, tile=48)
    whole = fit_gain(photo, render_cells(grid, themes), 16, iterations=0)
    want = np.clip(np.rint(whole * 128), 0, 255).astype(np.uint8)
    # Map pixels inside the photo: the same block ratio (to rounding of the sums).
    coded = decode_image(tiled.colour_map.data, codec="png")
    inside = coded[:6, :8].astype(int) - want[:6, :8]
    assert np.abs(inside).max() <= 1
    assert coded.shape == (7, 9, 3) and tiled.colour_map.coded_scale == 16
    # A budget map at an even scale draws its 2x bicubic enlargement, as the whole photo's.
    assert tiled.colour_map.upsample == 2 and tiled.colour_map.scale == 8
    assert tiled.colour_map.pixels.shape == (14, 18, 3)


def test_fit_quality_takes_the_highest_quality_that_fits():
    from terratheme.core.convert.colour_fit import fit_quality
    from terratheme.core.model.colour_map import ColourMap

    rng = np.random.default_rng(2)
    gain = rng.integers(60, 200, (40, 48, 3), dtype=np.uint8)
    sizes = {q: ColourMap.encode(gain, 8, "webp", q).nbytes for q in range(1, 100)}
    budget = sizes[50]
    q, cmap = fit_quality(gain, 8, "webp", budget)
    assert cmap.nbytes <= budget
    # The next quality does not fit (bytes need not grow strictly with the quality).
    assert q >= 50 and sizes[q] <= budget < sizes[q + 1]
    assert fit_quality(gain, 8, "webp", 10) is None


@pytest.mark.parametrize("curve", ["exponential", "steps"])
def test_fit_quality_from_any_guess_finds_what_a_scan_finds(monkeypatch, curve):
    from types import SimpleNamespace

    import terratheme.core.convert.colour_fit as cf

    # Bytes that grow with quality: smoothly, or in plateaus with jumps.
    def size(q):
        return int(200 * 2 ** (q / 15)) if curve == "exponential" else 1000 + 700 * (q // 9)

    calls = []

    class Stub:
        @staticmethod
        def encode(gain, scale, codec, quality, **kwargs):
            calls.append(quality)
            return SimpleNamespace(nbytes=size(quality), quality=quality)

    monkeypatch.setattr(cf, "ColourMap", Stub)
    for budget in (size(1) - 1, size(1), 999, 1500, 4321, 8000, size(99), 10 ** 9):
        fitting = [q for q in range(1, 100) if size(q) <= budget]
        for guess in (1, 17, 50, 83, 99):
            calls.clear()
            got = cf.fit_quality(np.zeros((4, 4, 3), np.uint8), 8, "avif", budget, guess=guess)
            if not fitting:
                assert got is None
            else:
                assert got[0] == max(fitting) and got[1].quality == max(fitting)
            # The guided steps, then a bisection of what is left.
            assert len(calls) <= cf.FIT_GUIDED_STEPS + 7, (budget, guess, calls)


def test_budget_map_spends_no_more_than_its_budget_and_beats_a_coarse_map_on_structure():
    from terratheme.core.fidelity import structure_similarity
    from terratheme.core.render.colour_map import apply_colour_map

    # A photo of 8-texel streets over a flat render: only a fine map can show them.
    photo = np.full((128, 128, 3), 200, np.uint8)
    photo[::32] = photo[1::32] = photo[2::32] = photo[3::32] = 60
    render = np.full((128, 128, 3), 128, np.uint8)
    opts = ColourMapOptions(budget=2.0, budget_scales=(32, 4))
    fitted = choose_colour_map(photo, render, opts, reserved=100)
    assert fitted.colour_map.nbytes <= opts.map_bytes(128 * 128, 100)
    # Coded at 1/4, drawn through its 2x bicubic enlargement at 1/2.
    assert fitted.colour_map.coded_scale == 4 and fitted.colour_map.upsample == 2
    assert fitted.colour_map.scale == 2
    shown = apply_colour_map(render.copy(), fitted.colour_map, (0, 0, 128, 128))
    assert structure_similarity(shown, photo, 4) > 0.8


def test_target_none_is_the_budget_and_bad_budgets_are_refused():
    assert ColourMapOptions().target is None
    assert ColourMapOptions(budget=0.08).map_bytes(1_000_000, 2) == 9998
    assert ColourMapOptions(budget=0.08).map_bytes(1_000_000, 20_000) == 0
    with pytest.raises(TerrathemeError):
        ColourMapOptions(budget=0.0)
    with pytest.raises(TerrathemeError):
        ColourMapOptions(budget_scales=())


def test_detail_themes_only_with_a_budget_map():
    from terratheme.core.convert.step import detail_sigma
    from terratheme.core.themes.detail import DETAIL_SIGMA

    assert detail_sigma(ColourMapOptions()) == DETAIL_SIGMA
    assert detail_sigma(ColourMapOptions(target=2.0)) is None
    assert detail_sigma(None) is None


def test_cell_within_budget_takes_a_larger_cell_only_when_the_grid_does_not_fit():
    from terratheme.core.convert.labels_to_grid import vote_grid
    from terratheme.core.model.grid import IndexGrid

    rng = np.random.default_rng(5)
    # Random 16-pixel blocks of 3 themes: a cell-4 grid costs more than a cell-16 one.
    labels = np.kron(rng.integers(0, 3, (8, 8)), np.ones((16, 16), int)).astype(np.uint8)
    choice = CellChoice((4, 4), 1.0, 0.0, (), True)  # no agreement target: bytes decide
    bits = {c: packed_bytes(IndexGrid(vote_grid(labels, (c, c)), (c, c))) * 8 / labels.size
            for c in (4, 8, 16)}
    assert bits[4] > bits[8] > bits[16]
    kept = cell_within_budget(labels, choice, (4, 8, 16), bits[4])
    assert kept == choice and kept.agreement == choice.agreement
    got = cell_within_budget(labels, choice, (4, 8, 16), (bits[8] + bits[16]) / 2)
    g16 = IndexGrid(vote_grid(labels, (16, 16)), (16, 16))
    assert got.cell == (16, 16) and got.agreement == pytest.approx(agreement(labels, g16))
    assert got.curve == choice.curve
    # Nothing fits: the largest cell (candidates reaching 16 go on to 32).
    assert cell_within_budget(labels, choice, (4, 8, 16), 0.0).cell == (32, 32)
    assert cell_within_budget(labels, choice, (4, 8), 0.0).cell == (8, 8)


def test_cell_within_budget_gives_up_at_most_its_share_of_label_agreement():
    """Under a budget of no bytes the grid grows only while its agreement stays within
    BUDGET_AGREEMENT_LOSS of the choice's target (005t2 at cell 24 kept 0.76x of its
    classification's mIoU, against 0.96x at 16)."""
    from dataclasses import replace

    from terratheme.core.convert.cell_choice import BUDGET_AGREEMENT_LOSS
    from terratheme.core.convert.labels_to_grid import vote_grid
    from terratheme.core.model.grid import IndexGrid

    # Stripes 32 px wide: the label view keeps over 0.9 of them up to cell 12, 0.79 at 16.
    labels = np.kron(np.arange(12) % 2, np.ones(32, int))[None].repeat(96, 0).astype(np.uint8)
    ladder = (4, 6, 8, 12, 16)
    scores = {c: agreement(labels, IndexGrid(vote_grid(labels, (c, c)), (c, c)))
              for c in ladder}
    assert min(scores[c] for c in (4, 6, 8, 12)) >= 0.9 > 0.9 - BUDGET_AGREEMENT_LOSS > scores[16]
    choice = CellChoice((4, 4), 1.0, 0.9, (), True)
    got = cell_within_budget(labels, choice, ladder, 0.0)
    assert got.cell == (12, 12) and got.agreement == pytest.approx(scores[12])
    # A target of 0.5 lets it go on to the largest (a ladder reaching 16 goes on to 32).
    assert cell_within_budget(labels, replace(choice, target=0.5), ladder, 0.0).cell == (32, 32)


def test_cell_within_budget_measures_a_samples_agreement_on_its_windows_apart():
    """A region sample's windows side by side meet at seams that are no borders of the
    photo: a large cell's vertex there mixes two windows (005t4 tiled 3 x 3: cell 12 kept
    0.846 of the joined sample's labels, 0.855 of its windows', 0.857 of the whole photo's)."""
    left, right = np.zeros((16, 16), np.uint8), np.ones((16, 16), np.uint8)
    joined = np.hstack([left, right])
    choice = CellChoice((4, 4), 1.0, 0.9, (), True)
    # Each window holds one class: every cell keeps all of it, so the grid grows to the top.
    apart = cell_within_budget(joined, choice, (4, 8, 16), 0.0, windows=[left, right])
    assert apart.cell == (32, 32) and apart.agreement == 1.0
    # Joined, the seam's vertices cost a quarter of the labels at cell 16.
    assert cell_within_budget(joined, choice, (4, 8, 16), 0.0).cell == (8, 8)


def test_cell_within_budget_goes_past_the_automatic_cap_unless_capped_lower():
    rng = np.random.default_rng(6)
    # Random 8-pixel blocks: a cell-16 grid of them overflows a budget of no bytes.
    labels = np.kron(rng.integers(0, 3, (24, 24)), np.ones((8, 8), int)).astype(np.uint8)
    choice = CellChoice((16, 16), 0.5, 0.0, (), True)  # no agreement target: bytes decide
    # convert's candidates reach 16: the grid goes on to 24 and 32 (192 = 6 cells of 32).
    assert cell_within_budget(labels, choice, CONVERT_CELL_CANDIDATES, 0.0).cell == (32, 32)
    got = cell_within_budget(labels, choice, CONVERT_CELL_CANDIDATES, 1e9)
    assert got.cell == (16, 16)
    # A road theme's candidates stop at 8, and so does the grid.
    road = road_candidates(CONVERT_CELL_CANDIDATES, ["road"])
    small = CellChoice((4, 4), 0.5, 0.0, (), True)
    assert cell_within_budget(labels, small, road, 0.0).cell == (8, 8)


def test_grid_budget_is_a_share_of_the_map_budget():
    from terratheme.core.convert.step import GRID_SHARE, grid_budget

    assert grid_budget(ColourMapOptions(budget=0.08), 10**6) == pytest.approx(0.08 * GRID_SHARE)
    assert grid_budget(ColourMapOptions(target=2.0), 10**6) is None
    assert grid_budget(None, 10**6) is None


def test_a_tiny_photo_gets_the_least_area_bytes():
    from terratheme.core.convert.colour_fit import MIN_AREA_BYTES
    from terratheme.core.convert.step import GRID_SHARE, grid_budget

    opts = ColourMapOptions(budget=0.04)
    assert opts.area_bytes(128 * 96) == MIN_AREA_BYTES
    assert opts.area_bytes(1000 * 1000) == 5000
    assert grid_budget(opts, 128 * 96) == pytest.approx(
        GRID_SHARE * MIN_AREA_BYTES * 8 / (128 * 96))
    assert grid_budget(opts, 1000 * 1000) == pytest.approx(GRID_SHARE * 0.04)


def test_a_budget_map_is_drawn_at_the_unsharp_mask_that_scores_best():
    from terratheme.core.fidelity import structure_similarity
    from terratheme.core.render.colour_map import apply_colour_map

    # 4-texel streets every 32 rows and columns: the block means and the codec soften them.
    photo = np.full((128, 128, 3), 200, np.uint8)
    for k in range(4):
        photo[32 * k + 12:32 * k + 16] = 60
        photo[:, 32 * k + 12:32 * k + 16] = 60
    render = np.full((128, 128, 3), 128, np.uint8)
    opts = ColourMapOptions(budget=1.0, budget_scales=(8,))
    sharp = choose_colour_map(photo, render, opts).colour_map
    assert sharp.sharpen in opts.budget_sharpens and sharp.sharpen > 0
    plain = sharp.redrawn(0, (128, 128))
    assert plain.data == sharp.data

    def s4(cmap):
        return structure_similarity(apply_colour_map(render.copy(), cmap, (0, 0, 128, 128)),
                                    photo, 4)

    assert s4(sharp) > s4(plain)
    # Only the amounts offered are tried.
    none = choose_colour_map(photo, render, ColourMapOptions(budget=1.0, budget_scales=(8,),
                                                             budget_sharpens=(0,)))
    assert none.colour_map.sharpen == 0 and none.colour_map.data == sharp.data
    with pytest.raises(TerrathemeError, match="budget_sharpens"):
        ColourMapOptions(budget_sharpens=(9,))


def test_a_map_made_tile_by_tile_takes_the_unsharp_mask_it_is_given(tmp_path):
    from terratheme.core.convert.colour_fit import colour_map_from_file
    from terratheme.core.io.images import write_image
    from terratheme.core.model.grid import IndexGrid

    rng = np.random.default_rng(3)
    photo = rng.integers(30, 220, (100, 140, 3), dtype=np.uint8)
    write_image(tmp_path / "p.png", photo)
    grid = IndexGrid(rng.integers(0, 2, (8, 10)).astype(np.uint8), (16, 16))
    themes = [np.full((8, 8, 3), 90, np.uint8), np.full((8, 8, 3), 160, np.uint8)]
    plain = colour_map_from_file(tmp_path / "p.png", grid, themes, 16,
                                 options=ColourMapOptions(codec="png"), tile=48).colour_map
    sharp = colour_map_from_file(tmp_path / "p.png", grid, themes, 16,
                                 options=ColourMapOptions(codec="png"), tile=48,
                                 sharpen=4).colour_map
    assert sharp.sharpen == 4 and sharp.data == plain.data
    assert np.array_equal(sharp.pixels, plain.redrawn(4, grid.texture_size).pixels)
    # A map to a dE8 target is never sharpened.
    target = colour_map_from_file(tmp_path / "p.png", grid, themes, 16,
                                  options=ColourMapOptions(codec="png", target=2.0), tile=48,
                                  sharpen=4).colour_map
    assert target.sharpen == 0


def _two_class_scene(seed=11):
    """A photo of two flat-coloured classes in blobs (with grain), its grid at cell 8 (the
    class of each vertex's texel) and neutral themes: the grid predicts the photo's colours."""
    from terratheme.core.model.grid import IndexGrid

    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:128, 0:160]
    blobs = (np.sin(xx / 9.0) + np.cos(yy / 7.0) + 0.5 * np.sin((xx + yy) / 5.0)) > 0.3
    colours = np.array([[70, 90, 40], [210, 195, 170]], np.float64)
    photo = colours[blobs.astype(int)] + rng.normal(0, 5, (128, 160, 3))
    photo = np.clip(photo, 0, 255).astype(np.uint8)
    grid = IndexGrid(blobs[::8, ::8].astype(np.uint8)[:17, :21].copy(), (8, 8))
    grid = IndexGrid(np.pad(grid.indices, ((0, 17 - grid.indices.shape[0]),
                                           (0, 21 - grid.indices.shape[1])), mode="edge"),
                     (8, 8))
    library = ThemeLibrary([flat_theme("dark", (128, 128, 128)),
                            flat_theme("light", (128, 128, 128))])
    return photo, grid, library


def test_a_budget_map_is_coded_over_the_grids_prediction_where_that_scores_better():
    from terratheme.core.convert.colour_fit import budget_score, reference
    from terratheme.core.convert.step import fit_colour_map
    from terratheme.core.model.map_prediction import class_prediction
    from terratheme.core.render.renderer import render_cells

    photo, grid, library = _two_class_scene()
    opts = ColourMapOptions(budget=0.02)
    with_grid = fit_colour_map(photo, grid, library, opts, packed=60)
    render = render_cells(grid, library.textures)
    without = choose_colour_map(photo, render, opts, reserved=60)
    cmap = with_grid.colour_map
    assert cmap.colours is not None and without.colour_map.colours is None
    assert cmap.nbytes <= opts.map_bytes(photo.shape[0] * photo.shape[1], 60)
    # The prediction is the grid's, from the colours the map ships.
    assert np.array_equal(cmap.prediction, class_prediction(
        grid.indices, grid.cell, np.asarray(cmap.colours, np.uint8), cmap.coded_scale,
        cmap.coded_shape))
    # Never worse by the search's own score than the map made without the grid.
    ref = reference(photo, sigmas=(), factors=(4, 8))
    from terratheme.core.convert.colour_fit import _quick_photo
    quick = _quick_photo(photo)
    h, w = photo.shape[:2]

    def score(c):
        return budget_score(ref, quick, apply_colour_map(render[:h, :w].copy(), c,
                                                         (0, 0, w, h)))[0]

    assert score(cmap) > score(without.colour_map)


def test_a_map_made_tile_by_tile_is_coded_over_the_prediction_when_asked(tmp_path):
    from terratheme.core.convert.colour_fit import colour_map_from_file, grid_prediction
    from terratheme.core.io.images import write_image
    from terratheme.core.model.project import ThematicTexture, load_project, save_project
    from terratheme.core.render.renderer import render_cells

    photo, grid, library = _two_class_scene(12)
    write_image(tmp_path / "p.png", photo)
    opts = ColourMapOptions(budget=0.02)
    kwargs = {"options": opts, "tile": 48, "reserved": 60}
    fitted = colour_map_from_file(tmp_path / "p.png", grid, library.textures, 4,
                                  predicted=True, **kwargs).colour_map
    plain = colour_map_from_file(tmp_path / "p.png", grid, library.textures, 4,
                                 **kwargs).colour_map
    assert fitted.colours is not None and plain.colours is None
    assert fitted.nbytes <= opts.map_bytes(photo.shape[0] * photo.shape[1], 60)
    # Its colours and prediction are the whole map's (the tiles' gains are the block ratio).
    stored = np.clip(np.rint(fit_gain(photo, render_cells(grid, library.textures), 4, 0)
                             * 128), 0, 255).astype(np.uint8)
    want = grid_prediction(stored, grid, len(library), 4, "avif")
    assert np.abs(np.asarray(fitted.colours, int) - want["colours"]).max() <= 1
    # What the project file gives back is the map the tiles made.
    save_project(tmp_path / "m.ttproj", ThematicTexture(grid, library, {}, colour_map=fitted))
    assert np.array_equal(load_project(tmp_path / "m.ttproj").colour_map.pixels, fitted.pixels)
