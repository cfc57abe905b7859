"""Engine maps back to a grid, band by band, headers checked first (issue 33)."""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest
import terratheme.core.exchange.maps_to_grid as maps_to_grid
from terratheme.core.errors import TerrathemeError
from terratheme.core.exchange.maps_to_grid import grid_from_maps
from terratheme.core.exchange.terrain3d import write_control_map
from terratheme.core.io.images import write_image


@pytest.fixture
def labels():
    rng = np.random.default_rng(5)
    return rng.integers(0, 5, (37, 29)).astype(np.uint8)  # 36 x 28 cells of one pixel


@pytest.fixture(params=[4, 64])
def band_rows(request, monkeypatch):
    monkeypatch.setattr(maps_to_grid, "BAND_ROWS", request.param)


def _one_hot(labels: np.ndarray, themes: int, value: int = 255) -> np.ndarray:
    return np.stack([(labels == t) * value for t in range(themes)], axis=2)


@pytest.mark.parametrize("step", [1, 2, 4])
def test_splatmaps_give_the_labels_at_the_vertices(tmp_path, labels, band_rows, step):
    weights = _one_hot(labels, 8).astype(np.uint8)
    write_image(tmp_path / "s0.png", weights[:, :, :4])
    write_image(tmp_path / "s1.tif", weights[:, :, 4:], tile=16)  # a tiled file beside a PNG
    grid = grid_from_maps([str(tmp_path / "s0.png"), str(tmp_path / "s1.tif")], "splatmap", 5,
                          step)
    assert np.array_equal(grid, labels[::step, ::step])


@pytest.mark.parametrize("step", [1, 4])
def test_weight_maps_and_control_maps_give_the_labels(tmp_path, labels, band_rows, step):
    paths = []
    for t in range(5):
        paths.append(str(tmp_path / f"w{t}.png"))
        write_image(paths[-1], ((labels == t) * 65535).astype(np.uint16))
    assert np.array_equal(grid_from_maps(paths, "weights", 5, step), labels[::step, ::step])
    # Terrain3D: base texture id in bits 27..31, no overlay blend.
    write_control_map(tmp_path / "c.exr", labels.astype(np.uint32) << 27)
    assert np.array_equal(grid_from_maps([str(tmp_path / "c.exr")], "terrain3d", 5, step),
                          labels[::step, ::step])


def _never_read(*args, **kwargs):
    raise AssertionError("a map was read before the headers were compared")


@pytest.mark.parametrize(("second", "match"), [
    (np.zeros((40, 29, 1), np.uint8), "w1.png: 29 x 40 uint8 differs from the first weight map's"),
    (np.zeros((37, 29, 1), np.uint16), "differs from the first weight map's 29 x 37 uint8"),
    # Grey + alpha: channel 1 was dropped without a word.
    (np.zeros((37, 29, 2), np.uint8), "w1.png: a weight map is an 8 or 16-bit grey image, got 2"),
])
def test_weight_maps_are_compared_on_their_headers(tmp_path, monkeypatch, second, match):
    monkeypatch.setattr(maps_to_grid, "read_bands", _never_read)
    write_image(tmp_path / "w0.png", np.zeros((37, 29, 1), np.uint8))
    write_image(tmp_path / "w1.png", second)
    with pytest.raises(TerrathemeError, match=match):
        grid_from_maps([str(tmp_path / "w0.png"), str(tmp_path / "w1.png")], "weights", 2, 1)


def test_a_large_splatmap_is_read_in_bounded_memory(tmp_path):
    # An all-zero 4097^2 splatmap (67 MB of pixels in a small PNG): memory is the grid and a
    # band, not the map (the whole read and an int64 argmax took 1.9 GB at 11585^2).
    side = 4097
    write_image(tmp_path / "s.png", np.zeros((side, side, 4), np.uint8))
    tracemalloc.start()
    try:
        grid = grid_from_maps([str(tmp_path / "s.png")], "splatmap", 4, 1)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert grid.shape == (side, side) and not grid.any()
    assert peak < side * side + (32 << 20), peak
