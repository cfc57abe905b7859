"""The colour-map stage of a whole region: each tile job gets its window of the grid only.

A tile's render from its :func:`core.convert.colour_fit.grid_window` must equal
the whole grid's render of that tile (bit for bit: the map is the serial one),
and what a job and its window weigh when pickled for a worker must be set by
the tile, not by the image.
"""

from __future__ import annotations

import pickle

import numpy as np
import pytest
from terratheme.core.convert.colour_fit import BlockGainJob, grid_window
from terratheme.core.errors import TerrathemeError
from terratheme.core.io.tiles import tile_windows
from terratheme.core.model.colour_map import ColourMap
from terratheme.core.model.grid import IndexGrid
from terratheme.core.render.boundary import BoundaryOptions
from terratheme.core.render.renderer import BlendMode, RenderOptions, render_cells
from terratheme.core.render.rules import SaddleRule


def _themes(rng, k=3):
    return [rng.integers(0, 256, (24, 20, 3), dtype=np.uint8) for _ in range(k)]


@pytest.mark.parametrize("options", [
    RenderOptions(),
    RenderOptions(saddle=SaddleRule.MAIN),
    RenderOptions(boundary=BoundaryOptions()),
    RenderOptions(blend=BlendMode.HISTOGRAM),
], ids=["linear", "main-saddle", "shaped", "histogram"])
def test_a_tile_rendered_from_its_window_equals_the_whole_grid(options):
    rng = np.random.default_rng(5)
    # Two themes in a checkerboard-like noise: saddle cells everywhere (the ring rule counts).
    grid = IndexGrid(rng.integers(0, 2, (23, 31)).astype(np.uint8), (8, 6))
    themes = _themes(rng, 2)
    w, h = grid.texture_size
    whole = render_cells(grid, themes, options=options)
    for tile in (17, 40, (64, 30)):
        for win in tile_windows(w, h, tile):
            origin, block = grid_window(grid, win)
            got = render_cells(block, themes, grid.cell, region=(win.x, win.y, win.w, win.h),
                               options=options, origin=origin)
            assert np.array_equal(got, whole[win.y:win.y1, win.x:win.x1]), (tile, win)


def test_a_window_one_vertex_short_of_the_ring_can_differ():
    # The halo is needed: without the ring's extra vertex the saddle rule sees a false border.
    rng = np.random.default_rng(2)
    grid = IndexGrid(rng.integers(0, 2, (40, 40)).astype(np.uint8), (4, 4))
    themes = _themes(rng, 2)
    w, h = grid.texture_size
    whole = render_cells(grid, themes)
    differ = 0
    for win in tile_windows(w, h, 12):
        (r0, c0), block = grid_window(grid, win)
        if r0 == 0 or c0 == 0:
            continue
        got = render_cells(block[1:, 1:], themes, grid.cell, region=(win.x, win.y, win.w, win.h),
                           origin=(r0 + 1, c0 + 1))
        differ += not np.array_equal(got, whole[win.y:win.y1, win.x:win.x1])
    assert differ > 0


def test_origin_errors():
    grid = np.zeros((5, 5), np.uint8)
    themes = [np.zeros((4, 4, 3), np.uint8)]
    with pytest.raises(TerrathemeError, match="origin"):
        render_cells(grid, themes, (4, 4), origin=(-1, 0))
    with pytest.raises(TerrathemeError, match="origin"):
        render_cells(grid, themes, (4, 4), origin=(1, 0),
                     colour_map=ColourMap(np.full((1, 1, 3), 128, np.uint8), 4))
    with pytest.raises(TerrathemeError):
        # A region outside the block.
        render_cells(grid, themes, (4, 4), region=(0, 0, 4, 4), origin=(2, 2))


def test_block_job_payload_is_set_by_the_tile_not_the_image():
    rng = np.random.default_rng(1)
    themes = _themes(rng)
    tile, cell = 256, 16
    job = BlockGainJob(themes, (cell, cell), RenderOptions(threads=1), 16)
    sent = {}
    for side in (1024, 8192):  # photos of 1 and 64 Mpx
        grid = IndexGrid(rng.integers(0, 3, (side // cell + 1,) * 2).astype(np.uint8),
                         (cell, cell))
        wins = tile_windows(side, side, tile)
        part = max(len(pickle.dumps((win, grid_window(grid, win)))) for win in wins)
        sent[side] = (len(pickle.dumps(job)), part, grid.indices.nbytes)
    (job_small, part_small, _), (job_big, part_big, grid_big) = sent[1024], sent[8192]
    # What every worker gets once (the themes, the options) does not depend on the image...
    assert job_small == job_big
    # ... and each tile's window is at most (tile / cell + 4)^2 vertices plus framing.
    # (the same for both images, to the pickled width of the window's position).
    assert abs(part_small - part_big) < 16
    assert max(part_small, part_big) <= (tile // cell + 4) ** 2 + 1024
    assert part_big * 100 < grid_big


@pytest.mark.parametrize("tile", [16, 32])
def test_block_job_gives_each_block_the_photo_over_the_render(tile):
    # Two flat themes of one colour: the render is (100, 80, 40) everywhere, whatever the
    # grid, so each 16 x 16 block's gain is its photo colour over that, times 128.
    rng = np.random.default_rng(4)
    grid = IndexGrid(rng.integers(0, 2, (3, 4)).astype(np.uint8), (16, 16))
    flat = np.full((24, 20, 3), (100, 80, 40), np.uint8)
    photo = np.empty((32, 48, 3), np.uint8)
    colours = [[(150, 80, 20), (100, 40, 10), (255, 255, 255)],
               [(0, 0, 0), (150, 80, 40), (25, 20, 10)]]
    for i in range(2):
        for j in range(3):
            photo[16 * i:16 * i + 16, 16 * j:16 * j + 16] = colours[i][j]
    photo[16:24, 16:32, 0] = 100   # block (1, 1): red half 100, half 200, mean 150
    photo[24:32, 16:32, 0] = 200
    want = np.array([[(192, 128, 64), (128, 64, 32), (255, 255, 255)],
                     [(0, 0, 0), (192, 128, 128), (32, 32, 32)]], np.uint8)
    job = BlockGainJob([flat, flat], grid.cell, RenderOptions(boundary=BoundaryOptions(),
                                                             threads=1), 16)
    for win in tile_windows(48, 32, tile):
        got = job(win, photo[win.ry:win.ry1, win.rx:win.rx1], grid_window(grid, win))
        np.testing.assert_array_equal(got, want[win.y // 16:win.y1 // 16,
                                               win.x // 16:win.x1 // 16])


def test_map_pixels_past_the_photo_take_the_nearest_covered_gain(tmp_path):
    from scipy import ndimage
    from terratheme.core.convert.colour_fit import ColourMapOptions, colour_map_from_file
    from terratheme.core.io.codec import decode_image
    from terratheme.core.io.images import write_image

    rng = np.random.default_rng(6)
    # A 13 x 17 vertex grid at cell 16 is a 256 x 192 texture; the photo covers 201 x 139 of
    # it, so the map at scale 8 has photo gains in its top-left 18 x 26 pixels only.
    photo = rng.integers(30, 220, (139, 201, 3), dtype=np.uint8)
    write_image(tmp_path / "p.png", photo)
    grid = IndexGrid(rng.integers(0, 3, (13, 17)).astype(np.uint8), (16, 16))
    fitted = colour_map_from_file(tmp_path / "p.png", grid, _themes(rng), 8,
                                  options=ColourMapOptions(codec="png"), tile=64)
    got = decode_image(fitted.colour_map.data, codec="png")  # the map as coded, at 8
    assert got.shape == (24, 32, 3)
    covered = np.zeros(got.shape[:2], bool)
    covered[:18, :26] = True
    _, (iy, ix) = ndimage.distance_transform_edt(~covered, return_indices=True)
    assert np.array_equal(got, got[iy, ix])
    assert not np.array_equal(got[:18, :26][:, -1], got[:18, :26][:, -2])


@pytest.mark.parametrize(("shape", "s"), [((64, 96, 3), 16), ((61, 70, 4), 16), ((37, 50, 3), 64),
                                          ((128, 128, 3), 1)])
def test_block_sums_are_the_exact_sums_of_each_block(shape, s):
    from terratheme.core.convert.colour_fit import _block_sums

    image = np.random.default_rng(3).integers(0, 256, shape, dtype=np.uint8)
    got = _block_sums(image, s)
    bh, bw = -(-shape[0] // s), -(-shape[1] // s)
    assert got.shape == (bh, bw, 3) and got.dtype == np.float64
    for j in range(bh):
        for i in range(bw):
            block = image[j * s:(j + 1) * s, i * s:(i + 1) * s, :3].astype(np.int64)
            assert np.array_equal(got[j, i], block.sum(axis=(0, 1)))

