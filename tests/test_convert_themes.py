"""Themes for a classified photo: patches cut from the photo, shipped themes by name."""

from __future__ import annotations

import numpy as np
import pytest

from core.errors import TerrathemeError
from core.themes.from_photo import (
    NO_DATA_NAME,
    PatchOptions,
    find_patch,
    themes_by_name,
    themes_from_photo,
)
from core.themes.tileable import SEAM_THRESHOLD, seam_score


def _two_regions(h=96, w=128, seed=0):
    """Left: noisy red-brown; right: noisy green with a calm 40 x 40 square at (80, 30)."""
    rng = np.random.default_rng(seed)
    photo = np.empty((h, w, 3), np.uint8)
    left = np.array([150, 90, 60]) + rng.normal(0, 18, (h, w // 2, 3))
    right = np.array([60, 140, 60]) + rng.normal(0, 25, (h, w - w // 2, 3))
    photo[:, : w // 2] = np.clip(left, 0, 255)
    photo[:, w // 2 :] = np.clip(right, 0, 255)
    calm = np.array([60, 140, 60]) + rng.normal(0, 3, (40, 40, 3))
    photo[30:70, 80:120] = np.clip(calm, 0, 255)
    labels = np.ones((h, w), np.uint8)
    labels[:, w // 2 :] = 2
    return photo, labels


def test_find_patch_picks_the_calm_square_inside_the_class():
    import cv2

    photo, labels = _two_regions()
    lab = cv2.cvtColor(photo.astype(np.float32) / 255, cv2.COLOR_RGB2LAB)
    x, y, s = find_patch(lab, labels == 2, PatchOptions(size=32, min_size=8))
    assert s == 32
    # The whole window lies in the calm square (columns 80..119, rows 30..69).
    assert 80 <= x and x + s <= 120 and 30 <= y and y + s <= 70
    # Class 1 has no calm part, but its window must stay inside the class (columns < 64).
    x1, y1, s1 = find_patch(lab, labels == 1, PatchOptions(size=32, min_size=8))
    assert x1 + s1 <= 64


def test_find_patch_prefers_the_class_colour_over_a_flat_dark_corner():
    import cv2

    # One class: mostly mid-grey with mild noise, plus a flat black 40 x 40 corner.
    rng = np.random.default_rng(1)
    photo = np.clip(128 + rng.normal(0, 6, (96, 96, 3)), 0, 255).astype(np.uint8)
    photo[:40, :40] = 0
    lab = cv2.cvtColor(photo.astype(np.float32) / 255, cv2.COLOR_RGB2LAB)
    mask = np.ones((96, 96), bool)
    opts = PatchOptions(size=32, min_size=8)
    # Variance alone picks the flat black corner ...
    x, y, s = find_patch(lab, mask, PatchOptions(size=32, min_size=8, representative=False))
    assert x + s <= 40 and y + s <= 40
    # ... the representative score a grey window that misses the corner entirely.
    x, y, s = find_patch(lab, mask, opts)
    assert s == 32 and (x >= 40 or y >= 40)
    assert photo[y : y + s, x : x + s].mean() > 100


def test_find_patch_shrinks_then_gives_up():
    lab = np.zeros((50, 50, 3), np.float32)
    mask = np.zeros((50, 50), bool)
    mask[10:30, 10:30] = True  # 20 x 20 region: sizes 50, 37, 27 do not fit, 20 does
    got = find_patch(lab, mask, PatchOptions(size=128, min_size=8, inside=1.0))
    assert got == (10, 10, 20)
    assert find_patch(lab, mask, PatchOptions(size=128, min_size=24, inside=1.0)) is None


def test_themes_from_photo_are_tileable_patches():
    photo, labels = _two_regions()
    mapping = themes_from_photo(photo, labels, options=PatchOptions(size=32, min_size=8))
    assert mapping.library.names == ["class 1", "class 2"]
    assert mapping.classes == (1, 2)
    assert mapping.lut[1] == 0 and mapping.lut[2] == 1
    for theme in mapping.library:
        assert theme.texture.shape == (32, 32, 3)
        assert theme.source.startswith("photo patch")
        assert seam_score(theme.texture) < SEAM_THRESHOLD
    # Display colour: the class's mean colour (red-brown, then green).
    assert mapping.library[0].colour[0] > mapping.library[0].colour[1]
    assert mapping.library[1].colour[1] > mapping.library[1].colour[0]


def test_tiny_class_and_no_data_get_flat_themes():
    photo = np.full((20, 20, 3), 100, np.uint8)
    labels = np.ones((20, 20), np.uint8)
    labels[0, 0] = 3  # one pixel: no 16-pixel patch fits
    labels[19, 19] = 0  # transparent
    photo[0, 0] = (10, 20, 30)
    mapping = themes_from_photo(photo, labels)
    assert mapping.library.names == ["class 1", "class 3", NO_DATA_NAME]
    assert mapping.library[1].colour == (10, 20, 30)
    assert "flat" in mapping.library[1].source
    assert mapping.library[0].source.startswith("photo patch")
    assert mapping.lut[0] == 2 and mapping.lut[3] == 1


def test_themes_by_name_assigns_by_colour():
    h, w = 32, 40
    photo = np.zeros((h, w, 3), np.uint8)
    photo[:, :20] = (40, 90, 200)  # blue: water
    photo[:, 20:] = (225, 200, 140)  # sand
    labels = np.ones((h, w), np.uint8)
    labels[:, 20:] = 2
    mapping = themes_by_name(photo, labels, ["sand", "water", "forest"])
    assert mapping.library.names == ["water", "sand"]
    assert mapping.lut[1] == 0 and mapping.lut[2] == 1
    explicit = themes_by_name(photo, labels, {1: "town", 2: "town"})
    assert explicit.library.names == ["town"] and explicit.lut[2] == 0


def test_themes_by_name_errors():
    photo = np.zeros((8, 8, 3), np.uint8)
    labels = np.ones((8, 8), np.uint8)
    labels[:, 4:] = 2
    with pytest.raises(TerrathemeError, match="only 1 theme names"):
        themes_by_name(photo, labels, ["water"])
    with pytest.raises(TerrathemeError, match="unknown theme"):
        themes_by_name(photo, labels, ["water", "lava"])
    with pytest.raises(TerrathemeError, match="no theme name"):
        themes_by_name(photo, labels, {1: "water"})
    with pytest.raises(TerrathemeError, match="repeat"):
        themes_by_name(photo, labels, ["water", "water"])
    with pytest.raises(TerrathemeError, match="do not match"):
        themes_from_photo(photo, labels[:4])
