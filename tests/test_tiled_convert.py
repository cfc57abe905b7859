"""The tiled grid path equals the whole-image path."""

from __future__ import annotations

import numpy as np
import pytest
from terratheme.core.convert.cell_choice import CONVERT_CELL_CANDIDATES, DEFAULT_CELL_CANDIDATES
from terratheme.core.convert.labels_to_grid import vote_grid
from terratheme.core.convert.photo import ConvertOptions, convert_photo
from terratheme.core.convert.tile_vote import vertex_tiles
from terratheme.core.convert.tiled import convert_file_tiled, grid_from_file
from terratheme.core.errors import TerrathemeError
from terratheme.core.io.images import write_image
from terratheme.core.io.tiles import Scheduler


def _classes(pixels: np.ndarray) -> np.ndarray:
    """A per-pixel classifier: the brightest channel, 1..3."""
    return np.argmax(pixels[..., :3], axis=2).astype(np.uint8) + 1


@pytest.mark.parametrize(("cell", "tile"), [((8, 8), 64), ((5, 7), 40), ((16, 4), 33), (1, 17)])
def test_tiled_grid_equals_whole_vote(tmp_path, cell, tile):
    rng = np.random.default_rng(7)
    coarse = rng.integers(0, 256, (12, 15, 3), dtype=np.uint8)
    img = np.kron(coarse, np.ones((9, 9, 1), np.uint8))[:101, :131]
    img = np.clip(img.astype(int) + rng.integers(-40, 40, img.shape), 0, 255).astype(np.uint8)
    path = tmp_path / "photo.tif"
    write_image(path, img, tile=32)
    whole = vote_grid(_classes(img), cell if isinstance(cell, tuple) else (cell, cell))
    lut = np.arange(256)
    lut[3] = 1  # merge two classes, as a theme mapping may
    want = vote_grid(lut.astype(np.uint8)[_classes(img)], cell if isinstance(cell, tuple)
                     else (cell, cell))
    for sched in Scheduler:
        got = grid_from_file(path, cell, _classes, tile=tile, overlap=3, scheduler=sched)
        assert np.array_equal(got.indices, whole)
    assert np.array_equal(grid_from_file(path, cell, _classes, lut=lut, tile=tile).indices, want)


def test_vertex_tiles_own_each_vertex_once():
    tiles = vertex_tiles((50, 30), (4, 3), 12, 5)
    hits = np.zeros((11, 14), int)
    for win in tiles:
        (r0, r1), (c0, c1) = win.rows, win.cols
        hits[r0:r1, c0:c1] += 1
        assert 0 <= win.rx <= win.x and win.x + win.w <= win.rx + win.rw <= 50
    assert (hits == 1).all()


def test_errors(tmp_path):
    path = tmp_path / "p.png"
    write_image(path, np.zeros((8, 8, 3), np.uint8))
    with pytest.raises(TerrathemeError, match="returned"):
        grid_from_file(path, 4, lambda p: np.zeros((2, 2), np.uint8))
    with pytest.raises(TerrathemeError, match="overlap"):
        grid_from_file(path, 4, _classes, overlap=-1)
    with pytest.raises(TerrathemeError, match="256 integers"):
        grid_from_file(path, 4, _classes, lut=[0, 1])


def test_a_short_last_vertex_block_joins_the_one_before():
    # 256 px at cell 16: 17 vertices a side; blocks of 4 -> 4, 4, 4, 5 (no block of 1).
    tiles = vertex_tiles((256, 256), (16, 16), 64, 0)
    assert len(tiles) == 16
    assert sorted({t.rows for t in tiles}) == [(0, 4), (4, 8), (8, 12), (12, 17)]
    # A last block of at least half a block stays on its own: 288 px, 19 vertices -> ..., 3.
    assert sorted({t.cols for t in vertex_tiles((288, 16), (16, 16), 64, 0)})[-1] == (16, 19)


def _three_regions(tmp_path):
    """Green left, sand above blue on the right, a little noise: (pixels, tiled TIFF path)."""
    rng = np.random.default_rng(1)
    img = np.empty((192, 256, 3), np.float64)
    img[:, :128] = (40, 120, 40)
    img[:96, 128:] = (225, 200, 140)
    img[96:, 128:] = (40, 90, 200)
    img = np.clip(img + rng.normal(0, 4, img.shape), 0, 255).astype(np.uint8)
    path = tmp_path / "photo.tif"
    write_image(path, img, tile=64)
    return img, path


def test_auto_cell_of_a_one_tile_photo_is_the_whole_image_conversions(tmp_path):
    # Three flat regions (green left; sand above blue on the right), a little noise:
    # any cell keeps the labels, so the choice is the largest candidate allowed.
    img, path = _three_regions(tmp_path)
    whole = convert_photo(img, ConvertOptions()).project
    tiled = convert_file_tiled(path, None, "auto", tile=1024)
    # The same candidates as convert's: the cell is capped at 16, as the whole image's.
    assert tiled.grid.cell == whole.grid.cell == (max(CONVERT_CELL_CANDIDATES),) * 2
    assert np.array_equal(tiled.grid.indices, whole.grid.indices)
    assert tiled.library.names == whole.library.names
    # Other candidates still reach the choice (the flat photo takes a larger cell).
    wide = convert_file_tiled(path, None, "auto", tile=1024, colour_map=None,
                              candidates=DEFAULT_CELL_CANDIDATES)
    assert wide.grid.cell[0] > max(CONVERT_CELL_CANDIDATES)


def test_a_road_theme_keeps_cells_of_at_most_8_on_the_tiled_path(tmp_path):
    from terratheme.core.convert.cell_choice import ROAD_MAX_CELL

    # The three flat regions above take the largest cell, unless a theme is named road.
    _, path = _three_regions(tmp_path)
    plain = convert_file_tiled(path, None, "auto", tile=1024, names=["grass", "sand", "water"])
    road = convert_file_tiled(path, None, "auto", tile=1024, names=["grass", "road", "water"])
    assert "road" in road.library.names
    assert plain.grid.cell[0] > ROAD_MAX_CELL >= road.grid.cell[0]


def test_a_theme_the_cut_named_road_leaves_the_cell_as_the_whole_photos(tmp_path, monkeypatch):
    import terratheme.core.themes.from_photo as from_photo

    # Unnamed cut themes are named by appearance; when that gives "road" the whole photo's
    # cell is not capped (only a caller's or a model's road is), so neither is the region's.
    monkeypatch.setattr(from_photo, "shipped_names",
                        lambda appearances, *_: ["road"] * len(appearances))
    img, path = _three_regions(tmp_path)
    whole = convert_photo(img, ConvertOptions()).project
    tiled = convert_file_tiled(path, None, "auto", tile=1024)
    assert "road" in tiled.library.names and tiled.library.names == whole.library.names
    assert tiled.grid.cell == whole.grid.cell == (max(CONVERT_CELL_CANDIDATES),) * 2


class OneClass:
    """A trained classifier's stand-in: every pixel is class 1."""

    classes = (1,)
    options = None

    def predict(self, pixels, progress=None):
        from terratheme.core.classify.photo import prepare_photo
        from terratheme.core.classify.result import Classification

        ones = np.ones(prepare_photo(pixels).rgb.shape[:2], np.uint8)
        return Classification(ones, ones.astype(np.float32), self.classes)


def _detail_energy(texture: np.ndarray) -> float:
    """Mean square of a detail theme's relative contrast about its neutral 128."""
    return float(((texture[..., :3].astype(np.float64).mean(axis=2) / 128.0 - 1.0) ** 2).mean())


def test_the_region_sample_seams_do_not_reach_the_themes(tmp_path, monkeypatch):
    import terratheme.core.convert.region_sample as rs

    # Issue 34: one class, grey noise of a fixed relative contrast (6%) on a brightness that
    # varies slowly over the photo (40..210). Its detail energy is the same everywhere, so
    # the theme's (its detail scaled to the class's energy) is the same whether measured on
    # the whole photo or on windows of it. Windows side by side without a gap add their
    # seams, steps of up to 170 levels, to the class's detail and to the theme cut there.
    rng = np.random.default_rng(3)
    yy, xx = np.mgrid[0:384, 0:384] / 384.0
    level = 125 + 85 * np.sin(2 * np.pi * 1.5 * xx) * np.sin(2 * np.pi * 1.5 * yy)
    grey = level * (1 + 0.06 * rng.standard_normal(level.shape))
    img = np.repeat(np.clip(np.rint(grey), 0, 255).astype(np.uint8)[..., None], 3, axis=2)
    path = tmp_path / "photo.tif"
    write_image(path, img, tile=64)
    monkeypatch.setattr(rs, "SAMPLE_PIECE", 48)
    monkeypatch.setattr(rs, "SAMPLE_GRID", 3)
    whole = convert_photo(img, ConvertOptions(cell=16), model=OneClass()).project
    tiled = convert_file_tiled(path, OneClass(), 16, tile=128)
    # No theme for the gaps between the sample's windows.
    assert len(tiled.library) == len(whole.library) == 1
    # Both are the class's energy, about 0.0035 (0.06^2 less the blur's share); the estimate
    # from 9 x 48^2 sample pixels is within a few percent of the whole photo's (its relative
    # error about sqrt(2 / 20736) = 1%; uint8 rounding adds 1/12 level^2, 0.03%).
    ratio = _detail_energy(tiled.library[0].texture) / _detail_energy(whole.library[0].texture)
    assert 0.9 < ratio < 1.1


def test_transparent_pixels_keep_their_theme_and_the_gaps_bring_none(tmp_path, monkeypatch):
    import terratheme.core.convert.region_sample as rs

    # The sample's gaps are no data too: their theme is dropped unless a window holds
    # transparent pixels of the photo (then the whole photo's themes have it as well).
    monkeypatch.setattr(rs, "SAMPLE_PIECE", 48)
    monkeypatch.setattr(rs, "SAMPLE_GRID", 3)
    img, _ = _three_regions(tmp_path)
    rgba = np.dstack([img, np.full(img.shape[:2], 255, np.uint8)])
    rgba[:, :40, 3] = 0  # the left 40 columns: in every window at x = 0 (the first column's)
    for name, pixels in (("opaque", img), ("holes", rgba)):
        path = tmp_path / f"{name}.tif"
        write_image(path, pixels, tile=64)
        whole = convert_photo(pixels, ConvertOptions(cell=8)).project
        tiled = convert_file_tiled(path, None, 8, tile=64)
        assert tiled.library.names == whole.library.names
        assert ("no data" in tiled.library.names) == (name == "holes")


def test_fully_transparent_tiles_are_no_data(tmp_path, monkeypatch):
    import terratheme.core.convert.region_sample as rs

    # A photo whose left half is transparent: its tiles and sample windows there hold no
    # pixel to classify (the classifier refuses such a photo); the region path makes them
    # no data, as the whole photo's transparent pixels are.
    monkeypatch.setattr(rs, "SAMPLE_PIECE", 48)
    monkeypatch.setattr(rs, "SAMPLE_GRID", 3)
    img, _ = _three_regions(tmp_path)
    rgba = np.dstack([np.concatenate([img, img], axis=1), np.full((192, 512), 255, np.uint8)])
    rgba[:, :256, 3] = 0
    path = tmp_path / "holes.tif"
    write_image(path, rgba, tile=64)
    whole = convert_photo(rgba, ConvertOptions(cell=8)).project
    tiled = convert_file_tiled(path, None, 8, tile=64)
    # (Names by appearance may differ: 48 px windows show the themes little of the photo.)
    assert len(tiled.library) == len(whole.library) and "no data" in whole.library.names
    no_data = tiled.library.names.index("no data")
    # Every vertex left of the opaque half's first cell (x < 256 - 8) is no data.
    assert (tiled.grid.indices[:, :256 // 8] == no_data).all()
    assert (tiled.grid.indices[:, 256 // 8 + 1:] != no_data).all()


def _coarse_classes(pixels: np.ndarray) -> np.ndarray:
    """A classifier on 8 x 8 blocks from the array's origin (as the features' coarse grid):
    bright (2) or dark (1) by the block's mean, each pixel its block's."""
    h, w = pixels.shape[:2]
    y = np.zeros((-(-h // 8) * 8, -(-w // 8) * 8), np.float32)
    y[:h, :w] = pixels[..., :3].mean(axis=2)
    means = y.reshape(y.shape[0] // 8, 8, y.shape[1] // 8, 8).mean(axis=(1, 3))
    return np.where(np.kron(means, np.ones((8, 8))) > 128, 2, 1)[:h, :w].astype(np.uint8)


@pytest.mark.parametrize(("cell", "overlap"), [(12, 27), (16, 128), (16, 279), (12, 128)])
def test_a_coarse_classifier_gives_the_whole_photos_grid_at_any_overlap(tmp_path, cell,
                                                                        overlap):
    # Found: a read window starting off the classifier's 8 px lattice (a cell of 12, or an
    # overlap of 279) shifted its coarse blocks, and 131 of 17,000 vertices differed.
    rng = np.random.default_rng(5)
    img = rng.integers(0, 256, (300, 420, 3), dtype=np.uint8)
    path = tmp_path / "photo.tif"
    write_image(path, img, tile=32)
    want = vote_grid(_coarse_classes(img), (cell, cell), keep_specks=False)
    got = grid_from_file(path, cell, _coarse_classes, tile=64, overlap=overlap,
                         keep_specks=False)
    assert np.array_equal(got.indices, want)
