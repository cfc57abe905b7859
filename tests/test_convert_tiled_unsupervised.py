"""``terratheme convert BIG --tile N`` without a model: unsupervised themes, tile by tile."""

from __future__ import annotations

import numpy as np
import pytest
import terratheme.core.convert.region_sample as rs
from terratheme.app.cli import main
from terratheme.core.classify import UnsupervisedOptions, fit_unsupervised
from terratheme.core.convert.photo import ConvertOptions, convert_photo
from terratheme.core.convert.region_sample import (
    fit_unsupervised_region,
    region_sample,
    sample_windows,
)
from terratheme.core.convert.tiled import convert_file_tiled
from terratheme.core.errors import TerrathemeError
from terratheme.core.io.images import write_image
from terratheme.core.model.project import load_project

GREEN, SAND, BLUE = (40, 120, 40), (225, 200, 140), (40, 90, 200)


def quadrants(h=192, w=256, seed=1):
    """Green left half; right half sand above, blue below; a little noise."""
    rng = np.random.default_rng(seed)
    img = np.empty((h, w, 3), np.float64)
    img[:, : w // 2] = GREEN
    img[: h // 2, w // 2 :] = SAND
    img[h // 2 :, w // 2 :] = BLUE
    return np.clip(img + rng.normal(0, 4, img.shape), 0, 255).astype(np.uint8)


def _run(args):
    return main(["convert", *map(str, args)])


def test_tiled_unsupervised_equals_whole_image(tmp_path):
    img = quadrants()
    photo = tmp_path / "big.tif"
    write_image(photo, img, tile=32)
    assert _run([photo, tmp_path / "whole.ttproj", "--cell", "8"]) == 0
    assert _run([photo, tmp_path / "tiled.ttproj", "--cell", "8", "--tile", "64"]) == 0
    whole, tiled = load_project(tmp_path / "whole.ttproj"), load_project(tmp_path / "tiled.ttproj")
    assert len(tiled.library) == len(whole.library) == 3
    a, b = whole.grid.indices, tiled.grid.indices
    assert a.shape == b.shape == (192 // 8 + 1, 256 // 8 + 1)
    assert (a == b).mean() > 0.99
    # Labels consistent across tiles: each quadrant's interior is one index, three distinct.
    g, s, bl = b[2:-2, 2:14], b[2:10, 18:-2], b[14:-2, 18:-2]
    assert len(np.unique(g)) == len(np.unique(s)) == len(np.unique(bl)) == 1
    assert len({g[0, 0], s[0, 0], bl[0, 0]}) == 3


def test_sample_windows_spread_over_the_photo_or_are_the_photo():
    assert sample_windows((256, 192), piece=96, grid=3) == [[(0, 0, 256, 192)]]
    rows = sample_windows((1000, 700), piece=96, grid=3, align=8)
    ny, nx = len(rows), len(rows[0])
    assert ny * nx <= 9 and nx >= ny and all(len(r) == nx for r in rows)
    for j, row in enumerate(rows):
        for i, (x, y, w, h) in enumerate(row):
            assert (w, h) == (96, 96) and x % 8 == 0 and y % 8 == 0
            # Inside the photo, starting in its own cell of the ny x nx division.
            assert x + w <= 1000 and y + h <= 700
            assert i * 1000 // nx - 8 < x < (i + 1) * 1000 // nx
            assert j * 700 // ny - 8 < y < (j + 1) * 700 // ny
    # A strip narrower than a window: one column of windows down it.
    strip = sample_windows((50, 5000), piece=96, grid=3)
    assert all(len(r) == 1 and r[0][2:] == (50, 96) for r in strip) and len(strip) == 9


def test_the_region_model_is_the_whole_photos(tmp_path):
    img = quadrants()
    photo = tmp_path / "big.tif"
    write_image(photo, img, tile=32)
    # Small feature windows and sample budget: many tiles, a stride of several pixels.
    opts = UnsupervisedOptions(tile=64, max_samples=700)
    region = fit_unsupervised_region(photo, options=opts)
    whole = fit_unsupervised(img, options=opts)
    assert np.array_equal(region.centres, whole.centres) and len(whole.classes) == 3
    assert np.array_equal(fit_unsupervised_region(photo, names=["a", "b"], options=opts).classes,
                          fit_unsupervised(img, themes=2, options=opts).classes)


def periodic(repeat=4, side=64, seed=2):
    """A mosaic of one photo repeated: blue water in the middle of each copy, sand around."""
    rng = np.random.default_rng(seed)
    base = np.empty((side, side, 3), np.float64)
    base[:] = SAND
    base[side // 4 : 3 * side // 4, side // 4 : 3 * side // 4] = BLUE
    img = np.tile(base, (repeat, repeat, 1))
    return np.clip(img + rng.normal(0, 4, img.shape), 0, 255).astype(np.uint8)


@pytest.fixture
def mosaic_file(tmp_path, monkeypatch):
    """(photo, its tiled TIFF) of :func:`periodic`, with a sample of 3 x 3 windows of 48 px."""
    img = periodic()
    photo = tmp_path / "mosaic.tif"
    write_image(photo, img, tile=32)
    monkeypatch.setattr(rs, "SAMPLE_PIECE", 48)
    monkeypatch.setattr(rs, "SAMPLE_GRID", 3)
    return img, photo


def test_a_periodic_mosaic_gets_the_whole_photos_themes(mosaic_file):
    # Issue 34: windows at the centres of a 4 x 4 division of a 4 x 4 mosaic all saw the
    # same place of the repeated photo (water only), so the region got other themes.
    img, photo = mosaic_file
    sample = region_sample(photo, lambda p: np.ones(p.shape[:2], np.uint8), 0)
    assert len(sample.windows) == 9 and sample.joined(sample.rgb).shape == (144, 144, 3)
    x, y, w, h = sample.windows[4]
    assert (sample.pieces(sample.rgb)[4] == img[y:y + h, x:x + w]).all()
    whole = convert_photo(img, ConvertOptions(cell=8)).project
    tiled = convert_file_tiled(photo, None, 8, tile=64)
    assert sorted(tiled.library.names) == sorted(whole.library.names)
    assert len(whole.library) == 2
    # The whole photo, larger than its sample, cuts its themes where the tiles do.
    by_name = {t.name: t.texture for t in tiled.library}
    assert all(np.array_equal(t.texture, by_name[t.name]) for t in whole.library)
    # The same theme at (almost) every vertex.
    named_whole = np.array(whole.library.names)[whole.grid.indices]
    named_tiled = np.array(tiled.library.names)[tiled.grid.indices]
    assert (named_whole == named_tiled).mean() > 0.98
    assert tiled.metadata["created_by"] == "terratheme convert (tiled)"


def _blue_or_not(pixels):
    """Labels of :func:`periodic`'s photo: 2 where blue, 1 elsewhere."""
    return np.where(pixels[:, :, 2] > 150, 2, 1).astype(np.uint8)


def test_a_photo_in_memory_has_its_files_region_sample(mosaic_file):
    img, path = mosaic_file
    classify = _blue_or_not
    from_file = region_sample(path, classify, 0)
    in_memory = rs.photo_sample(img, classify(img))
    assert in_memory.windows == from_file.windows and in_memory.places == from_file.places
    assert np.array_equal(in_memory.rgb, from_file.rgb)
    assert np.array_equal(in_memory.labels, from_file.labels)
    assert set(np.unique(in_memory.labels)) == {0, 1, 2} and in_memory.gap == 48
    # A photo no larger than the sample is its own sample.
    assert rs.photo_sample(img[:144, :144], classify(img[:144, :144])) is None


def _outside_the_sample(img, side=4):
    """(y, x) of a ``side`` x ``side`` block no sample window of ``img`` covers."""
    covered = np.zeros(img.shape[:2], np.int64)
    for row in rs.sample_windows(img.shape[1::-1], rs.SAMPLE_PIECE, rs.SAMPLE_GRID):
        for x, y, w, h in row:
            covered[y:y + h, x:x + w] = 1
    sums = np.pad(covered, ((1, 0), (1, 0))).cumsum(0).cumsum(1)
    inside = sums[side:, side:] - sums[:-side, side:] - sums[side:, :-side] + sums[:-side, :-side]
    ys, xs = np.nonzero(inside == 0)
    return int(ys[0]), int(xs[0])


def test_a_sample_keeps_the_photos_no_data_and_every_class(mosaic_file):
    from terratheme.core.convert.step import sample_themes
    from terratheme.core.themes.library import Theme, ThemeLibrary

    img, _ = mosaic_file
    labels = _blue_or_not(img)
    y, x = _outside_the_sample(img)
    # Transparent pixels the windows miss still map to the no-data theme.
    with_gap = labels.copy()
    with_gap[y:y + 4, x:x + 4] = 0
    sample = rs.photo_sample(img, with_gap)
    assert sample.no_data and not (sample.joined(sample.labels) == 0).any()
    mapping = sample_themes(sample, (1, 2))
    assert mapping.library[int(mapping.lut[0])].name == "no data"
    assert len(mapping.library) == 3
    # Without them, the gaps' no-data theme is dropped; a given library loses nothing.
    assert len(sample_themes(rs.photo_sample(img, labels), (1, 2)).library) == 2
    library = ThemeLibrary(Theme(n, (60 * i, 90, 90), np.full((8, 8, 3), 90 + i, np.uint8))
                           for i, n in enumerate(("sand", "water", "road")))
    kept = sample_themes(rs.photo_sample(img, labels), (1, 2), library)
    assert kept.library.names == ["sand", "water", "road"] and max(kept.lut[[1, 2]]) <= 2
    # Windows moved to cover a pixel hold it; the others stay where they were.
    moved = rs.photo_sample(img, labels, covering=[(x, y)])
    assert sum(wx <= x < wx + w and wy <= y < wy + h for wx, wy, w, h in moved.windows) == 1
    assert sum(a != b for a, b in zip(moved.windows, sample.windows, strict=True)) == 1


def test_sample_windows_move_onto_each_pixel_they_must_cover():
    rows = sample_windows((1000, 700), piece=96, grid=3, align=8)
    windows = [w for row in rows for w in row]
    # A pixel a window is centred on moves nothing.
    x, y, *_ = windows[4]
    assert sample_windows((1000, 700), piece=96, grid=3, align=8,
                          covering=[(x + 48, y + 48)]) == rows
    # Two pixels in the same cell no window holds: its window moves onto the first, the
    # nearest other window onto the second; each pixel in a window, corners aligned.
    spots = [(p, q) for p in range(0, 1000, 7) for q in range(0, 700, 7)
             if not any(wx <= p < wx + 96 and wy <= q < wy + 96 for wx, wy, *_ in windows)]
    first = spots[0]
    second = next(p for p in spots if abs(p[0] - first[0]) + abs(p[1] - first[1]) > 200
                  and p[0] * 3 // 1000 == first[0] * 3 // 1000
                  and p[1] * 3 // 700 == first[1] * 3 // 700)
    moved = [w for row in sample_windows((1000, 700), piece=96, grid=3, align=8,
                                         covering=[first, second]) for w in row]
    assert sum(a != b for a, b in zip(moved, windows, strict=True)) == 2
    for px, py in (first, second):
        assert any(wx <= px < wx + 96 and wy <= py < wy + 96 for wx, wy, *_ in moved)
    assert all(wx % 8 == 0 and wy % 8 == 0 and wx + 96 <= 1000 and wy + 96 <= 700
               for wx, wy, *_ in moved)


def test_a_window_moved_off_a_class_it_alone_held_is_made_up_for():
    from terratheme.core.convert.region_sample import covering_sample

    # Review: class 3 lies only in the first window's far corner; class 2 only outside every
    # window of the same cell. That window moves onto class 2 and loses class 3, whose spot
    # the moved window then holds at its edge: a window must still move onto class 3.
    size = 4000
    rows = sample_windows((size, size))
    windows = [w for row in rows for w in row]
    x0, y0, pw, ph = rows[0][0]
    labels = np.ones((size, size), np.uint8)
    labels[y0 + ph - 10:y0 + ph, x0 + pw - 10:x0 + pw] = 3

    def held(x, y):
        return any(a <= x < a + pw and b <= y < b + ph for a, b, *_ in windows)

    cell = size // len(rows)
    x2, y2 = next((x, y) for y in range(0, cell, 8) for x in range(0, cell, 8)
                  if not held(x, y) and not held(x + 15, y + 15) and abs(x - x0) > 200)
    labels[y2:y2 + 16, x2:x2 + 16] = 2
    rgb = np.zeros((size, size, 3), np.uint8)
    sample = rs.photo_sample(rgb, labels)
    assert set(np.unique(sample.labels)) == {0, 1, 3}
    lut = np.arange(256, dtype=np.uint8)
    covered = covering_sample(sample, (1, 2, 3), lut, labels, (1, 1), (size, size),
                              lambda covering: rs.photo_sample(rgb, labels, covering=covering))
    assert set(np.unique(covered.labels)) == {0, 1, 2, 3}


def test_class_spots_is_the_middle_of_a_missing_classes_densest_window(monkeypatch):
    from terratheme.core.convert.region_sample import RegionSample, class_spots

    monkeypatch.setattr(rs, "SAMPLE_PIECE", 3)
    labels = np.ones((4, 4), np.uint8)
    sample = RegionSample([(0, 0, 4, 4)], [(0, 0)], np.zeros((4, 4, 3), np.uint8), labels)
    lut = np.arange(256, dtype=np.uint8)
    # Theme 2 (class 2, absent from the sample) at three points, two of them side by side.
    themes = np.ones((6, 8), np.uint8)
    themes[0, 7] = themes[4, 2] = themes[4, 3] = 2
    # Step (2, 2): a box of 1 x 1 vertices, all three tie: the first in raster order, row 0
    # column 7, is pixel (14, 0).
    assert class_spots(sample, (1, 2), lut, themes, (2, 2), (16, 12)) == [(14, 0)]
    # Step 1: a 3 x 3 box holds both of the pair from rows 3-5, columns 2-3: first (2, 3).
    assert class_spots(sample, (1, 2), lut, themes, (1, 1), (8, 6)) == [(2, 3)]
    # A class the sample holds, or no theme shows, needs no window.
    assert class_spots(sample, (1, 3), lut, themes, (1, 1), (8, 6)) == []


class _BlueRedOrNot:
    """A trained classifier's stand-in: 2 where blue, 3 where red, 1 elsewhere."""

    classes = (1, 2, 3)
    options = None

    def predict(self, pixels, progress=None):
        from terratheme.core.classify.photo import prepare_photo
        from terratheme.core.classify.result import Classification

        rgb = prepare_photo(pixels).rgb
        labels = _blue_or_not(rgb)
        labels[(rgb[..., 0] > 150) & (rgb[..., 1] < 80)] = 3
        return Classification(labels, np.ones(labels.shape, np.float32), self.classes)


def test_a_class_only_between_the_windows_gets_its_own_theme_tiled_and_whole(mosaic_file,
                                                                            tmp_path):
    # A red block outside every sample window: its class had a flat grey placeholder theme.
    # Once the grid shows the class, a window moves onto it, tiled and whole alike.
    img, _ = mosaic_file
    y, x = _outside_the_sample(img, 24)
    red = img.copy()
    red[y:y + 24, x:x + 24] = (200, 40, 40)
    path = tmp_path / "red.tif"
    write_image(path, red, tile=32)
    model = _BlueRedOrNot()
    tiled = convert_file_tiled(path, model, 8, tile=64, colour_map=None)
    whole = convert_photo(red, ConvertOptions(cell=8, colour_map=None), model=model).project
    for project in (tiled, whole):
        theme = project.library[int(project.grid.indices[-(-(y + 8) // 8), -(-(x + 8) // 8)])]
        assert theme.source != "class absent from photo"
        r, g, b = theme.texture[..., :3].reshape(-1, 3).mean(axis=0)
        assert r > 150 and g < 80 and b < 80
    assert [t.texture.tobytes() for t in tiled.library] == \
        [t.texture.tobytes() for t in whole.library]
    # The cell is chosen on the first sample's windows, before any moved: so says the project.
    first = [list(w) for row in rs.sample_windows(red.shape[1::-1], rs.SAMPLE_PIECE,
                                                  rs.SAMPLE_GRID) for w in row]
    auto = convert_file_tiled(path, model, "auto", tile=64, colour_map=None)
    assert auto.metadata["cell_choice"]["measured_on"] == first


def test_transparent_pixels_the_windows_miss_are_no_data_tiled_and_whole(mosaic_file, tmp_path):
    img, _ = mosaic_file
    y, x = _outside_the_sample(img, 24)
    rgba = np.dstack([img, np.full(img.shape[:2], 255, np.uint8)])
    rgba[y:y + 24, x:x + 24, 3] = 0
    path = tmp_path / "collar.tif"
    write_image(path, rgba, tile=32)
    tiled = convert_file_tiled(path, None, 8, tile=64)
    whole = convert_photo(rgba, ConvertOptions(cell=8)).project
    for project in (tiled, whole):
        # The vertex at the block's middle (its cell's corners all inside the block).
        vy, vx = -(-(y + 8) // 8), -(-(x + 8) // 8)
        assert project.library[int(project.grid.indices[vy, vx])].name == "no data"


def test_the_editors_new_themes_are_converts_on_a_photo_larger_than_its_sample(mosaic_file):
    from terratheme.core.edit.classification import ClassifyMode, run_classification
    from terratheme.core.themes.library import ThemeLibrary

    img, _ = mosaic_file
    converted = convert_photo(img, ConvertOptions(cell=8, colour_map=None)).project.library
    update, _ = run_classification(ClassifyMode.UNSUPERVISED_NEW, img, None, ThemeLibrary([]),
                                   (8, 8), (33, 33), None)
    assert len(update.new_themes) == len(converted) == 2
    # The same patches, cut on the same sample windows (the editor renames and recolours).
    assert sorted(t.texture.tobytes() for t in update.new_themes) == \
        sorted(t.texture.tobytes() for t in converted)


def test_fixed_theme_count_and_names(tmp_path):
    photo = tmp_path / "big.tif"
    write_image(photo, quadrants(), tile=32)
    two = convert_file_tiled(photo, None, 8, themes=2, tile=64)
    # Two themes, and the calm twins the grid affords.
    classes = [n for n in two.library.names if not n.endswith(" calm")]
    assert len(classes) == 2
    assert all(n.removesuffix(" calm") in classes for n in two.library.names)
    named = convert_file_tiled(photo, None, 8, names=["water", "sand", "grass"], tile=64)
    assert sorted(named.library.names) == ["grass", "sand", "water"]
    # Each quadrant got the theme nearest its colour.
    idx = named.grid.indices
    names = named.library.names
    assert names[idx[5, 5]] == "grass" and names[idx[5, -5]] == "sand"
    assert names[idx[-5, -5]] == "water"
    with pytest.raises(TerrathemeError, match="only 2 names"):
        convert_file_tiled(photo, None, 8, themes=3, names=["water", "sand"], tile=64)
    with pytest.raises(TerrathemeError, match="assigned by colour"):
        convert_file_tiled(photo, None, 8, names={1: "water"}, tile=64)


def test_tiled_cli_errors(tmp_path, capsys):
    photo = tmp_path / "big.tif"
    write_image(photo, quadrants(h=64, w=64), tile=32)
    mask = tmp_path / "m.png"
    write_image(mask, np.ones((64, 64), np.uint8))
    out = tmp_path / "o.ttproj"
    assert _run([photo, out, "--tile", "64", "--scribbles", mask]) == 2
    assert "--tile does not take --scribbles" in capsys.readouterr().err
    assert _run([photo, out, "--tile", "8"]) == 2
    assert "must be >= 16" in capsys.readouterr().err
    assert _run([photo, out, "--tile", "32", "--themes", "2", "--cell", "8"]) == 0
    assert len(load_project(out).library) == 2


def test_trained_model_refuses_theme_count_and_position_features(tmp_path):
    from terratheme.core.classify import FeatureOptions, SupervisedOptions, train_classifier

    img = quadrants(h=64, w=64)
    photo = tmp_path / "big.tif"
    write_image(photo, img, tile=32)
    mask = np.zeros((64, 64), np.uint8)
    mask[10:13, 5:20], mask[10:13, 40:60] = 1, 2
    model = train_classifier([(img, mask)])
    with pytest.raises(TerrathemeError, match="themes K is for unsupervised"):
        convert_file_tiled(photo, model, 8, themes=3, tile=32)
    placed = train_classifier([(img, mask)],
                              SupervisedOptions(features=FeatureOptions(position=True)))
    with pytest.raises(TerrathemeError, match="pixel positions"):
        convert_file_tiled(photo, placed, 8, tile=32)
    model.save(tmp_path / "m.model")
    out = tmp_path / "o.ttproj"
    assert _run([photo, out, "--tile", "32", "--model", tmp_path / "m.model",
                 "--themes", "3"]) == 2


def test_the_cell_is_chosen_on_each_sample_window_apart():
    from terratheme.core.convert.cell_choice import choose_cell_size

    # Two flat windows of different themes: side by side their seam is a border that only
    # small cells keep; each on its own, any cell keeps every label.
    left, right = np.full((48, 48), 1, np.uint8), np.full((48, 48), 2, np.uint8)
    side_by_side = choose_cell_size(np.hstack([left, right]), 0.99, candidates=(4, 48))
    apart = choose_cell_size([left, right], 0.99, candidates=(4, 48))
    assert side_by_side.cell == (4, 4) and apart.cell == (48, 48)
    assert apart.curve[-1].agreement == 1.0 and apart.curve[-1].grid_bytes == 2 * 2 * 2
    # One window given as a list is the window itself.
    one = choose_cell_size([np.hstack([left, right])], 0.99, candidates=(4, 48))
    assert one == side_by_side
