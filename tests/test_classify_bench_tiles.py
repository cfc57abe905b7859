"""The one-photo-per-tile protocol helpers of benchmarks/classify_one_per_tile.py.

The benchmark helpers are not a package: they are loaded from their file, with
their folder on ``sys.path`` for their own imports.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest
from terratheme.core.classify import SupervisedOptions

_DIR = Path(__file__).resolve().parents[1] / "benchmarks"


def _load(name: str, monkeypatch):
    monkeypatch.syspath_prepend(str(_DIR))
    spec = importlib.util.spec_from_file_location(f"{name}_under_test", _DIR / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture
def opt(monkeypatch):
    return _load("classify_one_per_tile", monkeypatch)


NAMES = [f"image_part_{p:03d}t{t}.jpg" for t in range(1, 7) for p in range(1, 10)]


def test_a_random_draw_takes_one_photo_of_each_tile_in_tile_order(opt):
    draw = opt.random_draw(NAMES, 5)
    assert [opt.tile_of(n) for n in draw] == [1, 2, 3, 4, 5, 6]
    assert all(n in NAMES for n in draw)
    assert draw == opt.random_draw(NAMES, 5)


def _tile_photo(tile: int):
    """A 64 x 64 photo: left half class 1 (red), right half class 2 (blue), tile-tinted."""
    photo = np.zeros((64, 64, 3), np.uint8)
    photo[:, :32] = (200, 40 + tile, 40)
    photo[:, 32:] = (40, 40 + tile, 200)
    mask = np.ones((64, 64), np.uint8)
    mask[:, 32:] = 2
    return photo, mask


def test_score_draw_scores_every_photo_of_each_held_out_tile(opt):
    # Two photos of tile 1, one of each other tile.
    names = [f"image_part_{p:03d}t{t}.jpg" for t in range(1, 7)
             for p in ((1, 2) if t == 1 else (1,))]
    photos = {n: _tile_photo(opt.tile_of(n)) for n in names}
    train = tuple(f"image_part_001t{t}.jpg" for t in range(1, 7))
    options = SupervisedOptions(n_trees=2, adapt=False)
    cms, pixels, seconds = opt.score_draw(photos, train, options)
    assert sorted(cms) == sorted(names)
    assert pixels == 7 * 64 * 64
    assert seconds >= 0.0
    # Classes 3-5 never occur; red and blue halves are told apart everywhere.
    for cm in cms.values():
        assert cm[0, 0] == 64 * 32 and cm[1, 1] == 64 * 32
        assert cm.sum() == 64 * 64
