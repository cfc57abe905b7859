"""What a theme patch leaves out: the class's border rim and the lone marks that would repeat."""

from __future__ import annotations

import numpy as np
from terratheme.core.themes.cut_mask import lone_objects
from terratheme.core.themes.from_photo import themes_from_photo
from terratheme.core.themes.patch_search import INTERIOR, PatchOptions, interior_labels

_LUMA = np.array([0.299, 0.587, 0.114])


def _sand(h, w, seed=0, sd=3.0):
    rng = np.random.default_rng(seed)
    sand = np.array([225, 215, 200]) + rng.normal(0, sd, (h, w, 3))
    return np.clip(sand, 0, 255).astype(np.uint8)


def _interior(mask, x, y, s):
    """The class's interior pixels of the ``s x s`` window at ``(x, y)``."""
    return interior_labels(mask.astype(np.uint8))[y:y + s, x:x + s].astype(bool)


def test_class_interior_drops_the_rim_along_the_class_border_only():
    mask = np.zeros((40, 60), bool)
    mask[10:, :] = True  # the class below row 10, running off the photo's left, right, bottom
    inner = _interior(mask, 0, 0, 40)
    # Rows within INTERIOR of the border at row 10 go; the photo's own edges are no border.
    assert not inner[: 10 + INTERIOR].any()
    assert inner[10 + INTERIOR :, :].all()


def test_class_interior_reads_the_mask_beyond_the_window():
    mask = np.ones((50, 50), bool)
    mask[:, :5] = False  # a border 5 pixels left of the window at x = 10
    inner = _interior(mask, 10, 10, 20)
    assert inner.shape == (20, 20)
    assert inner.all()  # 5 pixels from the border is more than INTERIOR
    near = _interior(mask, 6, 10, 20)
    assert not near[:, : 5 + INTERIOR - 6].any() and near[:, 5 + INTERIOR - 6 :].all()


def test_interior_labels_keep_each_class_inside_its_own_border():
    labels = np.ones((30, 40), np.uint8)
    labels[:, 20:] = 2
    labels[:3, :3] = 0
    inner = interior_labels(labels)
    # Within INTERIOR of the border at column 20 nothing is inside; the photo's edges are none.
    assert (inner[:, 20 - INTERIOR : 20 + INTERIOR] == 0).all()
    assert (inner[10:, : 20 - INTERIOR] == 1).all() and (inner[:, 20 + INTERIOR :] == 2).all()
    # A class's interior is the same read from its own mask.
    for c in (1, 2):
        np.testing.assert_array_equal(_interior(labels == c, 0, 0, 40), inner == c)


def test_a_rim_along_dark_water_is_a_lone_object_once_the_water_is_painted_over():
    window = _sand(96, 96, seed=1)
    window[:30] = (40, 60, 70)  # dark water, another class
    window[30:38] = (130, 135, 135)  # a rim of blend the classifier gave the sand
    inner = np.zeros((96, 96), bool)
    inner[30 + INTERIOR :] = True  # the class's interior still holds half the rim
    # Beside the water the rim is the edge of a wide dark region, not an object.
    assert not lone_objects(window)[34:38].any()
    # Painted in the sand's median colour, the water leaves the rim a dark line on sand.
    seen = window.copy()
    seen[~inner] = np.median(window[inner], axis=0).astype(np.uint8)
    assert lone_objects(seen)[34:38, 10:86].all()
    assert not lone_objects(seen)[45:].any()


def test_theme_cut_beside_dark_water_carries_neither_its_rim_nor_a_track():
    h, w = 128, 128
    photo = _sand(h, w, seed=2)
    labels = np.ones((h, w), np.uint8)
    # Dark water along the top, with an 8 px rim of blend the classifier gave the sand.
    photo[:30] = (40, 60, 70)
    labels[:30] = 2
    photo[30:38] = (130, 135, 135)
    # A tyre mark on the sand.
    photo[90:94, 40:80] = photo[90:94, 40:80] - 80
    options = PatchOptions(size=96, min_size=32, quilt=False)
    mapping = themes_from_photo(photo, labels, options=options)
    sand = mapping.library[int(mapping.lut[1])].texture
    luma = sand[..., :3].astype(np.float64) @ _LUMA
    sand_luma = float(np.array([225, 215, 200]) @ _LUMA)
    # Every texel is sand: no rim (about 134) and no track (about 136) left in the tile.
    assert luma.min() > sand_luma - 25, luma.min()
