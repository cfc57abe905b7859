"""Lone marks found by their band energy, and holes filled with whole pieces of the class."""

from __future__ import annotations

import cv2
import numpy as np
from terratheme.core.themes.cut_mask import (
    band_marks,
    cut_window,
    fill_from_class,
    lone_objects,
    match_surroundings,
)
from terratheme.core.themes.patch_search import interior_labels
from terratheme.core.themes.quality import landmark_mask

_LUMA = np.array([0.299, 0.587, 0.114])


def _sand(h, w, seed=0, sd=2.0):
    """Sand of a grain about 3 texels across (blurred noise of luma spread ``sd``)."""
    rng = np.random.default_rng(seed)
    grain = cv2.GaussianBlur(rng.normal(0, 1, (h, w)).astype(np.float32), (0, 0), 1.5)
    grain *= sd / grain.std()
    return np.clip(np.array([215, 210, 205]) + grain[..., None], 0, 255).astype(np.uint8)


def _stroked(seed=0):
    """192 x 192 sand with a faint thin dark stroke (3 px, 20 levels) at rows 30..60, col 40."""
    sand = _sand(192, 192, seed)
    sand[30:60, 40:43] -= 20
    return sand


def test_a_faint_thin_stroke_the_landmark_test_misses_is_a_band_mark():
    sand = _stroked()
    # Its contrast is under the landmark test's 20 levels ...
    dark, bright = landmark_mask(sand, periodic=False)
    assert not dark.any() and not bright.any()
    # ... but its band energy is far above the sand's own grain.
    marks = band_marks(sand)
    assert marks[32:58, 40:43].all()
    assert not marks[:, 60:].any() and not marks[75:].any()
    found = lone_objects(sand)
    assert found[30:60, 40:43].all() and found.mean() < 0.05


def test_regular_ripples_hold_no_mark():
    yy, xx = np.mgrid[:96, :96]
    ripples = 200 + 20 * np.sin(2 * np.pi * (xx + 0.3 * yy) / 8.0)
    rng = np.random.default_rng(1)
    texture = np.clip(ripples[..., None] + rng.normal(0, 2, (96, 96, 3)), 0, 255).astype(np.uint8)
    assert not band_marks(texture).any()
    assert not lone_objects(texture).any()


def test_the_edge_of_a_region_across_the_window_is_no_mark():
    sand = _sand(192, 192, seed=2)
    sand[:80] -= 12  # a faintly darker region along the top, its edge across the window
    assert not band_marks(sand).any() and not lone_objects(sand).any()
    # The same step cut short (a third of the side) is a lone mark.
    short = _sand(192, 192, seed=2)
    short[76:80, 64:128] -= 12
    assert lone_objects(short)[76:80, 64:128].all()


def test_marks_everywhere_are_the_texture_itself():
    sand = _sand(96, 96, seed=3)
    for r in range(4, 96, 12):
        for c in range(4, 96, 12):
            sand[r : r + 2, c : c + 6] -= 40  # a dense, even scatter of dark dashes
    assert not band_marks(sand).any()


def _coded(h, w):
    """(h, w, 3) uint8 whose pixel (y, x) reads (y, x, 128): where a copied texel came from."""
    yy, xx = np.mgrid[:h, :w]
    return np.stack([yy, xx, np.full_like(yy, 128)], axis=2).astype(np.uint8)


def test_a_hole_takes_one_coherent_piece_of_the_class_when_one_fits():
    patch = _coded(64, 64)
    keep = np.ones((64, 64), bool)
    keep[20:32, 24:40] = False
    out = fill_from_class(patch, keep)
    assert np.array_equal(out[keep], patch[keep])
    # Every filled texel came from the same shift of the patch, from inside it (no wrap).
    yy, xx = np.mgrid[:64, :64]
    dy = (yy - out[:, :, 0].astype(int))[~keep]
    dx = (xx - out[:, :, 1].astype(int))[~keep]
    assert len(set(zip(dy.tolist(), dx.tolist(), strict=True))) == 1
    src = np.stack([out[:, :, 0], out[:, :, 1]], axis=2)[~keep].astype(int)
    assert keep[src[:, 0], src[:, 1]].all()


def test_a_hole_beside_a_dark_channel_is_not_filled_with_the_channel():
    patch = _sand(64, 64, seed=4)
    patch[20:28] = (60, 80, 60)  # a dark channel of the class, just above the hole
    keep = np.ones((64, 64), bool)
    keep[28:40, :] = False
    out = fill_from_class(patch, keep)
    luma = out[28:40].astype(np.float64) @ _LUMA
    assert luma.min() > 180, luma.min()


def test_cut_window_fills_its_holes_from_the_class_around_it():
    yy, xx = np.mgrid[:200, :200]
    # Around the window a checkerboard of 2 px squares; inside it stripes of the same colours.
    checker = ((yy // 2 + xx // 2) % 2).astype(bool)
    stripes = ((xx // 2) % 2).astype(bool)
    inside = (yy >= 64) & (yy < 128) & (xx >= 64) & (xx < 128)
    photo = np.where((np.where(inside, stripes, checker))[..., None], 160, 140).astype(np.uint8)
    photo = np.repeat(photo, 3, axis=2)
    mask = np.ones((200, 200), bool)
    mask[90:106, 90:106] = False  # another class inside the window at (64, 64), side 64
    photo[90:106, 90:106] = 0
    interior = interior_labels(mask.astype(np.uint8)).astype(bool)
    cut = cut_window(photo, mask, 64, 64, 64, interior).astype(int)
    hole = cut[28:40, 28:40, 0]  # inside the hole (window coordinates), off its edge
    # The hole holds the checkerboard (a 2-row shift flips it), not a second copy of the stripes.
    assert np.abs(hole[2:] - hole[:-2]).mean() > 15
    assert np.abs(cut[:20, :, 0] - cut[2:22, :, 0]).mean() < 1  # the window's own stripes stay
    # Its brightness is the class's: no blob.
    assert abs(hole.mean() - 150) < 5


def test_a_strong_feature_is_left_to_the_landmark_test():
    sand = _sand(96, 96, seed=5)
    sand[38:42, 30:62] = sand[38:42, 30:62] // 3  # a dark track, far above MARK_CEILING
    assert not band_marks(sand).any()
    # In calm sand the landmark test takes it.
    assert lone_objects(sand)[38:42, 30:62].all()


def test_a_piece_copied_from_a_shaded_part_takes_the_brightness_around_it():
    yy, xx = np.mgrid[:96, :96]
    grain = np.where(((yy // 2 + xx // 2) % 2).astype(bool), 10, -10)
    patch = np.repeat((200 + grain)[..., None], 3, axis=2).astype(np.uint8)
    hole = np.zeros((96, 96), bool)
    hole[40:56, 40:56] = True
    filled = patch.copy()
    filled[hole] -= 100  # a piece of the same grain from a shaded part
    out = match_surroundings(filled, patch, ~hole, hole).astype(int)
    assert abs(out[hole].mean() - 200) < 3
    # Its grain stays (the checkerboard's +-10), and the kept pixels are untouched.
    assert np.abs(out[42:54, 42:54, 0] - 200 - grain[42:54, 42:54]).max() <= 3
    assert np.array_equal(out[~hole], patch[~hole])
