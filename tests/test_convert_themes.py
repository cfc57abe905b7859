"""Themes for a classified photo: patches cut from the photo, shipped themes by name."""

from __future__ import annotations

import numpy as np
import pytest
from terratheme.core.errors import TerrathemeError
from terratheme.core.themes.cut_mask import fill_from_class, lone_objects
from terratheme.core.themes.from_photo import (
    NO_DATA_NAME,
    themes_by_name,
    themes_from_photo,
)
from terratheme.core.themes.library import shipped_theme_library
from terratheme.core.themes.patch_search import (
    PatchOptions,
    class_stats,
    class_windows,
    find_patch,
    texture_stats,
)
from terratheme.core.themes.tileable import SEAM_THRESHOLD, seam_score


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


def _windows(photo, mask, options):
    """The class region's scored windows (:func:`class_windows`)."""
    stats = class_stats(photo, mask.astype(np.uint8), options)
    return class_windows(stats.windows, mask, options, stats.targets[1])


def test_find_patch_matches_the_class_texture_not_its_calmest_corner():
    photo, labels = _two_regions()
    # Class 2's texture is its noise (std 25): the window picked avoids the calm square.
    x, y, s = find_patch(_windows(photo, labels == 2, PatchOptions(size=32, min_size=8)))
    assert s == 32 and x >= 64
    inside_calm = 80 <= x and x + s <= 120 and 30 <= y and y + s <= 70
    assert not inside_calm
    assert photo[y : y + s, x : x + s].std() > 15
    # Class 1's window stays inside the class (columns < 64).
    x1, y1, s1 = find_patch(_windows(photo, labels == 1, PatchOptions(size=32, min_size=8)))
    assert x1 + s1 <= 64


def test_find_patch_takes_the_calm_square_when_the_class_is_calm():
    photo, labels = _two_regions()
    calm = np.zeros(labels.shape, bool)
    calm[30:70, 80:120] = True
    calm[0:10, 64:74] = True  # a few noisy pixels of the class elsewhere
    x, y, s = find_patch(_windows(photo, calm, PatchOptions(size=32, min_size=8, inside=1.0)))
    assert 80 <= x and x + s <= 120 and 30 <= y and y + s <= 70


def test_find_patch_keeps_to_one_texture_of_a_class_of_two():
    # One class of a strong grain (left) and a grain a sixth as strong (right): a window
    # across both matches the class's mean energy best, but tiles into bands of the two.
    rng = np.random.default_rng(4)
    h, w = 64, 192
    amplitude = np.where(np.arange(w) < w // 2, 36.0, 6.0)
    photo = np.clip(120 + rng.normal(0, 1, (h, w, 3)) * amplitude[None, :, None], 0, 255)
    photo = photo.astype(np.uint8)
    mask = np.ones((h, w), bool)
    def across(even_weight):
        x, _, s = find_patch(_windows(photo, mask, PatchOptions(
            size=64, min_size=64, inside=1.0, even_weight=even_weight)))
        return min(max(0, x + s - w // 2), max(0, w // 2 - x))  # texels of the other side

    # Strips of 8 texels see no narrower edge; even_detail evens what is left.
    assert across(PatchOptions().even_weight) <= 4
    assert across(0.0) >= 24


def test_find_patch_shrinks_then_gives_up():
    photo = np.zeros((50, 50, 3), np.uint8)
    mask = np.zeros((50, 50), bool)
    mask[10:30, 10:30] = True  # 20 x 20 region: sizes 50, 37, 27 do not fit, 20 does
    got = find_patch(_windows(photo, mask, PatchOptions(size=128, min_size=8, inside=1.0)))
    assert got == (10, 10, 20)
    opts = PatchOptions(size=128, min_size=24, inside=1.0)
    assert find_patch(_windows(photo, mask, opts)) is None


def test_find_patch_skips_excluded_windows():
    photo, labels = _two_regions()
    first = find_patch(_windows(photo, labels == 1, PatchOptions(size=32, min_size=32)))
    second = find_patch(_windows(photo, labels == 1, PatchOptions(size=32, min_size=32)),
                        exclude=[first])
    assert second is not None
    assert abs(second[0] - first[0]) > 16 or abs(second[1] - first[1]) > 16


def test_fill_from_class_takes_only_class_pixels():
    rng = np.random.default_rng(3)
    patch = rng.integers(100, 200, (16, 16, 3), dtype=np.uint8)
    keep = np.ones((16, 16), bool)
    keep[4:8, 4:8] = False
    patch[4:8, 4:8] = 0  # another class's pixels
    out = fill_from_class(patch, keep)
    assert np.array_equal(out[keep], patch[keep])
    assert out[~keep].min() >= 100
    # Every filled texel is one of the kept ones.
    kept = {tuple(v) for v in patch[keep]}
    assert all(tuple(v) in kept for v in out[~keep])


def test_lone_objects_are_found_in_calm_texture_only():
    rng = np.random.default_rng(4)
    calm = np.clip(90 + rng.normal(0, 3, (64, 64, 3)), 0, 255).astype(np.uint8)
    calm[30:36, 30:36] = 250  # a white box in dark water
    found = lone_objects(calm)
    assert found[30:36, 30:36].all() and found.mean() < 0.05
    busy = rng.integers(0, 256, (64, 64, 3), dtype=np.uint8)
    assert lone_objects(busy).mean() < 0.2


def test_themes_from_photo_are_tileable_patches_with_the_class_detail():
    from terratheme.core.fidelity import detail_energy

    photo, labels = _two_regions()
    mapping = themes_from_photo(photo, labels, options=PatchOptions(size=32, min_size=8))
    assert mapping.classes == (1, 2)
    assert mapping.lut[1] == 0 and mapping.lut[2] == 1
    for theme, c in zip(mapping.library, (1, 2), strict=True):
        assert theme.texture.shape == (32, 32, 3)
        assert theme.source.startswith("photo patch")
        assert seam_score(theme.texture) < SEAM_THRESHOLD
        region = photo[:, :64] if c == 1 else photo[:, 70:]
        # The theme carries at least half of its class's fine detail.
        assert detail_energy(theme.texture) > 0.5 * detail_energy(region)
    # Display colour: the class's mean colour (red-brown, then green).
    assert mapping.library[0].colour[0] > mapping.library[0].colour[1]
    assert mapping.library[1].colour[1] > mapping.library[1].colour[0]
    # Named after shipped themes, never "class 1".
    names = set(shipped_theme_library().names)
    assert all(n.split(" ")[0] in names or n in names for n in mapping.library.names)
    assert len(set(mapping.library.names)) == 2


def test_tiny_class_and_no_data_get_flat_themes():
    photo = np.full((20, 20, 3), 100, np.uint8)
    labels = np.ones((20, 20), np.uint8)
    labels[0, 0] = 3  # one pixel: no patch fits
    labels[19, 19] = 0  # transparent
    photo[0, 0] = (10, 20, 30)
    mapping = themes_from_photo(photo, labels, names={1: "ground", 3: "speck"},
                                options=PatchOptions(size=16, min_size=16))
    assert mapping.library.names == ["ground", "speck", NO_DATA_NAME]
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


def test_class_stats_are_each_class_statistics_taken_once():
    from terratheme.core.themes.matching import class_appearances

    photo = np.zeros((12, 16, 3), np.uint8)
    photo[:, :8] = (10, 20, 30)
    photo[:, 8:] = (200, 100, 0)
    photo[0, 8] = (0, 0, 0)
    labels = np.ones((12, 16), np.uint8)
    labels[:, 8:] = 3
    labels[0, 0] = 0
    stats = class_stats(photo, labels)
    assert stats.counts[[0, 1, 3]].tolist() == [1, 95, 96] and stats.counts.sum() == 192
    np.testing.assert_allclose(stats.colour[1], (10, 20, 30))
    np.testing.assert_allclose(stats.colour[3], (200 * 95 / 96, 100 * 95 / 96, 0))
    # No data (0) is no class to cut a theme for.
    assert sorted(stats.targets) == [1, 3]
    texture = texture_stats(photo)
    # Appearances from the statistics equal those measured on the labels (2: absent, grey).
    for a, b in zip(class_appearances(stats, None, [1, 2, 3]),
                    class_appearances(texture, labels, [1, 2, 3]), strict=True):
        np.testing.assert_array_equal(a.lab, b.lab)
        assert a.energy == b.energy
