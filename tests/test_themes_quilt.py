"""core.themes.quilt: themes quilted from small blocks of a class (Efros & Freeman 2001, §2)."""

from __future__ import annotations

import numpy as np
import pytest
from terratheme.core.errors import TerrathemeError
from terratheme.core.themes import PatchOptions, themes_from_photo
from terratheme.core.themes.patch_search import best_windows, class_stats, class_windows
from terratheme.core.themes.quality import REPEAT_LIMIT, repeat_score
from terratheme.core.themes.quilt import QuiltOptions, candidate_blocks, quilt_tileable
from terratheme.core.themes.tileable import seam_score


def _grain(h: int, w: int, seed: int = 0) -> np.ndarray:
    """Red-brown noise with a little structure (blurred white noise)."""
    rng = np.random.default_rng(seed)
    noise = rng.normal(0.0, 1.0, (h, w))
    k = np.ones(3) / 3
    noise = np.apply_along_axis(lambda r: np.convolve(r, k, "same"), 1, noise)
    base = np.array([150.0, 90.0, 60.0])
    return np.clip(base + 25.0 * noise[:, :, None], 0, 255).astype(np.uint8)


def _corners(w: int, h: int, block: int, step: int = 4) -> np.ndarray:
    """Every ``step``-th block corner of an ``h x w`` region starting at the origin."""
    ys, xs = np.mgrid[0 : h - block + 1 : step, 0 : w - block + 1 : step]
    return np.stack([xs.ravel(), ys.ravel()], axis=1)


def test_quilt_has_whole_block_steps_and_wraps() -> None:
    photo = _grain(200, 220)
    options = QuiltOptions(size=100, block=24, overlap=6)
    quilt = quilt_tileable(photo, _corners(220, 200, 24), options)
    step = options.block - options.overlap
    assert quilt.dtype == np.uint8
    assert quilt.shape == (options.steps() * step, options.steps() * step, 3)
    assert options.steps() == 6
    # The torus layout closes up: the wrap edge is no worse than the texture's own grain
    # (seam_score 1 = a seam like any other column step).
    assert seam_score(quilt) < 1.5


def test_best_windows_keep_to_the_class_and_its_texture() -> None:
    # Left half red grain (the class), right half blue: every window lies in the class.
    photo = _grain(160, 240)
    photo[:, 120:] = (20, 40, 230)
    mask = np.zeros(photo.shape[:2], bool)
    mask[:, :120] = True
    options = PatchOptions(inside=1.0)
    stats = class_stats(photo, mask.astype(np.uint8), options)
    found = class_windows(stats.windows, mask, options, stats.targets[1])
    corners = best_windows(found, 20, 50, spacing=4)
    assert len(corners) == 50
    assert (corners[:, 0] + 20 <= 120).all() and (corners % 4 == 0).all()
    quilt = quilt_tileable(photo, corners, QuiltOptions(size=80, block=20, overlap=5))
    assert quilt[:, :, 2].max() < 150
    assert abs(float(quilt[:, :, 0].mean()) - float(photo[:, :120, 0].mean())) < 3.0


def test_quilt_blocks_sit_at_the_class_mean_colour() -> None:
    # A brightness ramp across the class: every block is moved to the mean of them all.
    photo = _grain(120, 200)
    ramp = np.linspace(-60, 60, 200)[None, :, None]
    photo = np.clip(photo + ramp, 0, 255).astype(np.uint8)
    blocks = candidate_blocks(photo, _corners(200, 120, 20),
                              QuiltOptions(size=80, block=20, overlap=5))
    means = blocks.mean(axis=(1, 2))
    np.testing.assert_allclose(means, means[0][None, :].repeat(len(means), 0), atol=0.01)


def test_quilt_repeats_less_than_a_tiled_block() -> None:
    photo = _grain(256, 256, seed=3)
    quilt = quilt_tileable(photo, _corners(256, 256, 24, step=8),
                           QuiltOptions(size=96, block=24, overlap=6))
    # No block is laid twice, so the quilt's detail does not correlate with itself
    # at any shift, while one block tiled 4 x 4 repeats exactly.
    assert repeat_score(quilt) < REPEAT_LIMIT
    assert repeat_score(np.tile(photo[:24, :24], (4, 4, 1))) > 0.9


def test_quilt_is_reproducible() -> None:
    photo = _grain(150, 150)
    corners = _corners(150, 150, 24)
    options = QuiltOptions(size=72, block=24, overlap=6)
    np.testing.assert_array_equal(quilt_tileable(photo, corners, options),
                                  quilt_tileable(photo, corners, options))


def test_quilt_needs_enough_blocks_inside_the_photo() -> None:
    photo = _grain(100, 100)
    options = QuiltOptions(size=72, block=24, overlap=6)
    # A 4 x 4 quilt lays 16 blocks: 15 corners are too few.
    assert options.steps() == 4
    assert quilt_tileable(photo, _corners(100, 100, 24)[:15], options) is None
    assert quilt_tileable(photo, _corners(100, 100, 24)[:16], options) is not None
    with pytest.raises(TerrathemeError, match="must lie inside the 100 x 100 photo"):
        quilt_tileable(photo, np.array([[80, 0]] * 20), options)


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"block": 24, "overlap": 12}, "under half the block"),
    ({"block": 24, "overlap": 0}, "overlap must be"),
    ({"size": 20, "block": 24, "overlap": 6}, "under two block steps"),
])
def test_quilt_options_are_checked(kwargs: dict, match: str) -> None:
    with pytest.raises(TerrathemeError, match=match):
        QuiltOptions(**kwargs)


def _lattice(size: int = 320) -> tuple[np.ndarray, np.ndarray]:
    """Faint grain under a lattice of small bright squares: every window repeats."""
    photo = _grain(size, size, seed=5).astype(np.int16) // 4 + 100
    yy, xx = np.mgrid[:size, :size]
    photo[((yy % 16) < 6) & ((xx % 16) < 6)] += 40
    return np.clip(photo, 0, 255).astype(np.uint8), np.ones((size, size), np.uint8)


def test_a_class_whose_windows_repeat_gets_a_quilted_theme() -> None:
    photo, labels = _lattice()
    # Without the evenness term: on this lattice its strips' aliasing with the period picks
    # a 120 px window that repeats a little less than the quilt, which then rightly loses.
    patched = themes_from_photo(photo, labels, names={1: "town"},
                                options=PatchOptions(size=160, quilt=False, even_weight=0.0))
    quilted = themes_from_photo(photo, labels, names={1: "town"},
                                options=PatchOptions(size=160, even_weight=0.0))
    patch_theme, quilt_theme = patched.library[0], quilted.library[0]
    assert patch_theme.source.endswith("(repeats)")
    assert quilt_theme.source.startswith("quilted from")
    assert repeat_score(quilt_theme.texture) < repeat_score(patch_theme.texture)
